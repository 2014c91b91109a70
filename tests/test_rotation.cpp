// Rotation conventions (Rowenhorst et al. 2015, P = -1, passive): conversions, round trips,
// gimbal lock and the meaning of the matrix on known orientations.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "subslip/crystal/rotation.hpp"

using namespace subslip::crystal;

namespace {

constexpr double kPi = std::numbers::pi;

double deg(double degrees) {
  return degrees * kPi / 180.0;
}

// Random Bunge angles covering the whole range, seeded so failures are reproducible.
std::vector<Eigen::Vector3d> random_euler_angles(int count) {
  std::mt19937_64 engine(42);
  std::uniform_real_distribution<double> turn(0.0, 2.0 * kPi);
  std::uniform_real_distribution<double> tilt(0.0, kPi);
  std::vector<Eigen::Vector3d> angles;
  for (int i = 0; i < count; ++i) angles.emplace_back(turn(engine), tilt(engine), turn(engine));
  return angles;
}

// Difference of two angles modulo 2 pi, in [0, pi].
double angle_distance(double a, double b) {
  const double d = std::fmod(std::abs(a - b), 2.0 * kPi);
  return std::min(d, 2.0 * kPi - d);
}

double max_abs_difference(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return (a - b).cwiseAbs().maxCoeff();
}

}  // namespace

TEST(Rotation, EulerMatrixAndQuaternionAgreeOnRandomAngles) {
  for (const Eigen::Vector3d& euler : random_euler_angles(2000)) {
    const Eigen::Matrix3d g = euler_to_matrix(euler);
    const Quaternion q = euler_to_quaternion(euler);
    EXPECT_TRUE(is_rotation(g, 1e-13));
    EXPECT_NEAR(q.norm(), 1.0, 1e-15);
    EXPECT_GE(q.w, 0.0);
    // Two independent formulas (Bunge matrix, qu2om after eu2qu) for the same rotation.
    EXPECT_LT(max_abs_difference(quaternion_to_matrix(q), g), 1e-14);
  }
}

TEST(Rotation, RoundTripsOnRandomOrientations) {
  for (const Eigen::Vector3d& euler : random_euler_angles(2000)) {
    const Eigen::Matrix3d g = euler_to_matrix(euler);
    const Quaternion q = euler_to_quaternion(euler);

    const Eigen::Vector3d from_matrix = matrix_to_euler(g);
    const Eigen::Vector3d from_quaternion = quaternion_to_euler(q);
    for (int i = 0; i < 3; ++i) {
      EXPECT_LT(angle_distance(from_matrix[i], euler[i]), 1e-9) << "angle " << i;
      EXPECT_LT(angle_distance(from_quaternion[i], euler[i]), 1e-9) << "angle " << i;
    }
    EXPECT_GE(from_matrix[0], 0.0);
    EXPECT_LT(from_matrix[0], 2.0 * kPi);
    EXPECT_GE(from_matrix[2], 0.0);
    EXPECT_LT(from_matrix[2], 2.0 * kPi);

    const Quaternion back = matrix_to_quaternion(g);
    EXPECT_NEAR(back.w, q.w, 1e-14);
    EXPECT_NEAR(back.x, q.x, 1e-14);
    EXPECT_NEAR(back.y, q.y, 1e-14);
    EXPECT_NEAR(back.z, q.z, 1e-14);
    EXPECT_LT(max_abs_difference(euler_to_matrix(quaternion_to_euler(q)), g), 1e-14);
  }
}

TEST(Rotation, GimbalLockAtPhiZeroKeepsOnlyTheSum) {
  for (const auto& [phi1, phi2] :
       {std::pair{30.0, 40.0}, {0.0, 0.0}, {350.0, 20.0}, {200.0, 270.0}}) {
    const Eigen::Vector3d euler(deg(phi1), 0.0, deg(phi2));
    const Eigen::Matrix3d g = euler_to_matrix(euler);
    for (const Eigen::Vector3d& back :
         {matrix_to_euler(g), quaternion_to_euler(euler_to_quaternion(euler))}) {
      EXPECT_EQ(back[1], 0.0);
      EXPECT_EQ(back[2], 0.0);
      EXPECT_LT(angle_distance(back[0], deg(phi1 + phi2)), 1e-12);
      EXPECT_LT(max_abs_difference(euler_to_matrix(back), g), 1e-14);
    }
  }
}

TEST(Rotation, GimbalLockAtPhiPiKeepsOnlyTheDifference) {
  for (const auto& [phi1, phi2] :
       {std::pair{30.0, 40.0}, {0.0, 0.0}, {350.0, 20.0}, {200.0, 270.0}}) {
    const Eigen::Vector3d euler(deg(phi1), kPi, deg(phi2));
    const Eigen::Matrix3d g = euler_to_matrix(euler);
    for (const Eigen::Vector3d& back :
         {matrix_to_euler(g), quaternion_to_euler(euler_to_quaternion(euler))}) {
      EXPECT_EQ(back[1], kPi);
      EXPECT_EQ(back[2], 0.0);
      EXPECT_LT(angle_distance(back[0], deg(phi1 - phi2)), 1e-12);
      EXPECT_LT(max_abs_difference(euler_to_matrix(back), g), 1e-14);
    }
  }
}

TEST(Rotation, NearGimbalLockStaysAccurate) {
  // Phi just above 0 and just below pi: phi1 and phi2 are ill-conditioned separately, but the
  // rotation they describe must come back to full precision.
  for (double Phi : {1e-13, 1e-9, 1e-6, kPi - 1e-6, kPi - 1e-9, kPi - 1e-13}) {
    const Eigen::Vector3d euler(deg(123.0), Phi, deg(77.0));
    const Eigen::Matrix3d g = euler_to_matrix(euler);
    EXPECT_LT(max_abs_difference(euler_to_matrix(matrix_to_euler(g)), g), 1e-14) << Phi;
    EXPECT_LT(max_abs_difference(euler_to_matrix(quaternion_to_euler(matrix_to_quaternion(g))), g),
              1e-14)
        << Phi;
  }
}

TEST(Rotation, PassiveMatrixMapsKnownDirections) {
  // Euler (90, 0, 0): g = [[0,1,0],[-1,0,0],[0,0,1]]. Crystal directions go to the sample frame
  // with g^T, so the crystal [100] is sample +y, and the sample x axis is the crystal [0 -1 0].
  const Eigen::Matrix3d g = euler_to_matrix(Eigen::Vector3d(deg(90.0), 0.0, 0.0));
  Eigen::Matrix3d expected;
  expected << 0, 1, 0, -1, 0, 0, 0, 0, 1;
  EXPECT_LT(max_abs_difference(g, expected), 1e-15);
  EXPECT_LT((g.transpose() * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm(), 1e-15);
  EXPECT_LT((g * Eigen::Vector3d::UnitX() - Eigen::Vector3d(0, -1, 0)).norm(), 1e-15);

  // Euler (0, 90, 0): the crystal frame is the sample frame turned by +90 deg about x, so the
  // crystal [001] points along sample -y.
  const Eigen::Matrix3d tilted = euler_to_matrix(Eigen::Vector3d(0.0, deg(90.0), 0.0));
  EXPECT_LT((tilted.transpose() * Eigen::Vector3d::UnitZ() - Eigen::Vector3d(0, -1, 0)).norm(),
            1e-15);
}

TEST(Rotation, AxisAngleIsThePassiveTurnOfTheFrame) {
  EXPECT_LT(max_abs_difference(axis_angle_to_matrix(Eigen::Vector3d::UnitZ(), deg(90.0)),
                               euler_to_matrix(Eigen::Vector3d(deg(90.0), 0.0, 0.0))),
            1e-15);
  EXPECT_LT(max_abs_difference(axis_angle_to_matrix(Eigen::Vector3d(2.0, 0.0, 0.0), deg(90.0)),
                               euler_to_matrix(Eigen::Vector3d(0.0, deg(90.0), 0.0))),
            1e-15);
  const Quaternion q = axis_angle_to_quaternion(Eigen::Vector3d(1.0, 2.0, -2.0), 0.7);
  const AxisAngle back = quaternion_to_axis_angle(q);
  EXPECT_NEAR(back.angle, 0.7, 1e-15);
  EXPECT_LT((back.axis - Eigen::Vector3d(1.0, 2.0, -2.0) / 3.0).norm(), 1e-15);
  EXPECT_THROW(axis_angle_to_quaternion(Eigen::Vector3d::Zero(), 1.0), std::invalid_argument);
}

TEST(Rotation, ProductComposesMatricesInOrder) {
  const auto angles = random_euler_angles(200);
  for (std::size_t i = 0; i + 1 < angles.size(); ++i) {
    const Quaternion a = euler_to_quaternion(angles[i]);
    const Quaternion b = euler_to_quaternion(angles[i + 1]);
    EXPECT_LT(max_abs_difference(quaternion_to_matrix(a * b),
                                 quaternion_to_matrix(a) * quaternion_to_matrix(b)),
              1e-14);
  }
}

TEST(Rotation, MatrixToQuaternionHandlesHalfTurns) {
  // 180 deg turns make w = 0, where sign rules based on g_ij - g_ji break down.
  std::vector<Eigen::Vector3d> axes{{1, 0, 0}, {0, 1, 0},  {0, 0, 1},
                                    {1, 1, 0}, {1, -1, 1}, {-1, 2, 3}};
  for (const Eigen::Vector3d& axis : axes) {
    for (double angle : {kPi, kPi - 1e-12, kPi - 1e-6}) {
      const Eigen::Matrix3d g = axis_angle_to_matrix(axis, angle);
      EXPECT_LT(max_abs_difference(quaternion_to_matrix(matrix_to_quaternion(g)), g), 1e-14);
      EXPECT_NEAR(misorientation_angle(matrix_to_quaternion(g), Quaternion{}), angle, 1e-7);
    }
  }
}

TEST(Rotation, MisorientationAngleWithoutSymmetry) {
  const Quaternion a = euler_to_quaternion(Eigen::Vector3d(0.3, 1.1, 2.0));
  for (double angle : {0.0, 1e-10, 1e-5, 0.5, 2.0, kPi}) {
    const Quaternion b = a * axis_angle_to_quaternion(Eigen::Vector3d(0.3, -0.4, 1.0), angle);
    EXPECT_NEAR(misorientation_angle(a, b), angle, 1e-15 + 1e-12 * angle);
    EXPECT_NEAR(misorientation_angle(b, a), angle, 1e-15 + 1e-12 * angle);
  }
  const Quaternion minus_a{-a.w, -a.x, -a.y, -a.z};
  EXPECT_NEAR(misorientation_angle(a, minus_a), 0.0, 1e-15);
}

TEST(Rotation, ExponentialMapIsTheActiveRotation) {
  // Turning e_x by +90 deg about z gives e_y.
  const Eigen::Matrix3d R = rotation_exp(Eigen::Vector3d(0.0, 0.0, kPi / 2.0));
  EXPECT_LT((R * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm(), 1e-15);

  std::mt19937_64 engine(7);
  std::normal_distribution<double> normal;
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d axis(normal(engine), normal(engine), normal(engine));
    const double angle = std::abs(normal(engine));
    const Eigen::Vector3d w = angle * axis.normalized();
    EXPECT_LT(max_abs_difference(rotation_exp(w), axis_angle_to_matrix(axis, angle).transpose()),
              1e-14);
    EXPECT_TRUE(is_rotation(rotation_exp(w), 1e-14));
    if (angle < kPi - 1e-3) {
      EXPECT_LT((rotation_log(rotation_exp(w)) - w).norm(), 1e-12);
    }
  }
  // Both sides of the series' bound (t = 1/10), where one step's lattice spin lies: the
  // quaternion's rotation to round-off.
  for (double angle = 1e-6; angle < 0.4; angle *= 1.21) {
    const Eigen::Vector3d axis(normal(engine), normal(engine), normal(engine));
    const Eigen::Vector3d w = angle * axis.normalized();
    EXPECT_LT(max_abs_difference(rotation_exp(w), axis_angle_to_matrix(axis, angle).transpose()),
              1e-15)
        << angle;
  }
  // The series branch: a tiny increment must be exact to first and second order.
  const Eigen::Vector3d tiny(1e-9, -2e-9, 3e-9);
  Eigen::Matrix3d K;
  K << 0, -tiny.z(), tiny.y(), tiny.z(), 0, -tiny.x(), -tiny.y(), tiny.x(), 0;
  EXPECT_LT(max_abs_difference(rotation_exp(tiny), Eigen::Matrix3d::Identity() + K + 0.5 * K * K),
            1e-24);
}

TEST(Rotation, SampleSpinTurnsCrystalDirectionsInTheSampleFrame) {
  const Eigen::Matrix3d g = euler_to_matrix(Eigen::Vector3d(0.4, 0.9, 2.2));
  const Eigen::Vector3d spin(0.01, -0.03, 0.02);
  const Eigen::Matrix3d g_new = apply_sample_spin(g, spin);
  const Eigen::Vector3d crystal_direction(1.0, 1.0, 1.0);
  const Eigen::Vector3d before = g.transpose() * crystal_direction;
  const Eigen::Vector3d after = g_new.transpose() * crystal_direction;
  EXPECT_LT((after - rotation_exp(spin) * before).norm(), 1e-15);
  EXPECT_TRUE(is_rotation(g_new, 1e-14));
}

TEST(Rotation, OrientationHoldsBothRepresentations) {
  const Orientation o = Orientation::from_euler(Eigen::Vector3d(1.0, 2.0, 3.0), 0.25);
  EXPECT_LT(max_abs_difference(o.g, euler_to_matrix(Eigen::Vector3d(1.0, 2.0, 3.0))), 1e-14);
  EXPECT_GE(o.q.w, 0.0);
  EXPECT_EQ(o.weight, 0.25);
  const Orientation flipped = Orientation::from_quaternion(Quaternion{-0.5, -0.5, -0.5, -0.5});
  EXPECT_EQ(flipped.q.w, 0.5);
  EXPECT_FALSE(is_rotation(2.0 * Eigen::Matrix3d::Identity()));
  EXPECT_FALSE(is_rotation(Eigen::Vector3d(1.0, 1.0, -1.0).asDiagonal()));
}
