// umat_ at finite strain (DFGRD0, DFGRD1) and as a Taylor aggregate (PROPS(1) = 2): a rigid
// rotation superposed on a motion leaves everything in the lattice frame unchanged and turns
// the stress with it; simple shear approaches the native grain under the same constant velocity
// gradient as the increments shrink; the aggregate equals the API's TaylorPoint.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstdio>

#include "subslip/crystal/rotation.hpp"
#include "umat_call.hpp"

namespace {

using namespace subslip::fe_testing;

const Eigen::Vector3d kEuler(30.0, 40.0, 50.0);  // [deg]

std::vector<double> finite_props() {
  std::vector<double> p = fcc_props(kEuler);
  p[SUBSLIP_UMAT_STRAIN - 1] = 1;
  return p;
}

void set_f(std::array<double, 9>& out, const Eigen::Matrix3d& f) {
  Eigen::Map<Eigen::Matrix3d>(out.data()) = f;  // column major, as Fortran stores it
}

double max_abs(const double* v, int n) {
  double s = 0.0;
  for (int i = 0; i < n; ++i) s = std::max(s, std::abs(v[i]));
  return s;
}

// Tension with shear, then back: F(t) = I + t G (t in s), and the same motion seen from a frame
// turning by 0.1 rad per increment about a skew axis (3 rad in all).
TEST(FeUmatFinite, ASuperposedRotationLeavesTheLatticeStressUnchanged) {
  UmatPoint plain(finite_props()), turned(finite_props());
  Eigen::Matrix3d g;
  g << -0.5e-3, 2e-3, 0.0, 0.0, -0.5e-3, 0.0, 0.0, 0.0, 1e-3;  // [1/s]
  const Eigen::Vector3d axis(1.0, 2.0, 3.0);
  const double dt = 0.2, omega = 0.5;  // [s], [rad/s]
  auto motion = [&](int k) {
    const double t = dt * (k <= 20 ? k : 40 - k);  // out and back
    return Eigen::Matrix3d(Eigen::Matrix3d::Identity() + t * g);
  };
  auto rotation = [&](int k) {  // active rotation of the observer's frame
    return subslip::crystal::rotation_exp(axis.normalized() * omega * dt * k);
  };
  for (int k = 1; k <= 30; ++k) {
    set_f(plain.dfgrd0, motion(k - 1));
    set_f(plain.dfgrd1, motion(k));
    set_f(turned.dfgrd0, rotation(k - 1) * motion(k - 1));
    set_f(turned.dfgrd1, rotation(k) * motion(k));
    ASSERT_EQ(plain.call({}, dt), 1.0) << subslip::fe_testing::last_message();
    ASSERT_EQ(turned.call({}, dt), 1.0) << subslip::fe_testing::last_message();
    SCOPED_TRACE("increment " + std::to_string(k));
    // The lattice frame: stress (STATEV 2..7), mu, r_s, slip.
    const double* a = plain.statev.data() + 1;
    const double* b = turned.statev.data() + 1;
    const double stress_scale = max_abs(a, 6);
    for (int i = 0; i < 6; ++i) EXPECT_NEAR(b[i], a[i], 1e-10 * stress_scale) << i;
    for (int field = 0; field < 3; ++field) {  // mu, r_s, slip
      const int first = 16 + 12 * field;
      const double scale = std::max(max_abs(a + first, 12), 1e-300);
      for (int i = first; i < first + 12; ++i) EXPECT_NEAR(b[i], a[i], 1e-10 * scale) << i;
    }
    // The sample frame: the stress turned with the observer.
    Eigen::Matrix3d s_plain, s_turned;
    s_plain << plain.stress[0], plain.stress[3], plain.stress[4], plain.stress[3], plain.stress[1],
        plain.stress[5], plain.stress[4], plain.stress[5], plain.stress[2];
    s_turned << turned.stress[0], turned.stress[3], turned.stress[4], turned.stress[3],
        turned.stress[1], turned.stress[5], turned.stress[4], turned.stress[5], turned.stress[2];
    const Eigen::Matrix3d expected = rotation(k) * s_plain * rotation(k).transpose();
    EXPECT_LE((s_turned - expected).cwiseAbs().maxCoeff(), 1e-10 * stress_scale);
  }
  EXPECT_GT(max_abs(plain.statev.data() + 1 + 16 + 24, 12), 1e-3);  // slip: plastic flow
}

// Simple shear F = I + gamma_dot t e1 x e2: the increment's stretch and rotation approach the
// constant velocity gradient of the native grain as dt shrinks (splitting the increment into a
// stretch and a rotation differs from the constant velocity gradient by O(dt^2)).
TEST(FeUmatFinite, SimpleShearApproachesTheNativeGrainAsIncrementsShrink) {
  const double rate = 1e-3, duration = 200.0;  // to a shear of 0.2  // [1/s], [s]
  Eigen::Matrix3d l = Eigen::Matrix3d::Zero();
  l(0, 1) = rate;
  auto difference = [&](int increments) {
    const double dt = duration / increments;
    UmatPoint u(finite_props());
    const pt::GrainPoint grain(fcc_parameters());
    pt::GrainState s = grain.initial_state(orientation_of(kEuler));
    pt::Mandel6 native = pt::Mandel6::Zero();
    for (int k = 1; k <= increments; ++k) {
      Eigen::Matrix3d f0 = Eigen::Matrix3d::Identity(), f1 = Eigen::Matrix3d::Identity();
      f0(0, 1) = rate * dt * (k - 1);
      f1(0, 1) = rate * dt * k;
      set_f(u.dfgrd0, f0);
      set_f(u.dfgrd1, f1);
      EXPECT_EQ(u.call({}, dt), 1.0) << subslip::fe_testing::last_message();
      const pt::GrainUpdate n = grain.update(s, l, dt);
      EXPECT_TRUE(n.report.ok);
      s = n.state;
      native = n.stress;
    }
    const auto expected = abaqus_stress(native);
    double d = 0.0, scale = 0.0;
    for (int i = 0; i < 6; ++i) {
      d = std::max(d, std::abs(u.stress[static_cast<std::size_t>(i)] -
                               expected[static_cast<std::size_t>(i)]));
      scale = std::max(scale, std::abs(expected[static_cast<std::size_t>(i)]));
    }
    return d / scale;
  };
  const double coarse = difference(50), fine = difference(200);
  // Measured: 3.3e-7 and 2.0e-8 (and 2.2e-9 with 800 increments): second order in dt.
  EXPECT_LT(fine, 1e-6);
  EXPECT_LT(fine, 0.25 * coarse);  // at least first order
}

// exp of a symmetric matrix.
Eigen::Matrix3d symmetric_exp(const Eigen::Matrix3d& e) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> s(e);
  return s.eigenvectors() * s.eigenvalues().array().exp().matrix().asDiagonal() *
         s.eigenvectors().transpose();
}

// Uniaxial stress along 33 at finite strain: each increment F1 = exp(E) F0 with E symmetric (a
// stretch without rotation, log U = E), its lateral components (all but 33, Abaqus order with
// engineering shears) solved by Newton with DDSDDE so that the lateral stresses vanish. The
// native grain takes L = E / dt with its own iteration on the lateral strains.
TEST(FeUmatFinite, UniaxialStressWithDdsddeEqualsTheNativeGrain) {
  constexpr std::array<int, 5> lateral = {0, 1, 3, 4, 5};  // Abaqus components
  UmatPoint u(finite_props());
  const pt::GrainPoint grain(fcc_parameters());
  pt::GrainState s = grain.initial_state(orientation_of(kEuler));
  Eigen::Matrix3d f = Eigen::Matrix3d::Identity();
  const double dt = 0.2;  // [s]
  int step = 0, newton_iterations = 0;
  // The stress scale of the path (its largest stress so far): the lateral stresses are resolved,
  // and compared, relative to it. (Relative to the axial stress of the moment they could not
  // be: after the reversal it passes through zero while the grain's stresses stay at their
  // level, and so does the round-off of its solve.)
  double path_scale = 0.0;
  for (const auto& [increments, d33] : {std::pair{20, 2e-4}, std::pair{30, -2e-4}}) {
    for (int k = 0; k < increments; ++k, ++step) {
      const UmatPoint start = u;
      std::array<double, 6> e{0, 0, d33, 0, 0, 0};  // engineering shears
      bool converged = false;
      for (int it = 0; it < 30 && !converged; ++it, ++newton_iterations) {
        u = start;
        set_f(u.dfgrd0, f);
        set_f(u.dfgrd1, symmetric_exp(rate_of(e, 1.0)) * f);
        ASSERT_EQ(u.call({}, dt), 1.0) << last_message();
        Eigen::Matrix<double, 5, 1> r;
        Eigen::Matrix<double, 5, 5> j;
        for (int a = 0; a < 5; ++a) {
          r(a) = u.stress[static_cast<std::size_t>(lateral[a])];
          for (int b = 0; b < 5; ++b) j(a, b) = u.ddsdde_at(lateral[a], lateral[b]);
        }
        converged = r.norm() <= 1e-11 * std::max(path_scale, std::abs(u.stress[2]));
        if (converged) break;
        const Eigen::Matrix<double, 5, 1> change = j.partialPivLu().solve(r);
        for (int a = 0; a < 5; ++a) e[static_cast<std::size_t>(lateral[a])] -= change(a);
      }
      ASSERT_TRUE(converged) << "increment " << step;
      f = symmetric_exp(rate_of(e, 1.0)) * f;
      const pt::GrainUpdate n = native_uniaxial_step(grain, s, d33, dt);
      s = n.state;
      const auto expected = abaqus_stress(n.stress);
      path_scale = std::max(path_scale, max_abs(expected.data(), 6));
      const double scale = path_scale;
      for (std::size_t i = 0; i < 6; ++i)
        EXPECT_NEAR(u.stress[i], expected[i], 1e-10 * scale) << "increment " << step;
      const double* b = u.statev.data() + 1;
      for (int i = 0; i < 6; ++i) EXPECT_NEAR(b[i], s.stress(i), 1e-10 * scale) << step;
      const double slip_scale = std::max(s.slip.cwiseAbs().maxCoeff(), 1e-3);
      for (int a = 0; a < 12; ++a)
        EXPECT_NEAR(b[16 + 24 + a], s.slip(a), 1e-10 * slip_scale) << step;
    }
  }
  EXPECT_GT(s.slip.cwiseAbs().maxCoeff(), 1e-3);  // well into plastic flow
  EXPECT_LT(u.stress[2], -2.0 * kTau0);           // and reversed into compression
  std::printf("finite-strain uniaxial stress: %d Newton iterations over %d increments\n",
              newton_iterations, step);
}

// A finite-strain increment the grain solver cannot take (one Newton iteration allowed): PNEWDT
// < 1, and STRESS, STATEV, SSE, SPD, SCD as they came in; the default solver takes it.
TEST(FeUmatFinite, AFailedIncrementCutsBackAndLeavesStressAndStatev) {
  UmatPoint u(finite_props());
  Eigen::Matrix3d g;
  g << -0.5e-3, 2e-3, 0.0, 0.0, -0.5e-3, 0.0, 0.0, 0.0, 1e-3;  // [1/s]
  const double dt = 0.2;                                       // [s]
  auto f = [&](double t) { return Eigen::Matrix3d(Eigen::Matrix3d::Identity() + t * g); };
  for (int k = 1; k <= 3; ++k) {
    set_f(u.dfgrd0, f(dt * (k - 1)));
    set_f(u.dfgrd1, f(dt * k));
    ASSERT_EQ(u.call({}, dt), 1.0) << last_message();
  }
  UmatPoint limited = u;
  limited.props[SUBSLIP_UMAT_MAX_ITERATIONS - 1] = 1;
  set_f(limited.dfgrd0, f(3 * dt));
  set_f(limited.dfgrd1, f(13 * dt));
  const UmatPoint before = limited;
  EXPECT_LT(limited.call({}, dt), 1.0);
  EXPECT_NE(last_message().find("grain solver"), std::string::npos) << last_message();
  EXPECT_EQ(limited.stress, before.stress);
  EXPECT_EQ(limited.statev, before.statev);
  EXPECT_EQ(limited.ddsdde, before.ddsdde);
  EXPECT_EQ((std::array<double, 3>{limited.sse, limited.spd, limited.scd}),
            (std::array<double, 3>{before.sse, before.spd, before.scd}));
  set_f(u.dfgrd0, f(3 * dt));
  set_f(u.dfgrd1, f(13 * dt));
  EXPECT_EQ(u.call({}, dt), 1.0) << last_message();
}

// A Taylor aggregate of three grains through PROPS equals the API's TaylorPoint.
TEST(FeUmatTaylor, AggregateEqualsTheNativeTaylorPoint) {
  const std::vector<Eigen::Vector3d> euler = {{0, 0, 0}, {30, 40, 50}, {80, 20, 10}};
  const std::vector<double> weights = {1.0, 2.0, 0.5};
  std::vector<double> props = fcc_props({0, 0, 0});
  props.resize(SUBSLIP_UMAT_TAYLOR_NPROPS(3));
  props[SUBSLIP_UMAT_POINT - 1] = 2;
  props[SUBSLIP_UMAT_TAYLOR_GRAINS - 1] = 3;
  std::vector<Eigen::Matrix3d> orientations;
  for (std::size_t g = 0; g < 3; ++g) {
    for (int i = 0; i < 3; ++i)
      props[SUBSLIP_UMAT_TAYLOR_GRAINS + 4 * g + static_cast<std::size_t>(i)] = euler[g](i);
    props[SUBSLIP_UMAT_TAYLOR_GRAINS + 4 * g + 3] = weights[g];
    orientations.push_back(orientation_of(euler[g]));
  }
  UmatPoint u(props);
  ASSERT_EQ(u.statev.size(), static_cast<std::size_t>(SUBSLIP_UMAT_NSTATV(3, 12)));
  const pt::TaylorPoint taylor(fcc_parameters(), orientations, weights);
  pt::TaylorState s = taylor.initial_state();
  const double dt = 0.1;
  for (int k = 0; k < 60; ++k) {
    const double sign = k < 30 ? 1.0 : -1.0;
    const std::array<double, 6> dstran{-1e-4 * sign, -1e-4 * sign, 2e-4 * sign, 1e-4, 0, 0};
    ASSERT_EQ(u.call(dstran, dt), 1.0) << subslip::fe_testing::last_message();
    const pt::TaylorUpdate n = taylor.update(s, rate_of(dstran, dt), dt);
    ASSERT_TRUE(n.report.ok);
    s = n.state;
    const auto expected = abaqus_stress(n.stress);
    double scale = 0.0;
    for (double v : expected) scale = std::max(scale, std::abs(v));
    for (std::size_t i = 0; i < 6; ++i)
      EXPECT_NEAR(u.stress[i], expected[i], 1e-10 * scale) << "increment " << k;
    for (std::size_t g = 0; g < 3; ++g) {
      const double* block = u.statev.data() + 1 + g * SUBSLIP_UMAT_GRAIN_BLOCK(12);
      for (int a = 0; a < 12; ++a)
        EXPECT_NEAR(block[16 + 24 + a], s.grains[g].slip(a),
                    1e-10 * std::max(1e-3, std::abs(s.grains[g].slip(a))));
    }
    for (int i = 0; i < 6; ++i)
      for (int j = 0; j < 6; ++j)
        EXPECT_NEAR(u.ddsdde_at(i, j),
                    n.tangent(subslip::fe_testing::kMandel[i], subslip::fe_testing::kMandel[j]) /
                        (subslip::fe_testing::kScale[i] * subslip::fe_testing::kScale[j]),
                    1e-10 * n.tangent.norm());
  }
}

}  // namespace
