#include "subslip/crystal/rotation.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace subslip::crystal {

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kTwoPi = 2.0 * std::numbers::pi;

// Below this value of sin^2(Phi/2) (or cos^2(Phi/2)) the rotation is treated as Phi = 0 (or pi):
// phi1 and phi2 are then no longer separately defined and Rowenhorst's degenerate branch applies.
// Above it the general formulas stay accurate (see quaternion_to_euler), so the threshold only
// has to catch the exact cases, including Phi = pi in floating point (cos^2(pi/2) = 4e-33); the
// error made by the branch is of the order of sqrt(threshold) = 1e-15 rad.
constexpr double kGimbalThreshold = 1e-30;

double wrap_to_two_pi(double angle) {
  double wrapped = angle - kTwoPi * std::floor(angle / kTwoPi);
  // floor can leave exactly 2 pi after rounding for angles just below a multiple of 2 pi.
  if (wrapped >= kTwoPi) wrapped -= kTwoPi;
  return wrapped;
}

Eigen::Vector3d wrap_euler(double phi1, double Phi, double phi2) {
  return {wrap_to_two_pi(phi1), Phi, wrap_to_two_pi(phi2)};
}

}  // namespace

double Quaternion::norm() const {
  return std::sqrt(w * w + x * x + y * y + z * z);
}

Quaternion Quaternion::normalized() const {
  const double n = norm();
  return {w / n, x / n, y / n, z / n};
}

Quaternion Quaternion::canonical() const {
  return w < 0.0 ? Quaternion{-w, -x, -y, -z} : *this;
}

Quaternion operator*(const Quaternion& a, const Quaternion& b) {
  // Rowenhorst eq. (23) with P = -1: the cross product enters with a minus sign.
  const Eigen::Vector3d va = a.vector_part();
  const Eigen::Vector3d vb = b.vector_part();
  const Eigen::Vector3d v = a.w * vb + b.w * va - va.cross(vb);
  return {a.w * b.w - va.dot(vb), v.x(), v.y(), v.z()};
}

double dot(const Quaternion& a, const Quaternion& b) {
  return a.w * b.w + a.x * b.x + a.y * b.y + a.z * b.z;
}

Orientation Orientation::from_quaternion(const Quaternion& q, double weight) {
  const Quaternion unit = q.normalized().canonical();
  return {unit, quaternion_to_matrix(unit), weight};
}

Orientation Orientation::from_matrix(const Eigen::Matrix3d& g, double weight) {
  return from_quaternion(matrix_to_quaternion(g), weight);
}

Orientation Orientation::from_euler(const Eigen::Vector3d& euler_radians, double weight) {
  return from_quaternion(euler_to_quaternion(euler_radians), weight);
}

Eigen::Matrix3d euler_to_matrix(const Eigen::Vector3d& euler) {
  const double c1 = std::cos(euler[0]), s1 = std::sin(euler[0]);
  const double c = std::cos(euler[1]), s = std::sin(euler[1]);
  const double c2 = std::cos(euler[2]), s2 = std::sin(euler[2]);
  Eigen::Matrix3d g;
  g << c1 * c2 - s1 * s2 * c, s1 * c2 + c1 * s2 * c, s2 * s,   //
      -c1 * s2 - s1 * c2 * c, -s1 * s2 + c1 * c2 * c, c2 * s,  //
      s1 * s, -c1 * s, c;
  return g;
}

Eigen::Vector3d matrix_to_euler(const Eigen::Matrix3d& g) {
  // Through the quaternion rather than Rowenhorst's om2eu: near Phi = 0 the direct formulas take
  // phi1 and phi2 from independent, nearly vanishing entries (g31, g32 and g13, g23), so their
  // rounding errors do not cancel in phi1 + phi2, the one angle that matters there. In qu2eu the
  // same noisy x, y enter both angles and cancel in the sum.
  return quaternion_to_euler(matrix_to_quaternion(g));
}

Quaternion euler_to_quaternion(const Eigen::Vector3d& euler) {
  // Rowenhorst eu2qu with P = -1: sigma = (phi1 + phi2)/2, delta = (phi1 - phi2)/2.
  const double sigma = 0.5 * (euler[0] + euler[2]);
  const double delta = 0.5 * (euler[0] - euler[2]);
  const double c = std::cos(0.5 * euler[1]);
  const double s = std::sin(0.5 * euler[1]);
  const Quaternion q{c * std::cos(sigma), s * std::cos(delta), s * std::sin(delta),
                     c * std::sin(sigma)};
  return q.canonical();
}

Eigen::Vector3d quaternion_to_euler(const Quaternion& q_in) {
  const Quaternion q = q_in.normalized();
  const double q03 = q.w * q.w + q.z * q.z;  // cos^2(Phi/2)
  const double q12 = q.x * q.x + q.y * q.y;  // sin^2(Phi/2)
  if (q12 <= kGimbalThreshold) {
    return wrap_euler(std::atan2(2.0 * q.w * q.z, q.w * q.w - q.z * q.z), 0.0, 0.0);
  }
  if (q03 <= kGimbalThreshold) {
    return wrap_euler(std::atan2(2.0 * q.x * q.y, q.x * q.x - q.y * q.y), kPi, 0.0);
  }
  // Rowenhorst qu2eu with P = -1. The common factor 1/chi cancels inside atan2. Close to
  // Phi = 0 the small x, y carry an ill-determined (phi1 - phi2)/2, but it enters phi1 and phi2
  // with opposite signs, so phi1 + phi2, which is what the rotation depends on, stays accurate.
  const double chi = std::sqrt(q03 * q12);
  const double phi1 = std::atan2(q.x * q.z + q.w * q.y, q.w * q.x - q.y * q.z);
  const double Phi = std::atan2(2.0 * chi, q03 - q12);
  const double phi2 = std::atan2(q.x * q.z - q.w * q.y, q.y * q.z + q.w * q.x);
  return wrap_euler(phi1, Phi, phi2);
}

Eigen::Matrix3d quaternion_to_matrix(const Quaternion& q_in) {
  // Rowenhorst qu2om with P = -1.
  const Quaternion q = q_in.normalized();
  const double qbar = q.w * q.w - (q.x * q.x + q.y * q.y + q.z * q.z);
  Eigen::Matrix3d g;
  g << qbar + 2.0 * q.x * q.x, 2.0 * (q.x * q.y + q.w * q.z), 2.0 * (q.x * q.z - q.w * q.y),
      2.0 * (q.x * q.y - q.w * q.z), qbar + 2.0 * q.y * q.y, 2.0 * (q.y * q.z + q.w * q.x),
      2.0 * (q.x * q.z + q.w * q.y), 2.0 * (q.y * q.z - q.w * q.x), qbar + 2.0 * q.z * q.z;
  return g;
}

Quaternion matrix_to_quaternion(const Eigen::Matrix3d& g) {
  // From qu2om (P = -1): g23 - g32 = 4 w x, g31 - g13 = 4 w y, g12 - g21 = 4 w z,
  // g12 + g21 = 4 x y, g13 + g31 = 4 x z, g23 + g32 = 4 y z, and 4 w^2 = 1 + trace,
  // 4 x^2 = 1 + g11 - g22 - g33, etc. Take the root of the largest square (never small: it is
  // at least 1/4) and the other three components from the off-diagonal sums and differences.
  const double trace = g.trace();
  Quaternion q;
  if (trace >= g(0, 0) && trace >= g(1, 1) && trace >= g(2, 2)) {
    q.w = 0.5 * std::sqrt(1.0 + trace);
    const double f = 0.25 / q.w;
    q.x = f * (g(1, 2) - g(2, 1));
    q.y = f * (g(2, 0) - g(0, 2));
    q.z = f * (g(0, 1) - g(1, 0));
  } else if (g(0, 0) >= g(1, 1) && g(0, 0) >= g(2, 2)) {
    q.x = 0.5 * std::sqrt(std::max(0.0, 1.0 + g(0, 0) - g(1, 1) - g(2, 2)));
    const double f = 0.25 / q.x;
    q.w = f * (g(1, 2) - g(2, 1));
    q.y = f * (g(0, 1) + g(1, 0));
    q.z = f * (g(0, 2) + g(2, 0));
  } else if (g(1, 1) >= g(2, 2)) {
    q.y = 0.5 * std::sqrt(std::max(0.0, 1.0 - g(0, 0) + g(1, 1) - g(2, 2)));
    const double f = 0.25 / q.y;
    q.w = f * (g(2, 0) - g(0, 2));
    q.x = f * (g(0, 1) + g(1, 0));
    q.z = f * (g(1, 2) + g(2, 1));
  } else {
    q.z = 0.5 * std::sqrt(std::max(0.0, 1.0 - g(0, 0) - g(1, 1) + g(2, 2)));
    const double f = 0.25 / q.z;
    q.w = f * (g(0, 1) - g(1, 0));
    q.x = f * (g(0, 2) + g(2, 0));
    q.y = f * (g(1, 2) + g(2, 1));
  }
  return q.normalized().canonical();
}

Quaternion axis_angle_to_quaternion(const Eigen::Vector3d& axis, double angle) {
  const double length = axis.norm();
  if (!(length > 0.0)) throw std::invalid_argument("rotation axis must be non-zero");
  const Eigen::Vector3d v = std::sin(0.5 * angle) / length * axis;
  return Quaternion{std::cos(0.5 * angle), v.x(), v.y(), v.z()}.canonical();
}

Eigen::Matrix3d axis_angle_to_matrix(const Eigen::Vector3d& axis, double angle) {
  return quaternion_to_matrix(axis_angle_to_quaternion(axis, angle));
}

AxisAngle quaternion_to_axis_angle(const Quaternion& q_in) {
  const Quaternion q = q_in.normalized().canonical();
  const Eigen::Vector3d v = q.vector_part();
  const double sin_half = v.norm();
  if (sin_half == 0.0) return {Eigen::Vector3d::UnitZ(), 0.0};
  return {v / sin_half, 2.0 * std::atan2(sin_half, q.w)};
}

double misorientation_angle(const Quaternion& a, const Quaternion& b) {
  const Quaternion delta = a.normalized() * b.normalized().conjugate();
  return 2.0 * std::atan2(delta.vector_part().norm(), std::abs(delta.w));
}

Eigen::Vector3d rotation_log(const Eigen::Matrix3d& active_rotation) {
  // The passive matrix of the same axis-angle pair is the transpose.
  const AxisAngle aa = quaternion_to_axis_angle(matrix_to_quaternion(active_rotation.transpose()));
  return aa.angle * aa.axis;
}

Eigen::Matrix3d apply_sample_spin(const Eigen::Matrix3d& g, const Eigen::Vector3d& spin_increment) {
  return g * rotation_exp(spin_increment).transpose();
}

bool is_rotation(const Eigen::Matrix3d& g, double tolerance) {
  const double orthogonality =
      (g * g.transpose() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  return orthogonality <= tolerance && std::abs(g.determinant() - 1.0) <= tolerance;
}

Eigen::Vector3d degrees_to_radians(const Eigen::Vector3d& degrees) {
  return degrees * (kPi / 180.0);
}

Eigen::Vector3d radians_to_degrees(const Eigen::Vector3d& radians) {
  return radians * (180.0 / kPi);
}

}  // namespace subslip::crystal
