// Mandel-notation elasticity: conversions, rotation against an explicit fourth-order tensor
// rotation, isotropy, cubic/hexagonal symmetry and the positive-definiteness errors.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <array>
#include <numbers>
#include <random>

#include "subslip/crystal/elasticity.hpp"
#include "subslip/crystal/rotation.hpp"

using namespace subslip::crystal;

namespace {

using Tensor4 = std::array<std::array<std::array<std::array<double, 3>, 3>, 3>, 3>;

// Voigt index of the pair (i, j): 11->0, 22->1, 33->2, 23->3, 13->4, 12->5 (written out here,
// independently of the library).
int voigt_index(int i, int j) {
  if (i == j) return i;
  return 6 - i - j;  // (1,2)->3, (0,2)->4, (0,1)->5
}

// Full tensor from a Voigt stiffness (C_ijkl = C_Voigt(I, J), minor symmetries by construction).
Tensor4 tensor_from_voigt(const MandelMatrix& voigt) {
  Tensor4 C{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k)
        for (int l = 0; l < 3; ++l) C[i][j][k][l] = voigt(voigt_index(i, j), voigt_index(k, l));
  return C;
}

// C'_ijkl = R_ip R_jq R_kr R_ls C_pqrs, loop by loop.
Tensor4 rotate_tensor(const Tensor4& C, const Eigen::Matrix3d& R) {
  Tensor4 rotated{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k)
        for (int l = 0; l < 3; ++l) {
          double sum = 0.0;
          for (int p = 0; p < 3; ++p)
            for (int q = 0; q < 3; ++q)
              for (int r = 0; r < 3; ++r)
                for (int s = 0; s < 3; ++s)
                  sum += R(i, p) * R(j, q) * R(k, r) * R(l, s) * C[p][q][r][s];
          rotated[i][j][k][l] = sum;
        }
  return rotated;
}

Eigen::Matrix3d random_rotation(unsigned seed) {
  std::mt19937_64 engine(seed);
  std::uniform_real_distribution<double> angle(0.0, 6.0);
  return euler_to_matrix(Eigen::Vector3d(angle(engine), angle(engine) / 2.0, angle(engine)));
}

Eigen::Matrix3d random_symmetric(std::mt19937_64& engine) {
  std::uniform_real_distribution<double> value(-1.0, 1.0);
  Eigen::Matrix3d a;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) a(i, j) = value(engine);
  return a + a.transpose();
}

double contract(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return (a.array() * b.array()).sum();
}

// Copper (GPa), a strongly anisotropic cubic crystal (Zener ratio 3.2).
constexpr double kC11 = 168.4, kC12 = 121.4, kC44 = 75.4;

}  // namespace

TEST(Elasticity, MandelVectorsKeepContractionsAndRoundTrip) {
  std::mt19937_64 engine(3);
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Matrix3d a = random_symmetric(engine);
    const Eigen::Matrix3d b = random_symmetric(engine);
    EXPECT_NEAR(mandel_from_symmetric(a).dot(mandel_from_symmetric(b)), contract(a, b), 1e-13);
    EXPECT_LT((symmetric_from_mandel(mandel_from_symmetric(a)) - a).norm(), 1e-15);
  }
  Eigen::Matrix3d shear = Eigen::Matrix3d::Zero();
  shear(1, 2) = shear(2, 1) = 1.0;  // order 11, 22, 33, 23, 13, 12: the 23 entry is 4th
  EXPECT_NEAR(mandel_from_symmetric(shear)[3], std::sqrt(2.0), 1e-15);
  shear.setZero();
  shear(0, 1) = shear(1, 0) = 1.0;
  EXPECT_NEAR(mandel_from_symmetric(shear)[5], std::sqrt(2.0), 1e-15);
}

TEST(Elasticity, MandelRotationOperatorIsOrthogonalAndRotatesTensors) {
  std::mt19937_64 engine(5);
  const Eigen::Matrix3d R = random_rotation(11);
  const MandelMatrix Q = mandel_rotation_operator(R);
  EXPECT_LT((Q * Q.transpose() - MandelMatrix::Identity()).norm(), 1e-14);
  const Eigen::Matrix3d a = random_symmetric(engine);
  EXPECT_LT((Q * mandel_from_symmetric(a) - mandel_from_symmetric(R * a * R.transpose())).norm(),
            1e-14);
}

TEST(Elasticity, RotatedCubicStiffnessEqualsFourthOrderTensorRotation) {
  MandelMatrix voigt = MandelMatrix::Zero();
  voigt.topLeftCorner<3, 3>().setConstant(kC12);
  voigt.diagonal() << kC11, kC11, kC11, kC44, kC44, kC44;
  const MandelMatrix C = cubic_stiffness(kC11, kC12, kC44);
  EXPECT_LT((voigt_from_mandel_stiffness(C) - voigt).norm(), 1e-12);
  EXPECT_NEAR(C(3, 3), 2.0 * kC44, 1e-12);

  for (unsigned seed : {1u, 2u, 3u}) {
    const Eigen::Matrix3d R = random_rotation(seed);
    const Tensor4 expected = rotate_tensor(tensor_from_voigt(voigt), R);
    const MandelMatrix rotated_voigt = voigt_from_mandel_stiffness(rotate_stiffness(C, R));
    const Tensor4 actual = tensor_from_voigt(rotated_voigt);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        for (int k = 0; k < 3; ++k)
          for (int l = 0; l < 3; ++l) EXPECT_NEAR(actual[i][j][k][l], expected[i][j][k][l], 1e-11);
    // The rotation must actually matter for an anisotropic crystal.
    EXPECT_GT((rotate_stiffness(C, R) - C).norm(), 1.0);
  }
}

TEST(Elasticity, IsotropicStiffnessIsInvariantUnderRotation) {
  const MandelMatrix C = isotropic_from_E_nu(200.0, 0.3);
  for (unsigned seed : {4u, 5u, 6u, 7u}) {
    EXPECT_LT((rotate_stiffness(C, random_rotation(seed)) - C).norm(), 1e-11);
  }
}

TEST(Elasticity, IsotropicParametrisationsAgree) {
  const double E = 200.0, nu = 0.3;
  const double G = E / (2.0 * (1.0 + nu));
  const double lambda = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
  const double K = E / (3.0 * (1.0 - 2.0 * nu));
  const MandelMatrix reference = isotropic_from_E_nu(E, nu);
  EXPECT_LT((isotropic_from_G_nu(G, nu) - reference).norm(), 1e-11);
  EXPECT_LT((isotropic_from_lambda_G(lambda, G) - reference).norm(), 1e-11);
  EXPECT_LT((isotropic_from_K_G(K, G) - reference).norm(), 1e-11);
  // Uniaxial strain: sigma11 = (lambda + 2G) eps11, sigma22 = lambda eps11.
  const MandelVector stress =
      reference * mandel_from_symmetric(Eigen::Vector3d(1, 0, 0).asDiagonal());
  EXPECT_NEAR(stress[0], lambda + 2.0 * G, 1e-11);
  EXPECT_NEAR(stress[1], lambda, 1e-11);
  // Pure shear eps12 = gamma/2 gives sigma12 = G gamma.
  Eigen::Matrix3d shear = Eigen::Matrix3d::Zero();
  shear(0, 1) = shear(1, 0) = 0.5;
  EXPECT_NEAR(symmetric_from_mandel(reference * mandel_from_symmetric(shear))(0, 1), G, 1e-12);
}

TEST(Elasticity, ZenerRatioOneCubicIsIsotropic) {
  const double C11 = 250.0, C12 = 100.0, C44 = 0.5 * (C11 - C12);
  EXPECT_NEAR(zener_ratio(C11, C12, C44), 1.0, 1e-15);
  EXPECT_LT((cubic_stiffness(C11, C12, C44) - isotropic_from_lambda_G(C12, C44)).norm(), 1e-12);
  EXPECT_NEAR(zener_ratio(kC11, kC12, kC44), 2.0 * kC44 / (kC11 - kC12), 1e-15);
}

TEST(Elasticity, CubicStiffnessHasCubicSymmetry) {
  const MandelMatrix C = cubic_stiffness(kC11, kC12, kC44);
  Eigen::Matrix3d quarter_turn;
  quarter_turn << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  EXPECT_LT((rotate_stiffness(C, quarter_turn) - C).norm(), 1e-12);
  const Eigen::Matrix3d three_fold =
      axis_angle_to_matrix(Eigen::Vector3d(1, 1, 1), 2.0 * std::numbers::pi / 3.0);
  EXPECT_LT((rotate_stiffness(C, three_fold) - C).norm(), 1e-11);
}

TEST(Elasticity, HexagonalStiffnessIsTransverselyIsotropicAboutC) {
  // Magnesium (GPa).
  const MandelMatrix C = hexagonal_stiffness(59.7, 26.2, 21.7, 61.7, 16.4);
  EXPECT_NEAR(voigt_from_mandel_stiffness(C)(5, 5), 0.5 * (59.7 - 26.2), 1e-12);
  for (double angle : {0.3, 1.0, 2.5}) {
    EXPECT_LT(
        (rotate_stiffness(C, axis_angle_to_matrix(Eigen::Vector3d::UnitZ(), angle)) - C).norm(),
        1e-11);
  }
  EXPECT_GT((rotate_stiffness(C, axis_angle_to_matrix(Eigen::Vector3d::UnitX(), 0.5)) - C).norm(),
            1.0);
}

TEST(Elasticity, SampleFrameStiffnessActsOnSampleTensors) {
  const MandelMatrix C = cubic_stiffness(kC11, kC12, kC44);
  const Eigen::Matrix3d g = euler_to_matrix(Eigen::Vector3d(0.3, 0.8, 1.9));
  std::mt19937_64 engine(9);
  const Eigen::Matrix3d strain_sample = random_symmetric(engine);
  // Lattice-frame route: strain to the lattice, Hooke there, stress back to the sample.
  const Eigen::Matrix3d strain_lattice = g * strain_sample * g.transpose();
  const Eigen::Matrix3d stress_lattice =
      symmetric_from_mandel(C * mandel_from_symmetric(strain_lattice));
  const Eigen::Matrix3d expected = g.transpose() * stress_lattice * g;
  const Eigen::Matrix3d actual =
      symmetric_from_mandel(stiffness_in_sample_frame(C, g) * mandel_from_symmetric(strain_sample));
  EXPECT_LT((actual - expected).norm(), 1e-11);
}

TEST(Elasticity, NonPositiveDefiniteConstantsAreNamed) {
  try {
    cubic_stiffness(100.0, 120.0, 50.0);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("cubic"), std::string::npos) << message;
    EXPECT_NE(message.find("C11=100"), std::string::npos) << message;
    EXPECT_NE(message.find("C12=120"), std::string::npos) << message;
    EXPECT_NE(message.find("C44=50"), std::string::npos) << message;
  }
  EXPECT_THROW(cubic_stiffness(100.0, 50.0, 0.0), std::invalid_argument);
  EXPECT_THROW(cubic_stiffness(100.0, -60.0, 10.0), std::invalid_argument);  // C11 + 2 C12 < 0
  EXPECT_THROW(isotropic_from_E_nu(200.0, 0.5), std::invalid_argument);
  EXPECT_THROW(isotropic_from_E_nu(-1.0, 0.3), std::invalid_argument);
  EXPECT_THROW(isotropic_from_G_nu(80.0, -1.2), std::invalid_argument);
  EXPECT_THROW(isotropic_from_K_G(-10.0, 80.0), std::invalid_argument);
  EXPECT_THROW(isotropic_from_lambda_G(100.0, 0.0), std::invalid_argument);
  try {
    hexagonal_stiffness(59.7, 26.2, 80.0, 61.7, 16.4);  // (C11 + C12) C33 < 2 C13^2
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("C13=80"), std::string::npos) << e.what();
  }
  EXPECT_NO_THROW(isotropic_from_E_nu(200.0, -0.5));  // auxetic but stable
}
