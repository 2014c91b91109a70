#include "subslip/crystal/elasticity.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <initializer_list>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

namespace subslip::crystal {

namespace {

constexpr double kSqrt2 = std::numbers::sqrt2;

// Mandel weights: 1 on the normal components, sqrt2 on the shear components.
MandelVector mandel_weights() {
  MandelVector w;
  w << 1.0, 1.0, 1.0, kSqrt2, kSqrt2, kSqrt2;
  return w;
}

// "C11=..., C12=..." for the error messages.
std::string list_constants(std::initializer_list<std::pair<const char*, double>> constants) {
  std::ostringstream text;
  text.precision(6);
  const char* separator = "";
  for (const auto& [name, value] : constants) {
    text << separator << name << "=" << value;
    separator = ", ";
  }
  return text.str();
}

void require_positive_definite(const MandelMatrix& C, const std::string& what,
                               const std::string& constants, const char* conditions) {
  const bool finite = C.allFinite();
  if (finite && smallest_eigenvalue(C) > 1e-12 * C.cwiseAbs().maxCoeff()) return;
  throw std::invalid_argument(what + " stiffness (" + constants + ") is " +
                              (finite ? "not positive definite" : "not finite") + ": it needs " +
                              conditions);
}

// C = lambda 1(x)1 + 2 G I, without checks.
MandelMatrix lame_stiffness(double lambda, double G) {
  MandelMatrix C = MandelMatrix::Zero();
  C.topLeftCorner<3, 3>().setConstant(lambda);
  C += 2.0 * G * MandelMatrix::Identity();
  return C;
}

constexpr const char* kIsotropicConditions =
    "shear modulus G > 0 and bulk modulus K > 0 "
    "(E > 0 and -1 < nu < 0.5)";

}  // namespace

MandelVector mandel_from_symmetric(const Eigen::Matrix3d& t) {
  MandelVector v;
  v << t(0, 0), t(1, 1), t(2, 2), kSqrt2 * 0.5 * (t(1, 2) + t(2, 1)),
      kSqrt2 * 0.5 * (t(0, 2) + t(2, 0)), kSqrt2 * 0.5 * (t(0, 1) + t(1, 0));
  return v;
}

Eigen::Matrix3d symmetric_from_mandel(const MandelVector& v) {
  const double t23 = v[3] / kSqrt2, t13 = v[4] / kSqrt2, t12 = v[5] / kSqrt2;
  Eigen::Matrix3d t;
  t << v[0], t12, t13,  //
      t12, v[1], t23,   //
      t13, t23, v[2];
  return t;
}

MandelMatrix mandel_from_voigt_stiffness(const MandelMatrix& voigt) {
  const MandelVector w = mandel_weights();
  return w.asDiagonal() * voigt * w.asDiagonal();
}

MandelMatrix voigt_from_mandel_stiffness(const MandelMatrix& mandel) {
  const MandelVector inverse_w = mandel_weights().cwiseInverse();
  return inverse_w.asDiagonal() * mandel * inverse_w.asDiagonal();
}

MandelMatrix mandel_rotation_operator(const Eigen::Matrix3d& R) {
  // Column j is the image of the j-th (orthonormal) Mandel basis tensor.
  MandelMatrix Q;
  for (int j = 0; j < 6; ++j) {
    const Eigen::Matrix3d basis_tensor = symmetric_from_mandel(MandelVector::Unit(j));
    Q.col(j) = mandel_from_symmetric(R * basis_tensor * R.transpose());
  }
  return Q;
}

MandelMatrix rotate_stiffness(const MandelMatrix& C, const Eigen::Matrix3d& R) {
  const MandelMatrix Q = mandel_rotation_operator(R);
  return Q * C * Q.transpose();
}

MandelMatrix stiffness_in_sample_frame(const MandelMatrix& C_lattice, const Eigen::Matrix3d& g) {
  return rotate_stiffness(C_lattice, g.transpose());
}

MandelMatrix isotropic_from_lambda_G(double lambda, double G) {
  const MandelMatrix C = lame_stiffness(lambda, G);
  require_positive_definite(C, "isotropic", list_constants({{"lambda", lambda}, {"G", G}}),
                            kIsotropicConditions);
  return C;
}

MandelMatrix isotropic_from_E_nu(double E, double nu) {
  const double G = E / (2.0 * (1.0 + nu));
  const double lambda = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
  const MandelMatrix C = lame_stiffness(lambda, G);
  require_positive_definite(C, "isotropic", list_constants({{"E", E}, {"nu", nu}}),
                            kIsotropicConditions);
  return C;
}

MandelMatrix isotropic_from_G_nu(double G, double nu) {
  const double lambda = 2.0 * G * nu / (1.0 - 2.0 * nu);
  const MandelMatrix C = lame_stiffness(lambda, G);
  require_positive_definite(C, "isotropic", list_constants({{"G", G}, {"nu", nu}}),
                            kIsotropicConditions);
  return C;
}

MandelMatrix isotropic_from_K_G(double K, double G) {
  const MandelMatrix C = lame_stiffness(K - 2.0 * G / 3.0, G);
  require_positive_definite(C, "isotropic", list_constants({{"K", K}, {"G", G}}),
                            kIsotropicConditions);
  return C;
}

MandelMatrix cubic_stiffness(double C11, double C12, double C44) {
  MandelMatrix voigt = MandelMatrix::Zero();
  voigt.topLeftCorner<3, 3>().setConstant(C12);
  voigt.diagonal() << C11, C11, C11, C44, C44, C44;
  const MandelMatrix C = mandel_from_voigt_stiffness(voigt);
  require_positive_definite(C, "cubic", list_constants({{"C11", C11}, {"C12", C12}, {"C44", C44}}),
                            "C44 > 0, C11 > |C12| and C11 + 2 C12 > 0");
  return C;
}

MandelMatrix hexagonal_stiffness(double C11, double C12, double C13, double C33, double C44) {
  MandelMatrix voigt = MandelMatrix::Zero();
  voigt.topLeftCorner<3, 3>() << C11, C12, C13,  //
      C12, C11, C13,                             //
      C13, C13, C33;
  voigt(3, 3) = voigt(4, 4) = C44;
  voigt(5, 5) = 0.5 * (C11 - C12);
  const MandelMatrix C = mandel_from_voigt_stiffness(voigt);
  require_positive_definite(
      C, "hexagonal",
      list_constants({{"C11", C11}, {"C12", C12}, {"C13", C13}, {"C33", C33}, {"C44", C44}}),
      "C44 > 0, C11 > |C12| and (C11 + C12) C33 > 2 C13^2");
  return C;
}

double zener_ratio(double C11, double C12, double C44) {
  return 2.0 * C44 / (C11 - C12);
}

double smallest_eigenvalue(const MandelMatrix& C) {
  const MandelMatrix symmetric = 0.5 * (C + C.transpose());
  Eigen::SelfAdjointEigenSolver<MandelMatrix> solver(symmetric, Eigen::EigenvaluesOnly);
  return solver.eigenvalues().minCoeff();
}

}  // namespace subslip::crystal
