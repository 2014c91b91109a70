// umat_ with the PROPS tail: an HCP crystal (C13, C33, c/a) with one tau0 per slip family
// equals the native GrainPoint of the same phase on paths at small and at finite strain. And
// SSE, SPD, SCD: on closed paths the work (the trapezoid of the stress over each increment's
// strain) is the elastic energy's change plus the plastic and viscous dissipation, to rounding.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstdio>

#include "subslip/crystal/rotation.hpp"
#include "umat_call.hpp"

namespace {

using namespace subslip::fe_testing;

// Titanium-like elasticity [MPa], c/a, and tau0 of basal, prismatic, pyramidal <a>, pyramidal
// <c+a> [MPa].
constexpr double kHcpC11 = 162400, kHcpC12 = 92000, kHcpC13 = 69000, kHcpC33 = 180700,
                 kHcpC44 = 46700, kCOverA = 1.587;
constexpr std::array<double, 4> kFamilyTau0 = {15.0, 10.0, 20.0, 40.0};
const Eigen::Vector3d kEuler(30.0, 40.0, 50.0);  // [deg]

std::vector<double> hcp_props(int strain) {
  std::vector<double> p = fcc_props(kEuler);
  p[SUBSLIP_UMAT_STRAIN - 1] = strain;
  p[SUBSLIP_UMAT_LATTICE - 1] = SUBSLIP_UMAT_LATTICE_HCP;
  p[SUBSLIP_UMAT_C11 - 1] = kHcpC11;
  p[SUBSLIP_UMAT_C12 - 1] = kHcpC12;
  p[SUBSLIP_UMAT_C44 - 1] = kHcpC44;
  p[SUBSLIP_UMAT_TAU0 - 1] = 0.0;  // one per family, in the tail
  p.resize(SUBSLIP_UMAT_SINGLE_NPROPS + SUBSLIP_UMAT_TAIL(SUBSLIP_UMAT_LATTICE_HCP, 1));
  const std::size_t base = SUBSLIP_UMAT_SINGLE_NPROPS - 1;
  p[base + SUBSLIP_UMAT_HCP_C13] = kHcpC13;
  p[base + SUBSLIP_UMAT_HCP_C33] = kHcpC33;
  p[base + SUBSLIP_UMAT_HCP_C_OVER_A] = kCOverA;
  for (std::size_t f = 0; f < 4; ++f) p[base + SUBSLIP_UMAT_HCP_TAIL + 1 + f] = kFamilyTau0[f];
  return p;
}

pt::GrainParameters hcp_parameters() {
  pt::GrainParameters d = fcc_parameters();
  d.families = {cr::SlipFamily::hcp_basal_a, cr::SlipFamily::hcp_prismatic_a,
                cr::SlipFamily::hcp_pyramidal_a, cr::SlipFamily::hcp_pyramidal_ca};
  d.family_settings.assign(4, d.family_settings[0]);
  for (std::size_t f = 0; f < 4; ++f) d.family_settings[f].tau0 = kFamilyTau0[f];
  d.c_over_a = kCOverA;
  d.stiffness = cr::hexagonal_stiffness(kHcpC11, kHcpC12, kHcpC13, kHcpC33, kHcpC44);
  return d;
}

double max_abs(const double* v, std::size_t n) {
  double s = 0.0;
  for (std::size_t i = 0; i < n; ++i) s = std::max(s, std::abs(v[i]));
  return s;
}

// STRESS and the grain's state (lattice stress, orientation, mu, r_s, slip) against native.
void expect_equal(const UmatPoint& u, const pt::Mandel6& stress, const pt::GrainState& s,
                  const std::string& what) {
  const auto expected = abaqus_stress(stress);
  const double scale = max_abs(expected.data(), 6);
  for (std::size_t i = 0; i < 6; ++i)
    EXPECT_NEAR(u.stress[i], expected[i], 1e-10 * scale) << what << " stress " << i;
  const double* b = u.statev.data() + 1;
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(b[i], s.stress(i), 1e-10 * scale) << what;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      EXPECT_NEAR(b[6 + 3 * i + j], s.orientation(i, j), 1e-10) << what << " orientation";
  const int n = static_cast<int>(s.mu.size());
  const pt::SlipVector* fields[] = {&s.mu, &s.r_s, &s.slip};
  for (int f = 0; f < 3; ++f) {
    const pt::SlipVector& v = *fields[f];
    const double field_scale = std::max(v.cwiseAbs().maxCoeff(), 1e-3);
    for (int a = 0; a < n; ++a)
      EXPECT_NEAR(b[16 + f * n + a], v(a), 1e-10 * field_scale) << what << " field " << f;
  }
}

TEST(FeUmatHcp, SmallStrainPathEqualsTheNativeGrain) {
  UmatPoint u(hcp_props(0));
  ASSERT_EQ(u.statev.size(), static_cast<std::size_t>(SUBSLIP_UMAT_NSTATV(1, 24)));
  const pt::GrainPoint grain(hcp_parameters());
  pt::GrainState s = grain.initial_state(orientation_of(kEuler));
  const double dt = 0.1;  // [s]
  int step = 0;
  for (const double sign : {1.0, -1.0}) {
    for (int k = 0; k < 40; ++k, ++step) {
      const std::array<double, 6> dstran{-0.5e-4 * sign, -0.5e-4 * sign, 1e-4 * sign,
                                         1e-4,           -0.3e-4,        0.2e-4};
      ASSERT_EQ(u.call(dstran, dt), 1.0) << last_message();
      const pt::GrainUpdate n = grain.update(s, rate_of(dstran, dt), dt);
      ASSERT_TRUE(n.report.ok) << n.report.why;
      s = n.state;
      expect_equal(u, n.stress, s, "increment " + std::to_string(step));
    }
  }
  // Plastic flow on more than one family (their tau0 differ).
  int families_slipping = 0;
  for (int first : {0, 3, 6, 12})
    families_slipping +=
        s.slip.segment(first, first == 12 ? 12 : (first == 6 ? 6 : 3)).cwiseAbs().maxCoeff() > 1e-4;
  EXPECT_GE(families_slipping, 2);
}

// A stretch F = diag(exp(e t)) at finite strain: log U over an increment is e dt, the native
// grain's constant velocity gradient diag(e), with no rotation.
TEST(FeUmatHcp, FiniteStretchPathEqualsTheNativeGrain) {
  UmatPoint u(hcp_props(1));
  const pt::GrainPoint grain(hcp_parameters());
  pt::GrainState s = grain.initial_state(orientation_of(kEuler));
  const Eigen::Vector3d rate(-0.4e-3, -0.6e-3, 1e-3);  // [1/s]
  const double dt = 0.2;                               // [s]
  auto f = [&](double t) {
    return Eigen::Matrix3d((rate * t).array().exp().matrix().asDiagonal());
  };
  for (int k = 1; k <= 30; ++k) {
    const double t1 = dt * (k <= 20 ? k : 40 - k), t0 = dt * (k <= 20 ? k - 1 : 41 - k);
    Eigen::Map<Eigen::Matrix3d>(u.dfgrd0.data()) = f(t0);
    Eigen::Map<Eigen::Matrix3d>(u.dfgrd1.data()) = f(t1);
    ASSERT_EQ(u.call({}, dt), 1.0) << last_message();
    const Eigen::Matrix3d l = Eigen::Matrix3d(rate.asDiagonal()) * ((t1 - t0) / dt);
    const pt::GrainUpdate n = grain.update(s, l, dt);
    ASSERT_TRUE(n.report.ok) << n.report.why;
    s = n.state;
    expect_equal(u, n.stress, s, "increment " + std::to_string(k));
  }
  EXPECT_GT(s.slip.cwiseAbs().maxCoeff(), 1e-4);
}

TEST(FeUmatHcp, TheTailIsCheckedByName) {
  std::vector<double> p = hcp_props(0);
  p.pop_back();
  UmatPoint short_tail(p, 500);
  EXPECT_LT(short_tail.call({1e-5, 0, 0, 0, 0, 0}, 0.1), 1.0);
  EXPECT_NE(last_message().find("C13, C33, c/a"), std::string::npos) << last_message();
  p = hcp_props(0);
  p[SUBSLIP_UMAT_SINGLE_NPROPS + SUBSLIP_UMAT_HCP_TAIL + 2 - 1] = -1.0;  // prismatic tau0
  UmatPoint negative(p, 500);
  EXPECT_LT(negative.call({1e-5, 0, 0, 0, 0, 0}, 0.1), 1.0);
  EXPECT_NE(last_message().find("PROPS(31) (tau0 of a slip family) must be > 0"), std::string::npos)
      << last_message();
}

// ---- SSE, SPD, SCD -----------------------------------------------------------------------------

Eigen::Matrix3d tensor(const std::array<double, 6>& s) {
  Eigen::Matrix3d t;
  t << s[0], s[3], s[4], s[3], s[1], s[5], s[4], s[5], s[2];
  return t;
}

struct Balance {
  double work = 0.0, work_scale = 0.0;  // sum of the increments' work and of its magnitudes
};

// A closed small-strain path (out, back beyond the start, and home): the work's trapezoid.
Balance small_strain_cycle(UmatPoint& u) {
  Balance b;
  const double dt = 0.1;
  for (const auto& [increments, sign] :
       {std::pair{20, 1.0}, std::pair{40, -1.0}, std::pair{20, 1.0}}) {
    for (int k = 0; k < increments; ++k) {
      const std::array<double, 6> dstran{
          -0.5e-4 * sign, -0.5e-4 * sign, 1e-4 * sign, 1e-4 * sign, 0.0, -0.5e-4 * sign};
      const auto stress0 = u.stress;
      EXPECT_EQ(u.call(dstran, dt), 1.0) << last_message();
      double w = 0.0;
      for (std::size_t i = 0; i < 6; ++i) w += 0.5 * (stress0[i] + u.stress[i]) * dstran[i];
      b.work += w;
      b.work_scale += std::abs(w);
    }
  }
  return b;
}

// The same at finite strain, F = Q(t)(I + s(t) G) with the stretch out, back and home while
// the frame turns: the work of an increment is 1/2 (sigma0 + R^T sigma1 R) : log U in the
// configuration at its start (F1 F0^-1 = R U).
Balance finite_strain_cycle(UmatPoint& u) {
  Balance b;
  Eigen::Matrix3d g;
  g << -0.5e-3, 2e-3, 0.0, 0.0, -0.5e-3, 0.0, 0.0, 0.0, 1e-3;  // [1/s]
  const double dt = 0.2;                                       // [s]
  auto stretch = [](int k) { return k <= 20 ? k : (k <= 60 ? 40 - k : k - 80); };
  auto f = [&](int k) {
    return Eigen::Matrix3d(
        subslip::crystal::rotation_exp(Eigen::Vector3d(1.0, 2.0, 3.0).normalized() * 0.1 * k) *
        (Eigen::Matrix3d::Identity() + dt * stretch(k) * g));
  };
  for (int k = 1; k <= 80; ++k) {
    Eigen::Map<Eigen::Matrix3d>(u.dfgrd0.data()) = f(k - 1);
    Eigen::Map<Eigen::Matrix3d>(u.dfgrd1.data()) = f(k);
    const Eigen::Matrix3d sigma0 = tensor(u.stress);
    EXPECT_EQ(u.call({}, dt), 1.0) << last_message();
    const Eigen::Matrix3d df = f(k) * f(k - 1).inverse();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> e(df.transpose() * df);
    const Eigen::Vector3d lambda = e.eigenvalues().cwiseSqrt();
    const Eigen::Matrix3d v = e.eigenvectors();
    const Eigen::Matrix3d r = df * v * lambda.cwiseInverse().asDiagonal() * v.transpose();
    const Eigen::Matrix3d log_u = v * lambda.array().log().matrix().asDiagonal() * v.transpose();
    const double w =
        (0.5 * (sigma0 + r.transpose() * tensor(u.stress) * r)).cwiseProduct(log_u).sum();
    b.work += w;
    b.work_scale += std::abs(w);
  }
  return b;
}

void expect_balance(const UmatPoint& u, const Balance& b, double rel, const std::string& what) {
  const double defect = b.work - (u.sse + u.spd + u.scd);  // SSE started at 0
  std::printf("%s: work %.6e, SSE %.6e, SPD %.6e, SCD %.6e, defect / sum|work| %.2e\n",
              what.c_str(), b.work, u.sse, u.spd, u.scd, std::abs(defect) / b.work_scale);
  EXPECT_LE(std::abs(defect), rel * b.work_scale) << what;
  EXPECT_GT(u.spd, 0.05 * b.work_scale) << what;
  EXPECT_GT(u.sse, 0.0) << what;  // the residual stress of the closed path
}

std::vector<double> finite_props_of(std::vector<double> p) {
  p[SUBSLIP_UMAT_STRAIN - 1] = 1;
  return p;
}

// Without the lattice's plastic spin, and with an overstress that carries a visible part of the
// stress (eta_v 100 s at slip rates near 1e-3/s).
std::vector<double> without_lattice_rotation(std::vector<double> p) {
  p[SUBSLIP_UMAT_LATTICE_ROTATION - 1] = 1;
  p[SUBSLIP_UMAT_ETA_V - 1] = 100.0;
  return p;
}

// Without the lattice's plastic spin the grain step's stress is sigma0 + C (de - P dgamma) in a
// fixed lattice frame, and the balance is exact but for rounding.
TEST(FeUmatEnergy, SmallStrainWorkIsElasticEnergyPlusDissipation) {
  for (const int form : {1, 3}) {  // exponential overstress, rate-independent
    std::vector<double> p = without_lattice_rotation(fcc_props(kEuler));
    p[SUBSLIP_UMAT_OVERSTRESS - 1] = form;
    UmatPoint u(p);
    const Balance b = small_strain_cycle(u);
    expect_balance(u, b, 1e-12, form == 1 ? "FCC, overstress" : "FCC, rate-independent");
    if (form == 1) {
      EXPECT_GT(u.scd, 1e-2 * u.spd);  // the overstress dissipates
    } else {
      EXPECT_EQ(u.scd, 0.0);  // no overstress: nothing viscous
    }
  }
  UmatPoint hcp(without_lattice_rotation(hcp_props(0)));
  expect_balance(hcp, small_strain_cycle(hcp), 1e-12, "HCP");
  UmatPoint taylor(without_lattice_rotation(taylor_fcc_props()));
  expect_balance(taylor, small_strain_cycle(taylor), 1e-12, "FCC Taylor aggregate");
}

// With the plastic spin the lattice turns within an increment: the work's trapezoid in the sample
// frame and the grain step's in the lattice frame differ by the turn's share (measured: 1.4e-6
// at small and 8.4e-7 at finite strain of the summed work on these paths).
TEST(FeUmatEnergy, WithThePlasticSpinTheBalanceHoldsToTheLatticeTurn) {
  for (const int strain : {0, 1}) {
    std::vector<double> p = without_lattice_rotation(fcc_props(kEuler));
    p[SUBSLIP_UMAT_LATTICE_ROTATION - 1] = 0;
    p[SUBSLIP_UMAT_STRAIN - 1] = strain;
    UmatPoint u(p);
    const Balance b = strain ? finite_strain_cycle(u) : small_strain_cycle(u);
    expect_balance(u, b, 1e-5, strain ? "FCC, plastic spin, finite" : "FCC, plastic spin, small");
  }
}

TEST(FeUmatEnergy, FiniteStrainWorkIsElasticEnergyPlusDissipation) {
  UmatPoint u(without_lattice_rotation(finite_props_of(fcc_props(kEuler))));
  expect_balance(u, finite_strain_cycle(u), 1e-12, "FCC, finite strain");
}

}  // namespace
