// umat_ at finite strain: DDSDDE is Abaqus' NLGEOM Jacobian, checked against the perturbation
// of DFGRD1 that defines it (Miehe 1996; Sun, Chaikof and Levenston 2008): column j is
// (tau(F1 + dF) - tau(F1 - dF)) / (2 J eps), dF = (eps / 2)(e_k e_l^T + e_l e_k^T) F1 with (k, l)
// the tensor indices of component j and tau = J sigma the Kirchhoff stress (engineering shears:
// eps is gamma). In an elastic and an elasto-plastic increment with a rotation of 0.1 rad, for
// a single crystal and a Taylor aggregate.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>

#include "subslip/crystal/rotation.hpp"
#include "umat_call.hpp"

namespace {

using namespace subslip::fe_testing;

constexpr std::array<std::array<int, 2>, 6> kAbaqusIndices = {
    {{0, 0}, {1, 1}, {2, 2}, {0, 1}, {0, 2}, {1, 2}}};

void set_f(std::array<double, 9>& out, const Eigen::Matrix3d& f) {
  Eigen::Map<Eigen::Matrix3d>(out.data()) = f;  // column major, as Fortran stores it
}

// One increment F0 -> F1 over dt from `start`'s state.
UmatPoint increment(const UmatPoint& start, const Eigen::Matrix3d& f0, const Eigen::Matrix3d& f1,
                    double dt) {
  UmatPoint u = start;
  set_f(u.dfgrd0, f0);
  set_f(u.dfgrd1, f1);
  EXPECT_EQ(u.call({}, dt), 1.0) << last_message();
  return u;
}

// The largest relative difference between DDSDDE of the increment and the central differences
// of the Kirchhoff stress over J under the perturbation of F1. The Kirchhoff term of the
// Jacobian alone (sigma (x) I) is checked to be far above the tolerance, so that the test tells
// the Jacobian from the Cauchy stress's derivative.
double jacobian_error(const UmatPoint& start, const Eigen::Matrix3d& f0, const Eigen::Matrix3d& f1,
                      double dt) {
  const UmatPoint at = increment(start, f0, f1, dt);
  double scale = 0.0, kirchhoff = 0.0;
  for (double v : at.ddsdde) scale = std::max(scale, std::abs(v));
  for (double v : at.stress) kirchhoff = std::max(kirchhoff, std::abs(v));
  EXPECT_GT(kirchhoff / scale, 1e-5);
  std::printf("Kirchhoff term / largest entry of DDSDDE: %.2e\n", kirchhoff / scale);
  const double h = 1e-8, j = f1.determinant();
  double error = 0.0;
  for (int c = 0; c < 6; ++c) {
    Eigen::Matrix3d e = Eigen::Matrix3d::Zero();
    const auto [k, l] = kAbaqusIndices[static_cast<std::size_t>(c)];
    e(k, l) += 0.5 * h;
    e(l, k) += 0.5 * h;
    const Eigen::Matrix3d fp = (Eigen::Matrix3d::Identity() + e) * f1;
    const Eigen::Matrix3d fm = (Eigen::Matrix3d::Identity() - e) * f1;
    const UmatPoint plus = increment(start, f0, fp, dt);
    const UmatPoint minus = increment(start, f0, fm, dt);
    for (int i = 0; i < 6; ++i) {
      const auto a = static_cast<std::size_t>(i);
      const double fd =
          (fp.determinant() * plus.stress[a] - fm.determinant() * minus.stress[a]) / (2 * h * j);
      error = std::max(error, std::abs(at.ddsdde_at(i, c) - fd) / scale);
    }
  }
  return error;
}

// Tension with shear seen from a frame turning 0.5 rad/s about a skew axis: F(t) = Q(t)(I + t G).
struct TurningMotion {
  Eigen::Matrix3d g;
  double dt = 0.2;                                                                 // [s]
  TurningMotion() { g << -0.5e-3, 2e-3, 0.0, 0.0, -0.5e-3, 0.0, 0.0, 0.0, 1e-3; }  // [1/s]
  Eigen::Matrix3d rotation(double t) const {
    return subslip::crystal::rotation_exp(Eigen::Vector3d(1.0, 2.0, 3.0).normalized() * 0.5 * t);
  }
  Eigen::Matrix3d at(double t) const { return rotation(t) * (Eigen::Matrix3d::Identity() + t * g); }
};

// The slip increment summed over the systems of every grain, |dgamma|, from `a` to `b`.
double slip_change(const UmatPoint& a, const UmatPoint& b, int grains) {
  double s = 0.0;
  for (int g = 0; g < grains; ++g)
    for (int k = 0; k < 12; ++k) {
      const auto i = static_cast<std::size_t>(1 + g * SUBSLIP_UMAT_GRAIN_BLOCK(12) + 16 + 24 + k);
      s += std::abs(b.statev[i] - a.statev[i]);
    }
  return s;
}

std::vector<double> finite(std::vector<double> p) {
  p[SUBSLIP_UMAT_STRAIN - 1] = 1;
  return p;
}

// Loading into plastic flow, then an elasto-plastic increment and an unloading (elastic) one.
void expect_jacobians(const std::vector<double>& props, int grains) {
  const TurningMotion m;
  UmatPoint u(finite(props));
  for (int k = 1; k <= 12; ++k) u = increment(u, m.at(m.dt * (k - 1)), m.at(m.dt * k), m.dt);
  ASSERT_GT(slip_change(UmatPoint(finite(props)), u, grains), 1e-4);

  const Eigen::Matrix3d f0 = m.at(12 * m.dt), f1 = m.at(13 * m.dt);
  const UmatPoint plastic = increment(u, f0, f1, m.dt);
  const double plastic_slip = slip_change(u, plastic, grains);
  EXPECT_GT(plastic_slip, 1e-5);  // the increment slips
  const double plastic_error = jacobian_error(u, f0, f1, m.dt);
  EXPECT_LT(plastic_error, 1e-6);

  // Unloading: 0.005 s of the stretch undone while the frame keeps turning.
  const Eigen::Matrix3d back =
      m.rotation(13 * m.dt) * (Eigen::Matrix3d::Identity() + (12 * m.dt - 0.005) * m.g);
  const UmatPoint elastic = increment(u, f0, back, m.dt);
  const double elastic_slip = slip_change(u, elastic, grains);
  // An elastic increment: no slip in the crystal; in the aggregate 2e-8, on a system of a grain
  // the unloading leaves near its reversal.
  EXPECT_LT(elastic_slip, 1e-4 * plastic_slip);
  const double elastic_error = jacobian_error(u, f0, back, m.dt);
  EXPECT_LT(elastic_error, 1e-6);
  std::printf(
      "Jacobian against the perturbation of F1: plastic %.2e (slip %.2e), elastic %.2e (slip "
      "%.2e)\n",
      plastic_error, plastic_slip, elastic_error, elastic_slip);
}

TEST(FeUmatFinite, DdsddeIsAbaqusJacobianOfTheIncrement) {
  expect_jacobians(fcc_props({30, 40, 50}), 1);
}

TEST(FeUmatFinite, DdsddeIsAbaqusJacobianOfTheTaylorIncrement) {
  expect_jacobians(taylor_fcc_props(), 3);
}

}  // namespace
