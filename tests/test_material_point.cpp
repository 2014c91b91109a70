// The material-point API (include/subslip/material_point.hpp), used through that header alone:
// a contact point, a grain and a Taylor point updated along a path give the drivers' results
// bitwise (the contact history driver, the Taylor aggregate of one and of several grains), their
// tangents are the derivatives of their updates (central differences), a batch gives each
// point's single update, the contact point's forward-Euler update refuses a step above its
// stability limit, its update without the tangent is the same update, and bad parameters and
// states are refused by name.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "subslip/history/contact_history.hpp"
#include "subslip/material_point.hpp"

namespace pt = subslip::point;
namespace cr = subslip::crystal;
namespace ct = subslip::contact;
namespace hs = subslip::history;

namespace {

// ---- contact -----------------------------------------------------------------------------------

constexpr double kNormalTraction = 1.0;  // [MPa]

pt::ContactParameters contact_parameters() {
  pt::ContactParameters p;  // the paper's default law, alpha = 1e6 MPa/mm
  p.law.friction.xi = 0.05;
  return p;
}

// Slide, reverse, hold: every branch of the update (elastic, sliding, reversal through zero).
std::vector<ct::Segment> contact_path() {
  std::vector<ct::Segment> path(3);
  path[0].velocity = {1e-3, 0.0};  // [mm/s]
  path[0].duration = 2.0;
  path[0].increments = 40;
  path[1].velocity = {-1e-3, 0.5e-3};
  path[1].duration = 3.0;
  path[1].increments = 30;
  path[1].growth = 1.05;
  path[2].velocity = {0.0, 0.0};
  path[2].duration = 5.0;
  path[2].increments = 10;
  for (auto& s : path) s.normal_traction = kNormalTraction;
  return path;
}

TEST(MaterialPoint, ContactPointAlongAPathEqualsTheContactDriverBitwise) {
  const pt::ContactParameters p = contact_parameters();
  const ct::ContactModel model{p.law, {}, p.stiffness, kNormalTraction};
  std::vector<ct::ContactState> driver;
  hs::run_history(model, contact_path(), {},
                  [&](const ct::ContactState& s, int) { driver.push_back(s); });

  const pt::ContactPoint point(p);
  std::vector<ct::ContactState> api{point.initial_state(kNormalTraction, {})};
  for (const ct::Segment& seg : contact_path()) {
    double t = 0.0;
    for (double dt : ct::increment_lengths(seg)) {
      const pt::ContactStep step{
          seg.velocity * dt, ct::normal_traction_at(seg, p.stiffness, kNormalTraction, t + dt), dt};
      const pt::ContactUpdate u = point.update(api.back(), step);
      ASSERT_TRUE(u.report.ok) << u.report.why;
      api.push_back(u.state);
      t += dt;
    }
  }
  ASSERT_EQ(api.size(), driver.size());
  for (std::size_t k = 0; k < api.size(); ++k) {
    SCOPED_TRACE(k);
    EXPECT_EQ(api[k].traction_t(0), driver[k].traction_t(0));
    EXPECT_EQ(api[k].traction_t(1), driver[k].traction_t(1));
    EXPECT_EQ(api[k].traction_n, driver[k].traction_n);
    EXPECT_EQ(api[k].law.mu, driver[k].law.mu);
    EXPECT_EQ(api[k].law.r_s, driver[k].law.r_s);
    EXPECT_EQ(api[k].vp_slip, driver[k].vp_slip);
    EXPECT_EQ(api[k].r, driver[k].r);
  }
}

// d f_t / d (du_t, f_n) against central differences of the update, while sliding obliquely to
// the traction (the direction turns) under a falling normal traction, along it, against it with
// sliding going on, and in an elastic step. (None passes through a lower ratio first, as a
// reversal does, where the tangent takes that point as fixed.)
TEST(MaterialPoint, ContactTangentIsTheDerivativeOfTheUpdate) {
  const pt::ContactPoint point(contact_parameters());
  pt::ContactState s = point.initial_state(kNormalTraction, {});
  for (int k = 0; k < 20; ++k) s = point.update(s, {{1e-5, 0.0}, kNormalTraction, 0.01}).state;
  for (const pt::ContactStep& step : {pt::ContactStep{{2e-6, 3e-6}, 0.95, 0.01},
                                      pt::ContactStep{{1e-6, 0.0}, kNormalTraction, 0.01},
                                      pt::ContactStep{{-2e-9, 0.0}, kNormalTraction, 0.01},
                                      pt::ContactStep{{-5e-9, 0.0}, kNormalTraction, 0.01}}) {
    const pt::ContactUpdate u = point.update(s, step);
    ASSERT_TRUE(u.report.ok);
    for (int j = 0; j < 3; ++j) {
      const double h = j < 2 ? 1e-12 : 1e-6;  // [mm]: 1e-6 MPa, a 1e-4 turn of f_t at most
      pt::ContactStep plus = step, minus = step;
      if (j < 2) {
        plus.slip(j) += h;
        minus.slip(j) -= h;
      } else {
        plus.normal_traction += h;
        minus.normal_traction -= h;
      }
      const Eigen::Vector2d d =
          (point.update(s, plus).state.traction_t - point.update(s, minus).state.traction_t) /
          (2.0 * h);
      const double scale = j < 2 ? contact_parameters().stiffness.alpha_t : 1.0;
      EXPECT_NEAR(u.tangent(0, j), d(0), 1e-5 * scale)
          << "column " << j << ", " << step.slip.transpose();
      EXPECT_NEAR(u.tangent(1, j), d(1), 1e-5 * scale)
          << "column " << j << ", " << step.slip.transpose();
    }
  }
}

// A step from a sliding contact that ends where f_n reaches zero (its opening) is the closed
// step's limit as f_n(end) -> 0+: the flow rule keeps the traction below r_hat mu f_n, so the
// trial traction is slid off and mu softens over that slip. At f_n(end) = eps f_n the closed step
// slides at most r_hat mu eps f_n / alpha_t less; its state and its sensitivities to the law's
// constants approach the opening step's as eps falls. (Taken as open, the step slid nothing.)
TEST(MaterialPoint, AStepEndingOnTheOpeningIsTheClosedStepsLimit) {
  const pt::ContactParameters p = contact_parameters();
  const pt::ContactPoint point(p);
  pt::ContactState s = point.initial_state(kNormalTraction, {});
  ct::ContactSensitivity d = ct::initial_sensitivity(false);
  const double dt = 0.05;                    // [s]
  const Eigen::Vector2d du(1e-3 * dt, 0.0);  // [mm], 1e-3 mm/s
  for (int k = 0; k < 40; ++k) {             // sliding (r ~ 1 after the peak)
    const pt::ContactUpdate u = point.update(s, {du, kNormalTraction, dt}, d);
    ASSERT_TRUE(u.report.ok) << u.report.why;
    s = u.state;
  }
  ASSERT_GT(s.vp_rate, 0.0);
  ct::ContactSensitivity d_open = d;
  const pt::ContactUpdate open = point.update(s, {du, 0.0, dt}, d_open);
  ASSERT_TRUE(open.report.ok) << open.report.why;
  EXPECT_EQ(open.state.traction_t.norm(), 0.0);
  EXPECT_EQ(open.state.r, 0.0);
  EXPECT_EQ(open.state.law.r_s, 0.0);
  const double slid = open.state.vp_slip - s.vp_slip;
  EXPECT_NEAR(slid, (s.traction_t + p.stiffness.alpha_t * du).norm() / p.stiffness.alpha_t,
              1e-12 * slid);
  EXPECT_LT(open.state.law.mu, s.law.mu);  // softened over the slip (mu_k < mu_s)
  const double scale = d_open.mu.cwiseAbs().maxCoeff();
  std::vector<double> gaps;  // of the sensitivities of mu
  for (double eps : {1e-4, 1e-10}) {
    SCOPED_TRACE(eps);
    ct::ContactSensitivity d_closed = d;
    const pt::ContactUpdate closed = point.update(s, {du, eps * kNormalTraction, dt}, d_closed);
    ASSERT_TRUE(closed.report.ok) << closed.report.why;
    const double bound =
        p.law.overstress.r_hat * s.law.mu * eps * kNormalTraction / p.stiffness.alpha_t;
    const double slip_gap = open.state.vp_slip - closed.state.vp_slip;
    EXPECT_GE(slip_gap, -1e-15 * slid);
    EXPECT_LE(slip_gap, bound * (1.0 + 1e-9));
    EXPECT_LE(std::abs(closed.state.law.mu - open.state.law.mu), p.law.friction.kappa * bound);
    gaps.push_back((d_closed.mu - d_open.mu).cwiseAbs().maxCoeff());
  }
  EXPECT_GT(scale, 0.0);
  EXPECT_LT(gaps[1], gaps[0]);
  EXPECT_LE(gaps[1], 1e-9 * scale);
}

TEST(MaterialPoint, ContactBatchGivesEachPointsUpdate) {
  const pt::ContactPoint point(contact_parameters());
  std::vector<pt::ContactState> states;
  std::vector<pt::ContactStep> steps;
  for (int k = 0; k < 9; ++k) {
    pt::ContactState s = point.initial_state(kNormalTraction, {});
    s = point.update(s, {{1e-6 * k, 0.0}, kNormalTraction, 0.01}).state;
    states.push_back(s);
    steps.push_back({{1e-6 * (k - 4), 2e-7 * k}, kNormalTraction, 0.01});
  }
  std::vector<pt::ContactUpdate> out(states.size());
  point.update(states, steps, out);
  for (std::size_t k = 0; k < states.size(); ++k) {
    const pt::ContactUpdate one = point.update(states[k], steps[k]);
    EXPECT_EQ(out[k].state.traction_t, one.state.traction_t);
    EXPECT_EQ(out[k].state.law.mu, one.state.law.mu);
    EXPECT_EQ(out[k].tangent, one.tangent);
  }
}

// The forward-Euler contact point (ContactParameters::method) refuses a step above its stability
// limit 2/lambda, lambda = alpha_t phi_r / (f_n mu) at the step's start, naming it and returning
// the start state, and takes one below it; it has no tangent. Without the tangent the implicit
// update is the same update bitwise.
TEST(MaterialPoint, ContactPointMethodAndTangentOptions) {
  const pt::ContactPoint implicit(contact_parameters());
  pt::ContactState s = implicit.initial_state(kNormalTraction, {});
  const double v = 1e-3;  // [mm/s]
  for (int k = 0; k < 40; ++k)
    s = implicit.update(s, {{v * 0.05, 0.0}, kNormalTraction, 0.05}).state;
  ASSERT_GT(s.vp_rate, 0.0);  // sliding: the flow rule's rate is stiff in r

  pt::ContactParameters p = contact_parameters();
  p.method = ct::Method::forward_euler;
  const pt::ContactPoint explicit_point(p);
  const double lambda = explicit_point.law().traction_relaxation_rate(
      p.stiffness.alpha_t, s.r, s.law.r_s, s.law.mu, s.traction_n);
  ASSERT_GT(lambda, 0.0);
  const double unstable = 4.0 / lambda, stable = 0.5 / lambda;
  const pt::ContactUpdate refused =
      explicit_point.update(s, {{v * unstable, 0.0}, kNormalTraction, unstable});
  EXPECT_FALSE(refused.report.ok);
  EXPECT_NE(refused.report.why.find("stability limit"), std::string::npos) << refused.report.why;
  EXPECT_EQ(refused.state.traction_t, s.traction_t);
  EXPECT_EQ(refused.state.time, s.time);
  // The implicit update takes that step.
  EXPECT_TRUE(implicit.update(s, {{v * unstable, 0.0}, kNormalTraction, unstable}).report.ok);

  const pt::ContactUpdate taken =
      explicit_point.update(s, {{v * stable, 0.0}, kNormalTraction, stable});
  ASSERT_TRUE(taken.report.ok) << taken.report.why;
  EXPECT_EQ(taken.state.time, s.time + stable);
  EXPECT_TRUE(taken.tangent.isZero(0.0));
  const pt::ContactUpdate with_tangent =
      implicit.update(s, {{v * stable, 0.0}, kNormalTraction, stable});
  EXPECT_NE(taken.state.traction_t, with_tangent.state.traction_t);  // another update

  pt::ContactParameters q = contact_parameters();
  q.tangent = false;
  const pt::ContactUpdate without_tangent =
      pt::ContactPoint(q).update(s, {{v * stable, 0.0}, kNormalTraction, stable});
  ASSERT_TRUE(without_tangent.report.ok);
  EXPECT_FALSE(with_tangent.tangent.isZero(0.0));
  EXPECT_TRUE(without_tangent.tangent.isZero(0.0));
  EXPECT_EQ(without_tangent.state.traction_t, with_tangent.state.traction_t);
  EXPECT_EQ(without_tangent.state.law.mu, with_tangent.state.law.mu);
  EXPECT_EQ(without_tangent.state.law.r_s, with_tangent.state.law.r_s);
  EXPECT_EQ(without_tangent.state.vp_slip, with_tangent.state.vp_slip);
  EXPECT_EQ(without_tangent.report.iterations, with_tangent.report.iterations);
}

TEST(MaterialPoint, BadContactParametersAndStepsAreRefusedByName) {
  pt::ContactParameters p = contact_parameters();
  p.stiffness.alpha_t = -1.0;
  try {
    pt::ContactPoint bad(p);
    FAIL() << "a negative alpha_t was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("alpha_t"), std::string::npos) << e.what();
  }
  const pt::ContactPoint point(contact_parameters());
  EXPECT_THROW(point.update(point.initial_state(1.0, {}), {{0.0, 0.0}, 1.0, 0.0}),
               std::invalid_argument);
}

// ---- grains
// --------------------------------------------------------------------------------------

pt::GrainParameters fcc() {
  pt::GrainParameters d;
  cr::SlipGroupSettings g;
  g.tau0 = 10.0;  // [MPa]
  g.law.friction = {1.0, 3.0, 5.0, 0.0};
  g.law.subloading = {subslip::law::SubloadingFunction::cot, 200.0};
  g.law.overstress = {subslip::law::OverstressForm::exponential, 1.0e-3, 16.0, 1.6};
  d.families = {cr::SlipFamily::fcc_111_110};
  d.family_settings = {g};
  d.stiffness = cr::cubic_stiffness(168400, 121400, 75400);  // copper [MPa]
  return d;
}

// Orientation matrices as the drivers hold them (each from its unit quaternion).
std::vector<Eigen::Matrix3d> orientations(int count) {
  std::vector<Eigen::Matrix3d> out;
  for (int k = 0; k < count; ++k)
    out.push_back(cr::Orientation::from_euler({0.3 + 0.7 * k, 0.2 + 0.37 * k, 1.1 * k}).g);
  return out;
}

// Tension, then simple shear, then compression: active sets change and the rates turn.
std::vector<cr::LoadSegment> grain_path() {
  std::vector<cr::LoadSegment> path(3);
  path[0].velocity_gradient.diagonal() << -0.5e-3, -0.5e-3, 1e-3;  // [1/s]
  path[0].duration = 5.0;
  path[0].increments = 25;
  path[1].velocity_gradient(0, 1) = 2e-3;
  path[1].duration = 2.0;
  path[1].increments = 20;
  path[1].growth = 1.1;
  path[2].velocity_gradient.diagonal() << 0.5e-3, 0.5e-3, -1e-3;
  path[2].duration = 4.0;
  path[2].increments = 16;
  return path;
}

struct DriverRecord {
  std::vector<Eigen::Matrix3d> macro_stress;
  std::vector<std::vector<double>> grain_stress, slip;
};

DriverRecord run_aggregate(const std::vector<Eigen::Matrix3d>& grains) {
  std::vector<cr::Orientation> o;
  for (const auto& g : grains) {
    o.push_back(cr::Orientation::from_matrix(g));
    o.back().g = g;  // the very matrix the API's grain starts from
  }
  const auto aggregate = cr::build_taylor_aggregate(fcc(), o);
  DriverRecord r;
  aggregate->run(grain_path(), {}, [&](const cr::MacroState& m, const cr::GrainFields& f) {
    r.macro_stress.push_back(m.stress);
    std::vector<double> stress(6 * static_cast<std::size_t>(f.grain_count()));
    std::vector<double> slip(static_cast<std::size_t>(f.grain_count() * f.slip_count()));
    f.values(cr::GrainField::stress, stress.data());
    f.values(cr::GrainField::slip, slip.data());
    r.grain_stress.push_back(stress);
    r.slip.push_back(slip);
  });
  return r;
}

// A stress row as the aggregate's fields write it: 11 22 33 23 13 12.
std::vector<double> stress_row(const pt::Mandel6& m) {
  const Eigen::Matrix3d t = cr::symmetric_from_mandel(m);
  return {t(0, 0), t(1, 1), t(2, 2), t(1, 2), t(0, 2), t(0, 1)};
}

// Calls step(L, dt, k) for every increment k = 1, 2, ... of grain_path(); returns the count + 1.
template <class Step>
std::size_t along_grain_path(Step&& step) {
  std::size_t k = 1;
  for (const cr::LoadSegment& seg : grain_path())
    for (double dt : cr::increment_lengths(seg.duration, seg.increments, seg.growth))
      step(seg.velocity_gradient, dt, k++);
  return k;
}

TEST(MaterialPoint, GrainAlongAPathEqualsTheSingleCrystalDriverBitwise) {
  const auto grains = orientations(1);
  const DriverRecord driver = run_aggregate(grains);
  const pt::GrainPoint grain(fcc());
  pt::GrainState s = grain.initial_state(grains[0]);
  const std::size_t outputs =
      along_grain_path([&](const Eigen::Matrix3d& l, double dt, std::size_t k) {
        const pt::GrainUpdate u = grain.update(s, l, dt);
        ASSERT_TRUE(u.report.ok) << u.report.why;
        s = u.state;
        ASSERT_LT(k, driver.grain_stress.size());
        EXPECT_EQ(stress_row(u.stress), driver.grain_stress[k]) << "increment " << k;
        EXPECT_EQ(std::vector<double>(s.slip.data(), s.slip.data() + s.slip.size()), driver.slip[k])
            << "increment " << k;
      });
  EXPECT_EQ(outputs, driver.grain_stress.size());
}

TEST(MaterialPoint, TaylorPointAlongAPathEqualsTheTaylorAggregateBitwise) {
  const auto grains = orientations(7);
  const DriverRecord driver = run_aggregate(grains);
  const pt::TaylorPoint taylor(fcc(), grains);
  pt::TaylorState s = taylor.initial_state();
  const std::size_t outputs =
      along_grain_path([&](const Eigen::Matrix3d& l, double dt, std::size_t k) {
        const pt::TaylorUpdate u = taylor.update(s, l, dt);
        ASSERT_TRUE(u.report.ok) << u.report.why;
        s = u.state;
        ASSERT_LT(k, driver.macro_stress.size());
        EXPECT_EQ(cr::symmetric_from_mandel(u.stress), driver.macro_stress[k]) << "increment " << k;
      });
  EXPECT_EQ(outputs, driver.macro_stress.size());
}

// d sigma / d (D dt) against central differences of the update in each Mandel direction, after
// a prestrain (several systems active).
TEST(MaterialPoint, GrainTangentIsTheDerivativeOfTheUpdate) {
  const pt::GrainPoint grain(fcc());
  const cr::LoadSegment tension = grain_path()[0];
  pt::GrainState s = grain.initial_state(orientations(3)[2]);
  for (int k = 0; k < 10; ++k) s = grain.update(s, tension.velocity_gradient, 0.2).state;
  const double dt = 0.1;
  const pt::GrainUpdate u = grain.update(s, tension.velocity_gradient, dt);
  ASSERT_TRUE(u.report.ok);
  const double h = 1e-8;  // strain
  for (int j = 0; j < 6; ++j) {
    pt::Mandel6 e = pt::Mandel6::Zero();
    e(j) = h;
    const Eigen::Matrix3d dl = cr::symmetric_from_mandel(e) / dt;
    const pt::Mandel6 d = (grain.update(s, tension.velocity_gradient + dl, dt).stress -
                           grain.update(s, tension.velocity_gradient - dl, dt).stress) /
                          (2.0 * h);
    for (int i = 0; i < 6; ++i)
      EXPECT_NEAR(u.tangent(i, j), d(i), 1e-5 * u.tangent.norm()) << i << ", " << j;
  }
}

TEST(MaterialPoint, GrainBatchGivesEachGrainsUpdate) {
  const pt::GrainPoint grain(fcc());
  const auto grains = orientations(5);
  std::vector<pt::GrainState> states;
  std::vector<Eigen::Matrix3d> gradients;
  for (std::size_t k = 0; k < grains.size(); ++k) {
    const Eigen::Matrix3d l = grain_path()[k % 3].velocity_gradient;
    states.push_back(grain.update(grain.initial_state(grains[k]), l, 0.5).state);
    gradients.push_back(l * (1.0 + 0.1 * static_cast<double>(k)));
  }
  std::vector<pt::GrainUpdate> out(states.size());
  grain.update(states, gradients, 0.25, out);
  for (std::size_t k = 0; k < states.size(); ++k) {
    const pt::GrainUpdate one = grain.update(states[k], gradients[k], 0.25);
    EXPECT_EQ(out[k].stress, one.stress);
    EXPECT_EQ(out[k].tangent, one.tangent);
    EXPECT_EQ(out[k].state.slip, one.state.slip);
  }
}

TEST(MaterialPoint, AStateOfAnotherSlipCountIsRefused) {
  const pt::GrainPoint grain(fcc());
  pt::GrainState s = grain.initial_state(Eigen::Matrix3d::Identity());
  s.mu.resize(6);
  EXPECT_THROW(grain.update(s, Eigen::Matrix3d::Zero(), 1.0), std::invalid_argument);
  pt::GrainOptions o;
  o.tolerance = 0.0;
  EXPECT_THROW(pt::GrainPoint(fcc(), o), std::invalid_argument);
}

}  // namespace
