// umat_ of libsubslip_fe, called through its C ABI as an FE code calls it, against the
// material-point API (GrainPoint) driven natively along the same paths: uniaxial stress (a
// Newton iteration on the lateral strains with DDSDDE, and an independent one with the API's
// Mandel tangent), simple shear with a reversal, plane strain; DDSDDE against central
// differences of STRESS; refused increments (PNEWDT < 1, STRESS and STATEV untouched, a message
// naming the cause); concurrent calls from OpenMP threads.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "umat_call.hpp"

namespace {

using namespace subslip::fe_testing;

const Eigen::Vector3d kEuler(30.0, 40.0, 50.0);  // [deg]

// |a - b| <= rel max|b| over the components.
template <class A, class B>
void expect_close(const A& a, const B& b, std::size_t n, double rel, const std::string& what) {
  double scale = 0.0;
  for (std::size_t i = 0; i < n; ++i) scale = std::max(scale, std::abs(b[i]));
  for (std::size_t i = 0; i < n; ++i)
    EXPECT_LE(std::abs(a[i] - b[i]), rel * scale)
        << what << " component " << i << ": " << a[i] << " vs " << b[i];
}

// The grain state umat_ keeps (STATEV) against a native one: stress, orientation, mu, r_s, slip.
void expect_state(const UmatPoint& u, const pt::GrainState& s, double rel,
                  const std::string& what) {
  const int n = static_cast<int>(s.mu.size());
  const double* b = u.statev.data() + 1;
  expect_close(b, s.stress.data(), 6, rel, what + " lattice stress");
  expect_close(b + 6, Eigen::Matrix<double, 3, 3, Eigen::RowMajor>(s.orientation).data(), 9, rel,
               what + " orientation");
  expect_close(b + 16, s.mu.data(), static_cast<std::size_t>(n), rel, what + " mu");
  expect_close(b + 16 + n, s.r_s.data(), static_cast<std::size_t>(n), rel, what + " r_s");
  expect_close(b + 16 + 2 * n, s.slip.data(), static_cast<std::size_t>(n), rel, what + " slip");
}

// Uniaxial stress along 33: the lateral strain increments (every component but 33) solved by
// Newton so that the lateral stresses vanish, with each path's own tangent.
constexpr std::array<int, 5> kLateral = {0, 1, 3, 4, 5};  // Abaqus components

std::array<double, 6> umat_uniaxial_step(UmatPoint& u, double d33, double dt) {
  const auto stress0 = u.stress;
  const auto statev0 = u.statev;
  std::array<double, 6> dstran{0, 0, d33, 0, 0, 0};
  for (int it = 0; it < 30; ++it) {
    u.stress = stress0;
    u.statev = statev0;
    EXPECT_EQ(u.call(dstran, dt), 1.0) << last_message();
    Eigen::Matrix<double, 5, 1> r;
    Eigen::Matrix<double, 5, 5> j;
    for (int a = 0; a < 5; ++a) {
      r(a) = u.stress[static_cast<std::size_t>(kLateral[a])];
      for (int b = 0; b < 5; ++b) j(a, b) = u.ddsdde_at(kLateral[a], kLateral[b]);
    }
    if (r.norm() <= 1e-11 * std::abs(u.stress[2])) return dstran;
    const Eigen::Matrix<double, 5, 1> step = j.partialPivLu().solve(r);
    for (int a = 0; a < 5; ++a) dstran[static_cast<std::size_t>(kLateral[a])] -= step(a);
  }
  ADD_FAILURE() << "the UMAT Newton iteration on the lateral strains did not converge";
  return dstran;
}

TEST(FeUmat, UniaxialStressWithDdsddeEqualsTheNativeGrain) {
  UmatPoint u(fcc_props(kEuler));
  ASSERT_EQ(u.statev.size(), static_cast<std::size_t>(SUBSLIP_UMAT_NSTATV(1, 12)));
  const pt::GrainPoint grain(fcc_parameters());
  pt::GrainState s = grain.initial_state(orientation_of(kEuler));
  // Tension to 0.4 %, then back into compression (a reversal).
  const double dt = 0.2;  // [s]
  int step = 0;
  for (const auto& [increments, d33] : {std::pair{20, 2e-4}, std::pair{30, -2e-4}}) {
    for (int k = 0; k < increments; ++k, ++step) {
      umat_uniaxial_step(u, d33, dt);
      const pt::GrainUpdate n = native_uniaxial_step(grain, s, d33, dt);
      s = n.state;
      const std::string what = "increment " + std::to_string(step);
      expect_close(u.stress, abaqus_stress(n.stress), 6, 1e-10, what + " stress");
      expect_state(u, s, 1e-10, what);
    }
  }
  EXPECT_GT(s.slip.cwiseAbs().maxCoeff(), 1e-3);  // well into plastic flow
  EXPECT_LT(u.stress[2], -2.0 * kTau0);           // and reversed into compression
}

TEST(FeUmat, SimpleShearAndReversalEqualTheNativeGrain) {
  UmatPoint u(fcc_props(kEuler));
  const pt::GrainPoint grain(fcc_parameters());
  pt::GrainState s = grain.initial_state(orientation_of(kEuler));
  const double dt = 0.1;
  int step = 0;
  for (const auto& [increments, gamma] : {std::pair{30, 2e-4}, std::pair{60, -2e-4}}) {
    for (int k = 0; k < increments; ++k, ++step) {
      const std::array<double, 6> dstran{0, 0, 0, gamma, 0, 0};
      ASSERT_EQ(u.call(dstran, dt), 1.0) << last_message();
      const pt::GrainUpdate n = grain.update(s, rate_of(dstran, dt), dt);
      ASSERT_TRUE(n.report.ok);
      s = n.state;
      const std::string what = "increment " + std::to_string(step);
      expect_close(u.stress, abaqus_stress(n.stress), 6, 1e-10, what + " stress");
      expect_state(u, s, 1e-10, what);
      // DDSDDE is the API's tangent in Abaqus' order with engineering shears.
      EXPECT_NEAR(u.ddsdde_at(3, 3), n.tangent(5, 5) / 2.0, 1e-10 * n.tangent.norm());
      EXPECT_NEAR(u.ddsdde_at(0, 5), n.tangent(0, 3) / std::sqrt(2.0), 1e-10 * n.tangent.norm());
    }
  }
  EXPECT_GT(s.slip.cwiseAbs().maxCoeff(), 1e-3);
}

// Plane strain (NSHR = 1): the 3D increment with no 13, 23 strain, its first four components.
TEST(FeUmat, PlaneStrainIsTheFirstFourComponentsOf3d) {
  UmatPoint plane(fcc_props(kEuler)), full(fcc_props(kEuler));
  plane.nshr = 1;
  for (int k = 0; k < 20; ++k) {
    const std::array<double, 6> dstran{1e-4, -0.5e-4, 0.0, 2e-4, 0.0, 0.0};
    ASSERT_EQ(plane.call(dstran, 0.1), 1.0) << last_message();
    ASSERT_EQ(full.call(dstran, 0.1), 1.0);
    for (int i = 0; i < 4; ++i) {
      EXPECT_EQ(plane.stress[static_cast<std::size_t>(i)],
                full.stress[static_cast<std::size_t>(i)]);
      for (int j = 0; j < 4; ++j) EXPECT_EQ(plane.ddsdde_at(i, j), full.ddsdde_at(i, j));
    }
  }
}

// DDSDDE against central differences of STRESS in each DSTRAN component, in plastic flow.
TEST(FeUmat, DdsddeIsTheDerivativeOfStress) {
  UmatPoint u(fcc_props(kEuler));
  for (int k = 0; k < 15; ++k) ASSERT_EQ(u.call({-1e-4, -1e-4, 2e-4, 0, 0, 0}, 0.2), 1.0);
  const std::array<double, 6> dstran{-0.4e-4, -0.6e-4, 1e-4, 0.3e-4, -0.2e-4, 0.1e-4};
  const double dt = 0.1;
  UmatPoint at = u;
  ASSERT_EQ(at.call(dstran, dt), 1.0);
  double scale = 0.0;
  for (double v : at.ddsdde) scale = std::max(scale, std::abs(v));
  const double h = 1e-9;
  for (int j = 0; j < 6; ++j) {
    UmatPoint plus = u, minus = u;
    auto dp = dstran, dm = dstran;
    dp[static_cast<std::size_t>(j)] += h;
    dm[static_cast<std::size_t>(j)] -= h;
    ASSERT_EQ(plus.call(dp, dt), 1.0);
    ASSERT_EQ(minus.call(dm, dt), 1.0);
    for (int i = 0; i < 6; ++i) {
      const double fd =
          (plus.stress[static_cast<std::size_t>(i)] - minus.stress[static_cast<std::size_t>(i)]) /
          (2 * h);
      EXPECT_NEAR(at.ddsdde_at(i, j), fd, 1e-6 * scale) << i << ", " << j;
    }
  }
  // In plastic flow: the tangent is far from the elastic one (an increment of no time).
  UmatPoint elastic = u;
  ASSERT_EQ(elastic.call({0, 0, 0, 0, 0, 0}, 0.0), 1.0);
  double difference = 0.0;
  for (std::size_t k = 0; k < 36; ++k)
    difference = std::max(difference, std::abs(elastic.ddsdde[k] - at.ddsdde[k]));
  EXPECT_GT(difference, 0.05 * scale);
}

// An increment over no time with no strain (Abaqus' first call) returns the elastic stiffness
// and changes nothing; a strain over no time is refused.
TEST(FeUmat, AnIncrementOfNoTime) {
  UmatPoint u(fcc_props({0, 0, 0}));
  ASSERT_EQ(u.call({0, 0, 0, 0, 0, 0}, 0.0), 1.0) << last_message();
  EXPECT_NEAR(u.ddsdde_at(0, 0), kC11, 1e-9 * kC11);
  EXPECT_NEAR(u.ddsdde_at(0, 1), kC12, 1e-9 * kC11);
  EXPECT_NEAR(u.ddsdde_at(3, 3), kC44, 1e-9 * kC11);
  EXPECT_EQ(u.stress, (std::array<double, 6>{}));
  const auto statev = u.statev;
  EXPECT_LT(u.call({1e-4, 0, 0, 0, 0, 0}, 0.0), 1.0);
  EXPECT_NE(last_message().find("DTIME = 0"), std::string::npos) << last_message();
  EXPECT_EQ(u.statev, statev);
}

// A refused increment: PNEWDT < 1, STRESS, STATEV and SSE, SPD, SCD exactly as they came in,
// one message.
void expect_refused(UmatPoint& u, const std::array<double, 6>& dstran, double dt,
                    const std::string& naming) {
  const auto stress = u.stress;
  const auto statev = u.statev;
  const std::array<double, 3> energies{u.sse, u.spd, u.scd};
  EXPECT_LT(u.call(dstran, dt), 1.0);
  EXPECT_EQ(u.stress, stress);
  EXPECT_EQ(u.statev, statev);
  EXPECT_EQ((std::array<double, 3>{u.sse, u.spd, u.scd}), energies);
  EXPECT_NE(last_message().find(naming), std::string::npos) << last_message();
}

TEST(FeUmat, AFailedIncrementCutsBackAndLeavesStressAndStatev) {
  UmatPoint u(fcc_props(kEuler));
  for (int k = 0; k < 3; ++k) ASSERT_EQ(u.call({-1e-4, -1e-4, 2e-4, 0, 0, 0}, 0.2), 1.0);
  // The same crystal whose grain solver may take one Newton iteration a step: no plastic
  // increment converges in one.
  UmatPoint limited = u;
  limited.props[SUBSLIP_UMAT_MAX_ITERATIONS - 1] = 1;
  expect_refused(limited, {-1e-3, -1e-3, 2e-3, 0, 0, 0}, 0.2, "grain solver");
  // The default solver takes that increment.
  EXPECT_EQ(u.call({-1e-3, -1e-3, 2e-3, 0, 0, 0}, 0.2), 1.0) << last_message();
  EXPECT_EQ(last_message(), "");
  // Non-finite strain.
  expect_refused(u, {std::numeric_limits<double>::quiet_NaN(), 0, 0, 0, 0, 0}, 0.2, "DSTRAN");
}

TEST(FeUmat, BadPropsAndStatevAreRefusedByName) {
  {
    UmatPoint u(fcc_props(kEuler), 40);  // needs 89
    u.call({1e-4, 0, 0, 0, 0, 0}, 0.1);
    expect_refused(u, {1e-4, 0, 0, 0, 0, 0}, 0.1, "NSTATV = 40: these PROPS need 89");
  }
  {
    std::vector<double> props = fcc_props(kEuler);
    props.pop_back();
    UmatPoint u(props, 89);
    expect_refused(u, {1e-4, 0, 0, 0, 0, 0}, 0.1, "NPROPS = 25");
    EXPECT_EQ(subslip_fe_umat_statev_count(props.data(), 25), 0);
  }
  {
    std::vector<double> props = fcc_props(kEuler);
    props[SUBSLIP_UMAT_LATTICE - 1] = 7;
    UmatPoint u(props, 89);
    expect_refused(u, {1e-4, 0, 0, 0, 0, 0}, 0.1, "PROPS(3) (lattice)");
  }
  {
    std::vector<double> props = fcc_props(kEuler);
    props[SUBSLIP_UMAT_R_HAT - 1] = 0.5;  // the law's own check
    UmatPoint u(props, 89);
    expect_refused(u, {1e-4, 0, 0, 0, 0, 0}, 0.1, "r_hat");
  }
  {
    UmatPoint u(fcc_props(kEuler));
    u.statev[0] = 3.0;
    expect_refused(u, {1e-4, 0, 0, 0, 0, 0}, 0.1, "STATEV(1)");
  }
  {
    UmatPoint u(fcc_props(kEuler));
    u.nshr = 2;
    expect_refused(u, {1e-4, 0, 0, 0, 0, 0}, 0.1, "NSHR = 2");
  }
}

// Many integration points updated at once from OpenMP threads (as an FE code loops over its
// elements), each with its own orientation and path, the material made on first use by
// whichever thread comes first: the results equal the serial ones bitwise.
// Half the points at small strain, half at finite strain (DFGRD0, DFGRD1).
TEST(FeUmat, ConcurrentCallsGiveTheSerialResults) {
  constexpr int kPoints = 24, kSteps = 12;
  auto props_of = [](int p) {
    std::vector<double> props = fcc_props({10.0 * p, 5.0 + 3.0 * p, 7.0 * p});
    props[SUBSLIP_UMAT_TAU0 - 1] = kTau0 * (1.0 + 1e-9);  // a material no other test made
    props[SUBSLIP_UMAT_STRAIN - 1] = p % 2;
    return props;
  };
  auto run = [&](int p) {
    UmatPoint u(props_of(p));
    u.noel = p;
    Eigen::Matrix3d f = Eigen::Matrix3d::Identity();
    for (int k = 0; k < kSteps; ++k) {
      const double s = k < 8 ? 1.0 : -1.0;
      const std::array<double, 6> dstran{-1e-4 * s, 0.5e-4 * s, 0.5e-4 * s, 1e-4 * (p % 3), 0, 0};
      Eigen::Map<Eigen::Matrix3d>(u.dfgrd0.data()) = f;
      f = (Eigen::Matrix3d::Identity() + rate_of(dstran, 1.0)) * f;
      Eigen::Map<Eigen::Matrix3d>(u.dfgrd1.data()) = f;
      if (u.call(dstran, 0.1) != 1.0) ADD_FAILURE() << last_message();
    }
    return u;
  };
  std::vector<UmatPoint> parallel(kPoints, UmatPoint(props_of(0)));
#pragma omp parallel for num_threads(4) schedule(dynamic)
  for (int p = 0; p < kPoints; ++p) parallel[static_cast<std::size_t>(p)] = run(p);
  for (int p = 0; p < kPoints; ++p) {
    const UmatPoint serial = run(p);
    const UmatPoint& other = parallel[static_cast<std::size_t>(p)];
    EXPECT_EQ(serial.stress, other.stress) << "point " << p;
    EXPECT_EQ(serial.statev, other.statev) << "point " << p;
    EXPECT_EQ(serial.ddsdde, other.ddsdde) << "point " << p;
    EXPECT_EQ((std::array<double, 3>{serial.sse, serial.spd, serial.scd}),
              (std::array<double, 3>{other.sse, other.spd, other.scd}))
        << "point " << p;
  }
}

}  // namespace
