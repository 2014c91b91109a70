// Rotation conventions: Rowenhorst et al. (2015), "Consistent representations of and conversions
// between 3D rotations", Modelling Simul. Mater. Sci. Eng. 23 083501, with P = -1 and PASSIVE
// rotations, the choice DAMASK makes.
//
// THE ORIENTATION MATRIX g maps SAMPLE-frame components to CRYSTAL-frame components:
//
//     v_crystal = g v_sample,        v_sample = g^T v_crystal.
//
// So the rows of g are the crystal axes written in the sample frame, and the columns of g are the
// sample axes written in the crystal frame. A crystal direction d (e.g. [1 0 0]) points along
// g^T d in the sample. A symmetric tensor goes crystal -> sample as T_sample = g^T T_crystal g.
//
// Bunge Euler angles (phi1, Phi, phi2) are radians, stored in an Eigen::Vector3d in that order
// (degrees only in files). g = Z(phi2) X(Phi) Z(phi1) with the passive elementary rotations:
//
//   g = [  c1 c2 - s1 s2 c    s1 c2 + c1 s2 c   s2 s ]
//       [ -c1 s2 - s1 c2 c   -s1 s2 + c1 c2 c   c2 s ]    (c = cos Phi, s = sin Phi)
//       [  s1 s              -c1 s              c    ]
//
// Example: Euler (90, 0, 0) deg gives g = [[0,1,0],[-1,0,0],[0,0,1]]: the crystal [100] lies along
// sample +y (the crystal frame is the sample frame turned by +90 deg about z).
//
// Quaternions q = (w, x, y, z) = (cos(omega/2), n sin(omega/2)) describe the same passive
// rotation as the axis-angle pair (n, omega): the crystal frame is obtained by turning the sample
// frame by +omega (right hand) about n. Conversions return w >= 0 (q and -q are the same
// rotation). The product a * b follows P = -1, so that matrix(a * b) = matrix(a) matrix(b).
//
// Ranges returned: phi1, phi2 in [0, 2 pi), Phi in [0, pi]. At Phi = 0 only phi1 + phi2 is
// defined and at Phi = pi only phi1 - phi2; as Rowenhorst does, phi2 is then set to 0.
#pragma once

#include <Eigen/Core>
#include <cmath>

namespace subslip::crystal {

struct Quaternion {
  double w = 1.0;
  double x = 0.0;
  double y = 0.0;
  double z = 0.0;

  Eigen::Vector3d vector_part() const { return {x, y, z}; }
  Eigen::Vector4d as_vector() const { return {w, x, y, z}; }
  double norm() const;
  Quaternion conjugate() const { return {w, -x, -y, -z}; }
  Quaternion normalized() const;
  // The same rotation with w >= 0.
  Quaternion canonical() const;
};

// Quaternion product with P = -1: matrix(a * b) = matrix(a) * matrix(b), i.e. b is applied first
// (sample -> intermediate frame), then a.
Quaternion operator*(const Quaternion& a, const Quaternion& b);
double dot(const Quaternion& a, const Quaternion& b);

// An orientation as read from a file or generated: both representations, plus a weight
// (volume fraction up to normalisation) for aggregates.
struct Orientation {
  Quaternion q;                                     // canonical (w >= 0), unit
  Eigen::Matrix3d g = Eigen::Matrix3d::Identity();  // quaternion_to_matrix(q)
  double weight = 1.0;

  static Orientation from_quaternion(const Quaternion& q, double weight = 1.0);
  static Orientation from_matrix(const Eigen::Matrix3d& g, double weight = 1.0);
  static Orientation from_euler(const Eigen::Vector3d& euler_radians, double weight = 1.0);
};

Eigen::Matrix3d euler_to_matrix(const Eigen::Vector3d& euler);
// Goes through the quaternion, which keeps phi1 + phi2 accurate close to Phi = 0.
Eigen::Vector3d matrix_to_euler(const Eigen::Matrix3d& g);
Quaternion euler_to_quaternion(const Eigen::Vector3d& euler);
Eigen::Vector3d quaternion_to_euler(const Quaternion& q);
Eigen::Matrix3d quaternion_to_matrix(const Quaternion& q);
// Shepperd's branch on the largest of (trace, g11, g22, g33): no cancellation for any rotation,
// including 180 deg turns where the sign rules of Rowenhorst's om2qu become ambiguous.
Quaternion matrix_to_quaternion(const Eigen::Matrix3d& g);

// Passive rotation by `angle` (radians) about `axis` (any non-zero length; normalised here).
// Throws std::invalid_argument for a zero axis.
Quaternion axis_angle_to_quaternion(const Eigen::Vector3d& axis, double angle);
Eigen::Matrix3d axis_angle_to_matrix(const Eigen::Vector3d& axis, double angle);

struct AxisAngle {
  Eigen::Vector3d axis;  // unit; +z when the angle is 0
  double angle;          // radians, in [0, pi]
};
AxisAngle quaternion_to_axis_angle(const Quaternion& q);

// Angle (radians, [0, pi]) of the rotation taking orientation b to orientation a, without crystal
// symmetry. Computed with atan2 so that small angles keep full precision.
double misorientation_angle(const Quaternion& a, const Quaternion& b);

// Rodrigues' formula: the ACTIVE rotation matrix exp([w]x) that turns vectors by |w| about w/|w|
// (right hand). Series near w = 0, so it is exact for tiny increments.
//   rotation_exp(omega n) == axis_angle_to_matrix(n, omega)^T   (active = transpose of passive).
// Inline: the grain step calls it a few times per step and compiles it with its own
// instruction set.
inline Eigen::Matrix3d rotation_exp(const Eigen::Vector3d& w) {
  const double theta2 = w.squaredNorm();
  // sin(t)/t and (1 - cos t)/t^2 by their Taylor series to t^8 for t < 1/10 (the lattice
  // spin of one step, nearly always): the first terms left out, t^10/11! and t^10/12!, are below
  // 3e-18, under the rounding of the quotients, which would also pay a sine and a cosine. The
  // series' coefficients are constants (Horner's form with multiplications: a division on this
  // chain of dependent operations costs several multiplications' time, and the rotations of a
  // grain step are a few per cent of it).
  double a, b;
  if (theta2 < 1e-2) {
    constexpr double a1 = -1.0 / 6.0, a2 = 1.0 / 120.0, a3 = -1.0 / 5040.0, a4 = 1.0 / 362880.0;
    constexpr double b1 = -1.0 / 24.0, b2 = 1.0 / 720.0, b3 = -1.0 / 40320.0, b4 = 1.0 / 3628800.0;
    const double t2 = theta2;
    a = 1.0 + t2 * (a1 + t2 * (a2 + t2 * (a3 + t2 * a4)));
    b = 0.5 + t2 * (b1 + t2 * (b2 + t2 * (b3 + t2 * b4)));
  } else {
    // Through the half angle: 1 - cos t = 2 sin^2(t/2) keeps its digits.
    const double theta = std::sqrt(theta2);
    const double sin_half = std::sin(0.5 * theta), cos_half = std::cos(0.5 * theta);
    a = 2.0 * sin_half * cos_half / theta;
    b = 2.0 * sin_half * sin_half / theta2;
  }
  // R = I + a [w] + b [w]^2, with [w]^2 = w w^T - |w|^2 I.
  Eigen::Matrix3d r = b * (w * w.transpose());
  r.diagonal().array() += 1.0 - b * theta2;
  r(0, 1) -= a * w.z(), r(1, 0) += a * w.z();
  r(0, 2) += a * w.y(), r(2, 0) -= a * w.y();
  r(1, 2) -= a * w.x(), r(2, 1) += a * w.x();
  return r;
}

// The inverse: the axial vector (angle in [0, pi]) of an active rotation matrix.
Eigen::Vector3d rotation_log(const Eigen::Matrix3d& active_rotation);

// Orientation update for a lattice spin increment w (axial vector of W dt, SAMPLE frame): the
// lattice turns actively by rotation_exp(w), so crystal directions in the sample frame become
// R g^T d, i.e. g_new = g R^T.
Eigen::Matrix3d apply_sample_spin(const Eigen::Matrix3d& g, const Eigen::Vector3d& spin_increment);

// det(g) = 1 and g g^T = I to within `tolerance` (max-norm).
bool is_rotation(const Eigen::Matrix3d& g, double tolerance = 1e-10);

Eigen::Vector3d degrees_to_radians(const Eigen::Vector3d& degrees);
Eigen::Vector3d radians_to_degrees(const Eigen::Vector3d& radians);

}  // namespace subslip::crystal
