// Tests that pin down the physics of one frictional contact point driven by the
// subloading-overstress friction law (Hashiguchi et al. 2016), with both integrators.
//
// Units: N, mm, min (stress in MPa, stiffness in MPa/mm, velocity in mm/min). Expected values
// are computed inside the tests (closed forms, bisection, convergence sequences); no number is
// copied from a run of the code.
//
// Two tolerances recur and are derived once here:
//  * kResidualTol = 1e-12: IntegratorOptions::residual_tolerance, the flow residual G (traction
//    ratio units, dG/dr >= 1) at which the implicit step stops. It bounds the error of r.
//  * the slip resolution: a root in the slip increment ds alone resolves ds to 1e-14 relative
//    (the x_tol of its bracketed Newton), and the traction is alpha (du - ds), so r would be
//    resolved only to alpha * 1e-14 * du / (f_n mu): ~2e-9 at the paper's alpha = 1e6 MPa/mm
//    and du ~ 0.1 mm. The step takes such a root again in the traction (model.md), so this is
//    a bound, not the resolution; `ratio_resolution` below returns twice the sum, and
//    LongSlidingStepMeetsTheFlowRuleToItsTolerance checks kResidualTol alone.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <iostream>
#include <limits>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include "message_number.hpp"
#include "paper_law.hpp"
#include "subslip/contact/contact_point.hpp"
#include "subslip/history/contact_history.hpp"
#include "subslip/law/subloading_friction.hpp"

using namespace subslip::contact;
using namespace subslip::history;
namespace law = subslip::law;

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kEps = std::numeric_limits<double>::epsilon();
constexpr double kResidualTol = 1e-12;
constexpr double kSlipResolution = 1e-14;
constexpr double kFn = 5.56;  // normal traction of the paper's section 5 test [MPa]

// The paper's section 5 constants (figure 11a); its contact: alpha = 1000 GPa/mm.
using subslip::testing::paper_law;

ContactModel make_model(const law::LawParameters& p, double alpha = 1e6) {
  ContactModel m;
  m.law = p;
  m.initial_law_state = {p.friction.mu_s, 0.0};  // fully recovered, unloaded
  m.stiffness = {alpha, alpha};
  m.initial_normal_traction = kFn;
  return m;
}

// A slide of `length` mm at `velocity` in `increments` increments whose lengths grow
// geometrically by `last_over_first` overall (1: uniform).
Segment slide(const Vec2& velocity, double length, int increments, double last_over_first = 1.0) {
  Segment s;
  s.velocity = velocity;
  s.duration = length / velocity.norm();
  s.normal_traction = kFn;
  s.increments = increments;
  s.growth = increments > 1 ? std::pow(last_over_first, 1.0 / (increments - 1)) : 1.0;
  return s;
}

Segment hold(double duration, int increments, double last_over_first = 1.0) {
  Segment s;
  s.duration = duration;
  s.normal_traction = kFn;
  s.increments = increments;
  s.growth = increments > 1 ? std::pow(last_over_first, 1.0 / (increments - 1)) : 1.0;
  return s;
}

struct Trace {
  std::vector<ContactState> states;  // initial state, then one per increment
  std::vector<int> segment;          // -1 for the initial state
};

Trace run(const ContactModel& m, const std::vector<Segment>& segments,
          Method method = Method::implicit, int max_cutbacks = 40) {
  IntegratorOptions opt;
  opt.method = method;
  opt.max_cutbacks = max_cutbacks;
  EXPECT_EQ(opt.residual_tolerance, kResidualTol);  // the tolerances below are derived from it
  Trace t;
  run_history(m, segments, opt, [&](const ContactState& s, int seg) {
    t.states.push_back(s);
    t.segment.push_back(seg);
  });
  return t;
}

// ---- independent analytical steady state (paper section 3b) -------------------------------

// mu_ss from kappa (1 - mu/mu_k) v + xi (1 - mu/mu_s) = 0.
double steady_mu(const law::FrictionCoefficientEvolution& f, double v) {
  return (f.kappa * v + f.xi) / (f.kappa * v / f.mu_k + f.xi / f.mu_s);
}

// phi(r, r_s) of (3.10)/(3.15), written here independently of the code under test.
double phi_ref(const law::Overstress& o, double r, double r_s) {
  if (r <= r_s) return 0.0;
  const double x = r - r_s;
  const double g =
      o.form == law::OverstressForm::exponential ? std::expm1(o.n * x) : std::pow(x, o.n);
  return g / (o.eta_v * (o.r_hat - r));
}

double phi_r_ref(const law::Overstress& o, double r, double r_s) {
  const double x = r - r_s, gap = o.r_hat - r;
  const bool e = o.form == law::OverstressForm::exponential;
  const double g = e ? std::expm1(o.n * x) : std::pow(x, o.n);
  const double dg = e ? o.n * std::exp(o.n * x) : o.n * std::pow(x, o.n - 1.0);
  return (dg * gap + g) / (o.eta_v * gap * gap);
}

// r_ss from phi(r_ss, 1) = v by bisection on [1, r_hat] (phi is increasing there); the
// rate-independent model slides at r = r_s = 1.
double steady_r(const law::LawParameters& p, double v) {
  if (p.overstress.form == law::OverstressForm::rate_independent) return 1.0;
  double lo = 1.0, hi = p.overstress.r_hat;
  for (int i = 0; i < 2000; ++i) {
    const double mid = 0.5 * (lo + hi);
    if (mid <= lo || mid >= hi) break;
    (phi_ref(p.overstress, mid, 1.0) < v ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

// Resolution of r for an implicit increment of sliding du (see the file comment).
double ratio_resolution(double alpha, double du, double mu) {
  return 2.0 * (kResidualTol + alpha * kSlipResolution * du / (kFn * mu));
}

double last_increment_slip(const Segment& s) {
  return increment_lengths(s).back() * s.velocity.norm();
}

double peak_ratio(const Trace& t, int segment) {
  double peak = 0.0;
  for (size_t i = 0; i < t.states.size(); ++i)
    if (t.segment[i] == segment) peak = std::max(peak, t.states[i].traction_ratio());
  return peak;
}

// Admissibility of one output state; empty when fine.
std::string inadmissible(const ContactState& s, const law::LawParameters& p) {
  std::ostringstream why;
  const bool finite = std::isfinite(s.traction_t.x()) && std::isfinite(s.traction_t.y()) &&
                      std::isfinite(s.traction_n) && std::isfinite(s.law.mu) &&
                      std::isfinite(s.law.r_s) && std::isfinite(s.r) && std::isfinite(s.vp_slip) &&
                      std::isfinite(s.time);
  if (!finite) why << "non-finite ";
  if (!(s.law.r_s >= 0.0)) why << "r_s<0 ";
  if (!(s.law.r_s <= s.r)) why << "r_s>r ";
  if (p.overstress.form != law::OverstressForm::rate_independent && !(s.r < p.overstress.r_hat))
    why << "r>=r_hat ";
  // The exact mu update never leaves [min(mu_k, mu_s), max(mu_k, mu_s)] from a start inside.
  const double lo = std::min(p.friction.mu_s, p.friction.mu_k);
  const double hi = std::max(p.friction.mu_s, p.friction.mu_k);
  if (!(s.law.mu >= lo * (1.0 - 4 * kEps) && s.law.mu <= hi * (1.0 + 4 * kEps))) why << "mu ";
  // (2.22): f_t/f_n = r mu, to rounding.
  if (finite && std::abs(s.traction_ratio() - s.r * s.law.mu) > 8 * kEps * s.traction_ratio())
    why << "ratio!=r*mu ";
  if (!why.str().empty()) {
    why << "(t=" << s.time << " r=" << s.r << " r_s=" << s.law.r_s << " mu=" << s.law.mu << ")";
  }
  return why.str();
}

// Measured numbers worth quoting, printed with enough digits to compare.
std::ostream& measured() {
  return std::cout << std::setprecision(12) << "[ measured ] ";
}

// Least-squares slope of log(err) against log(h).
double observed_order(const std::vector<double>& h, const std::vector<double>& err) {
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  const double n = static_cast<double>(h.size());
  for (size_t i = 0; i < h.size(); ++i) {
    const double x = std::log(h[i]), y = std::log(err[i]);
    sx += x;
    sy += y;
    sxx += x * x;
    sxy += x * y;
  }
  return (n * sxy - sx * sy) / (n * sxx - sx * sx);
}

const law::OverstressForm kAllForms[] = {law::OverstressForm::exponential,
                                         law::OverstressForm::power,
                                         law::OverstressForm::rate_independent};

}  // namespace

// ---------------------------------------------------------------------------------------------
// Segments.
// ---------------------------------------------------------------------------------------------

TEST(ContactSegments, IncrementLengthsAreGeometricAndSumToDuration) {
  for (int n : {1, 2, 7, 1000}) {
    for (double growth : {1.0, 0.9, 1.01}) {
      Segment s;
      s.duration = 3.7;
      s.increments = n;
      s.growth = growth;
      const auto dt = increment_lengths(s);
      ASSERT_EQ(dt.size(), static_cast<size_t>(n));
      double sum = 0.0;
      for (size_t i = 0; i < dt.size(); ++i) {
        sum += dt[i];
        if (i > 0) {
          EXPECT_NEAR(dt[i] / dt[i - 1], growth, 4 * kEps);
        }
      }
      // A sum of n positive terms: n eps relative rounding at most.
      EXPECT_NEAR(sum, s.duration, n * kEps * s.duration);
    }
  }
}

// The prescribed normal traction is affine in time to its own precision near its zero, where a
// contact opens or closes: at three close times there, the middle value lies on the chord of the
// outer two to a few ulps of itself (not of the segment's start traction, 1e9 times and more
// f_n there). A traction that jitters by more than its own ulps is a rate a short step sees.
TEST(ContactSegments, NormalTractionIsAffineToItsOwnPrecisionNearItsZero) {
  const ContactStiffness stiffness{1e6, 1e6};
  Segment unload;  // 5.56 MPa to -1 MPa over 0.5 min: opens at 0.5 x 5.56 / 6.56 min
  unload.duration = 0.5;
  unload.normal_traction = -1.0;
  Segment close;  // from -1 MPa at a normal velocity: closes at 1 / 6.56 min
  close.duration = 1.0;
  close.normal_control = NormalControl::velocity;
  close.normal_velocity = 6.56e-6;
  for (const auto& [seg, fn_start] : {std::pair{unload, 5.56}, std::pair{close, -1.0}}) {
    const double zero = seg.normal_control == NormalControl::velocity
                            ? -fn_start / (stiffness.alpha_n * seg.normal_velocity)
                            : seg.duration * fn_start / (fn_start - seg.normal_traction);
    for (double before : {1e-9, 1e-12, 1e-14}) {
      const double t0 = zero * (1.0 - 2.0 * before), t2 = zero * (1.0 - before);
      const double t1 = 0.5 * (t0 + t2);
      const double f0 = normal_traction_at(seg, stiffness, fn_start, t0);
      const double f1 = normal_traction_at(seg, stiffness, fn_start, t1);
      const double f2 = normal_traction_at(seg, stiffness, fn_start, t2);
      const double chord = f0 + (f2 - f0) * ((t1 - t0) / (t2 - t0));
      EXPECT_NE(f1, 0.0);
      EXPECT_LE(std::abs(f1 - chord), 8.0 * kEps * std::abs(f1))
          << "f_n " << f1 << " at " << before << " of the zero's time before it";
    }
  }
}

// ---------------------------------------------------------------------------------------------
// 3. Steady sliding reaches the analytical steady state.
// ---------------------------------------------------------------------------------------------

TEST(ContactSteadyState, LongSlideReachesAnalyticalSteadyState) {
  struct Case {
    law::OverstressForm form;
    law::SubloadingFunction f;
  };
  std::vector<Case> cases;
  for (auto form : kAllForms) cases.push_back({form, law::SubloadingFunction::cot});
  cases.push_back({law::OverstressForm::exponential, law::SubloadingFunction::neg_log});
  cases.push_back({law::OverstressForm::exponential, law::SubloadingFunction::reciprocal});
  for (const auto& c : cases) {
    for (double v : {1.0, 200.0}) {
      const auto p = paper_law(c.form, c.f);
      const double alpha = 1e6;
      // 20 mm: the mu transient decays like exp(-(kappa/mu_k) u) = e^-47 and r_s reaches 1 to
      // double precision after a few / u_tilde of slip.
      const Segment seg = slide(Vec2(v, 0.0), 20.0, 2000, 1e5);
      const Trace t = run(make_model(p, alpha), {seg});
      SCOPED_TRACE(std::string(law::to_string(c.form)) + "/" + std::string(law::to_string(c.f)) +
                   " v=" + std::to_string(v));
      for (const auto& s : t.states) ASSERT_EQ(inadmissible(s, p), "");
      const ContactState& end = t.states.back();
      const double mu_ss = steady_mu(p.friction, v);
      const double r_ss = steady_r(p, v);
      const double tol_r = ratio_resolution(alpha, last_increment_slip(seg), mu_ss);
      // r_s -> 1: the rate-independent step leaves r_s = min(R, r) with |r - R| <= the residual
      // tolerance per step; 100 x that bounds what the attraction of U lets accumulate.
      EXPECT_NEAR(end.law.r_s, 1.0, 100 * kResidualTol);
      // mu: the transient is e^-47; the last steps slide at v to the slip resolution (1e-14),
      // and the exact update contracts each step's rounding by e^{-B} (B ~ 0.3 per final
      // increment), leaving ~eps/B ~ 1e-15 relative: 1e-12 relative.
      EXPECT_NEAR(end.law.mu, mu_ss, 1e-12 * mu_ss);
      EXPECT_NEAR(end.r, r_ss, tol_r);
      EXPECT_NEAR(end.traction_ratio(), r_ss * mu_ss, tol_r * mu_ss + 1e-12 * r_ss * mu_ss);
      EXPECT_NEAR(end.vp_rate, v, 1e-9 * v);  // all the sliding is viscoplastic at steady state
      measured() << "steady " << law::to_string(c.form) << "/" << law::to_string(c.f) << " v=" << v
                 << ": ratio " << end.traction_ratio() << " analytical " << r_ss * mu_ss << " (r "
                 << end.r << " vs " << r_ss << ", mu " << end.law.mu << " vs " << mu_ss << ")\n";
    }
  }
}

// ---------------------------------------------------------------------------------------------
// 4. Rate sensitivity and the properties of paper section 3b.
// ---------------------------------------------------------------------------------------------

TEST(ContactRateSensitivity, ExponentialPeakAndBottomIncreaseWithSpeed) {
  const auto p = paper_law();
  double previous_peak = 0.0, previous_bottom = 0.0;
  for (double v : {1.0, 10.0, 50.0, 100.0, 200.0}) {  // the speeds of the paper's test
    const Trace t = run(make_model(p), {slide(Vec2(v, 0.0), 20.0, 2000, 1e5)});
    const double peak = peak_ratio(t, 0);
    const double bottom = t.states.back().traction_ratio();
    // Positive rate sensitivity (paper figures 9, 12): strictly larger at a larger speed.
    EXPECT_GT(peak, previous_peak) << "v=" << v;
    EXPECT_GT(bottom, previous_bottom) << "v=" << v;
    EXPECT_GT(peak, bottom);
    previous_peak = peak;
    previous_bottom = bottom;
    measured() << "exponential v=" << v << ": peak " << peak << " bottom " << bottom << "\n";
  }
}

// Property (1) of section 3b: as v -> 0, r -> r_s and mu -> mu_s, so f_t/f_n -> r_s mu_s -> mu_s
// (the subloading-friction model is recovered). Property (6) for fluid friction: r > 1.
TEST(ContactRateSensitivity, QuasiStaticLimitAndFastSliding) {
  const auto p = paper_law();
  const auto& o = p.overstress;
  double previous_deviation = std::numeric_limits<double>::infinity();
  for (double v : {200.0, 1.0, 1e-2, 1e-3, 1e-4, 1e-5}) {
    const Segment seg = slide(Vec2(v, 0.0), 20.0, 200, 1e4);
    const Trace t = run(make_model(p), {seg});
    const ContactState& end = t.states.back();
    const double mu_ss = steady_mu(p.friction, v);
    const double tol_r = ratio_resolution(1e6, last_increment_slip(seg), mu_ss);
    EXPECT_NEAR(end.r, steady_r(p, v), tol_r) << "v=" << v;
    EXPECT_NEAR(end.law.r_s, 1.0, 100 * kResidualTol);
    const double deviation = std::abs(end.traction_ratio() / p.friction.mu_s - 1.0);
    EXPECT_LT(deviation, previous_deviation) << "v=" << v;
    previous_deviation = deviation;
    // Fast (and any nonzero) sliding of the overstress model is above the normal-yield surface.
    EXPECT_GT(end.r, 1.0) << "v=" << v;
    if (v >= 1.0) {
      EXPECT_GT(end.traction_ratio() / p.friction.mu_s, 1.0) << "v=" << v;
    }
    if (v == 1e-5) {
      // Linearising e^{n x} - 1 ~ n x in phi(1 + x, 1) = v: x = eta_v (r_hat - 1) v / n, with
      // relative error ~ n x/2 + x/(r_hat - 1) < 0.5% at this speed; 1% tolerance.
      const double x_lin = o.eta_v * (o.r_hat - 1.0) * v / o.n;
      EXPECT_NEAR(end.r - 1.0, x_lin, 1e-2 * x_lin);
      // mu_ss = mu_s (1 - (kappa v/xi)(mu_s/mu_k - 1)) to first order in v.
      EXPECT_NEAR(end.law.mu / p.friction.mu_s, 1.0, 2.0 * 0.2 * v / 0.009 * (0.097 / 0.085 - 1.0));
      EXPECT_LT(deviation, 1e-3);
    }
  }
}

// Dry friction (section 2 model): negative rate sensitivity, f_t/f_n = mu <= mu_s, r = r_s <= 1.
TEST(ContactRateSensitivity, RateIndependentHasNegativeRateSensitivity) {
  const auto p = paper_law(law::OverstressForm::rate_independent);
  double previous = std::numeric_limits<double>::infinity();
  for (double v : {1e-2, 1.0, 200.0, 1e4}) {
    const Segment seg = slide(Vec2(v, 0.0), 20.0, 2000, 1e5);
    const Trace t = run(make_model(p), {seg});
    // r = r_s: the flow residual is r - R(r_s0, ds), zero to the ratio resolution of the
    // largest increment (bounded with mu >= mu_k).
    const double tol_r = ratio_resolution(1e6, last_increment_slip(seg), p.friction.mu_k);
    for (const auto& s : t.states) {
      ASSERT_EQ(inadmissible(s, p), "");
      ASSERT_NEAR(s.r, s.law.r_s, tol_r);
      ASSERT_LE(s.law.r_s, 1.0);
      ASSERT_LE(s.r, 1.0 + tol_r);
      ASSERT_LE(s.traction_ratio(), p.friction.mu_s * (1.0 + tol_r));
    }
    const double ratio = t.states.back().traction_ratio();
    const double mu_ss = steady_mu(p.friction, v);
    EXPECT_NEAR(ratio, mu_ss, tol_r * mu_ss) << "v=" << v;
    EXPECT_LT(ratio, previous) << "v=" << v;
    previous = ratio;
    measured() << "rate-independent v=" << v << ": steady ratio " << ratio << " analytical "
               << mu_ss << "\n";
  }
}

// ---------------------------------------------------------------------------------------------
// 5. Peak, decay toward the kinetic value, recovery during a hold.
// ---------------------------------------------------------------------------------------------

TEST(ContactHold, PeakThenDecayTowardKinetic) {
  for (auto form : {law::OverstressForm::exponential, law::OverstressForm::rate_independent}) {
    SCOPED_TRACE(std::string(law::to_string(form)));
    const auto p = paper_law(form);
    const Trace t = run(make_model(p), {slide(Vec2(1.0, 0.0), 20.0, 2000, 1e5)});
    size_t ipeak = 0;
    for (size_t i = 0; i < t.states.size(); ++i)
      if (t.states[i].traction_ratio() > t.states[ipeak].traction_ratio()) ipeak = i;
    const double peak = t.states[ipeak].traction_ratio();
    const double bottom = t.states.back().traction_ratio();
    // The peak is an interior maximum, reached after a monotone rise.
    ASSERT_GT(ipeak, 0u);
    ASSERT_LT(ipeak + 10, t.states.size());
    for (size_t i = 1; i <= ipeak; ++i)
      EXPECT_GE(t.states[i].traction_ratio(), t.states[i - 1].traction_ratio()) << i;
    // Then decays to the bottom without undershooting it (beyond the ratio resolution).
    for (size_t i = ipeak; i < t.states.size(); ++i)
      EXPECT_GE(t.states[i].traction_ratio(), bottom - 1e-8 * bottom) << i;
    EXPECT_GT(peak, bottom * 1.05);
    // The friction coefficient has gone from mu_s toward mu_k and stopped at mu_ss, which is
    // within (xi/(kappa v)) of mu_k.
    const double mu_ss = steady_mu(p.friction, 1.0);
    EXPECT_NEAR(t.states.back().law.mu, mu_ss, 1e-12 * mu_ss);  // as in the long slide test
    EXPECT_LT(t.states.back().law.mu - p.friction.mu_k, 0.1 * (p.friction.mu_s - p.friction.mu_k));
  }
}

// During a hold without slip, (3.4) reduces to d mu/dt = xi (1 - mu/mu_s), whose solution from
// mu(t1) = mu1 is mu(t) = mu_s + (mu1 - mu_s) exp(-xi (t - t1)/mu_s) (separate variables:
// d(mu - mu_s)/(mu - mu_s) = -(xi/mu_s) dt). The traction does not change (no sliding, no
// viscoplastic slip), so r = f_t/(f_n mu) falls as mu recovers and r_s follows it (3.12).
TEST(ContactHold, RecoveryFollowsExactExponentialWhileStuck) {
  for (auto form : {law::OverstressForm::exponential, law::OverstressForm::rate_independent}) {
    SCOPED_TRACE(std::string(law::to_string(form)));
    const auto p = paper_law(form);
    const auto& fr = p.friction;
    const std::vector<Segment> segs = {slide(Vec2(1.0, 0.0), 5.0, 500, 1e4), hold(100.0, 200, 1e6),
                                       slide(Vec2(1.0, 0.0), 5.0, 500, 1e4)};
    const Trace t = run(make_model(p), segs);
    for (const auto& s : t.states) ASSERT_EQ(inadmissible(s, p), "");
    std::vector<size_t> in_hold;
    for (size_t i = 0; i < t.states.size(); ++i)
      if (t.segment[i] == 1) in_hold.push_back(i);
    const double final_vp = t.states[in_hold.back()].vp_slip;
    // The first hold output after which no more viscoplastic slip happens.
    size_t k1 = in_hold.front();
    for (size_t i : in_hold)
      if (t.states[i].vp_slip != final_vp) k1 = i + 1;
    ASSERT_LE(k1, in_hold.back() - 20) << "the contact never sticks during the hold";
    const ContactState& s1 = t.states[k1];
    for (size_t i = k1; i <= in_hold.back(); ++i) {
      const ContactState& s = t.states[i];
      // Bit-for-bit: no slip means the traction is untouched.
      EXPECT_EQ(s.traction_t, s1.traction_t) << i;
      EXPECT_EQ(s.vp_slip, s1.vp_slip) << i;
      const double expected =
          fr.mu_s + (s1.law.mu - fr.mu_s) * std::exp(-fr.xi * (s.time - s1.time) / fr.mu_s);
      // The implicit step applies the same exponential per increment; composing (i - k1)
      // increments costs a few ulps of mu each.
      EXPECT_NEAR(s.law.mu, expected, (i - k1 + 1) * 8 * kEps * fr.mu_s) << i;
      if (i > k1) {  // outputs reached by a stuck increment
        EXPECT_EQ(s.law.r_s, s.r) << i;
        EXPECT_LT(s.r, t.states[i - 1].r) << i;
      }
    }
    // Re-slide after the hold: the recovered friction gives a new peak above the ratio just
    // before the hold (which was the steady sliding value).
    const double before_hold = t.states[in_hold.front() - 1].traction_ratio();
    const double repeak = peak_ratio(t, 2);
    EXPECT_GT(repeak, before_hold * 1.01);
    measured() << "" << law::to_string(form) << ": ratio before hold " << before_hold
               << ", peak on re-slide " << repeak << ", mu after hold "
               << t.states[in_hold.back()].law.mu << "\n";
  }
}

// ---------------------------------------------------------------------------------------------
// 6. Bounds over the parameter space.
// ---------------------------------------------------------------------------------------------

namespace {

// Runs every combination and returns a description of each failure (empty: all admissible).
std::vector<std::string> sweep(law::OverstressForm form, const std::vector<double>& speeds,
                               const std::vector<double>& exponents,
                               const std::vector<double>& r_hats,
                               const std::vector<double>& alphas) {
  std::vector<std::string> failures;
  // Step sizes: the whole 2 mm slide in one increment, ten increments, and 1000 increments
  // graded from ~4e-10 mm (last/first = 1e8) -- tiny against every elastic length f_t/alpha.
  const std::pair<int, double> steppings[] = {{1, 1.0}, {10, 1.0}, {1000, 1e8}};
  for (double v : speeds) {
    for (double n : exponents) {
      for (double r_hat : r_hats) {
        for (double alpha : alphas) {
          for (auto [increments, grading] : steppings) {
            auto p = paper_law(form);
            p.overstress.n = n;
            p.overstress.r_hat = r_hat;
            std::ostringstream tag;
            tag << "v=" << v << " n=" << n << " r_hat=" << r_hat << " alpha=" << alpha
                << " increments=" << increments << ": ";
            try {
              const Trace t =
                  run(make_model(p, alpha), {slide(Vec2(v, 0.0), 2.0, increments, grading)});
              for (const auto& s : t.states) {
                const std::string why = inadmissible(s, p);
                if (!why.empty()) {
                  failures.push_back(tag.str() + why);
                  break;
                }
              }
            } catch (const std::exception& e) {
              failures.push_back(tag.str() + e.what());
            }
          }
        }
      }
    }
  }
  return failures;
}

std::string summary(const std::vector<std::string>& failures) {
  std::ostringstream out;
  out << failures.size() << " failing combinations";
  for (size_t i = 0; i < std::min<size_t>(failures.size(), 8); ++i) out << "\n  " << failures[i];
  return out.str();
}

}  // namespace

TEST(ContactBounds, AdmissibleAcrossParameterSpaceExponential) {
  const auto failures = sweep(law::OverstressForm::exponential, {1e-4, 1e-2, 1.0, 1e2, 1e4, 1e6},
                              {1.0, 4.0, 16.0, 128.0}, {1.01, 1.8, 6.4}, {1e5, 1e6, 1e8});
  EXPECT_TRUE(failures.empty()) << summary(failures);
}

// Regression: the power form once failed whenever an increment's elastic trial ratio was small
// enough that the root of the flow residual lay ~2^200 below the trial slip (now solved in
// z = ds^(1/n), see SubloadingFrictionLaw::slip_exponent).
TEST(ContactBounds, AdmissibleAcrossParameterSpacePower) {
  const auto failures = sweep(law::OverstressForm::power, {1e-4, 1e-2, 1.0, 1e2, 1e4, 1e6},
                              {1.0, 4.0, 16.0, 128.0}, {1.01, 1.8, 6.4}, {1e5, 1e6, 1e8});
  EXPECT_TRUE(failures.empty()) << summary(failures);
}

TEST(ContactBounds, AdmissibleAcrossParameterSpaceRateIndependent) {
  const auto failures = sweep(law::OverstressForm::rate_independent,
                              {1e-4, 1e-2, 1.0, 1e2, 1e4, 1e6}, {16.0}, {1.8}, {1e5, 1e6, 1e8});
  EXPECT_TRUE(failures.empty()) << summary(failures);
}

// Regression (was a bug: the root was out of reach in ds). Power overstress form (3.10) with the
// paper's n = 16, alpha = 1e6 MPa/mm, a fresh contact (mu = 0.097, r = r_s = 0, f_n = 5.56) and a
// first increment du = 1e-10 mm in dt = 1e-10 min: the elastic trial ratio is r_trial = alpha
// du/(f_n mu) = 1.85e-4, and the flow residual G(ds) = r - r_s - (eta_v (r_hat - r) ds/dt)^{1/n}
// has its root at ds ~ dt r_trial^n/(eta_v r_hat) ~ 1e-73 mm, i.e. ~2^210 below the bracket [0,
// f_t/alpha]. Newton steps leave the bracket (G ~ -ds^{1/n} is concave), so the safeguarded Newton
// bisects and stops at its 200-iteration cap: implicit_step returns ok = false ("flow rule did not
// converge"). Halving the increment only makes r_trial smaller, so advance() throws StepFailure
// after 40 cut-backs. Expected: ok, with the (essentially elastic) answer r = r_trial.
TEST(ContactBounds, PowerFormImplicitStepWithSmallTrialRatio) {
  for (double n : {16.0, 32.0}) {
    auto p = paper_law(law::OverstressForm::power);
    p.overstress.n = n;
    const law::SubloadingFrictionLaw lw(p);
    const ContactStiffness c{1e6, 1e6};
    ContactState s0;
    s0.traction_n = kFn;
    s0.law = {p.friction.mu_s, 0.0};
    const double du = 1e-10, dt = 1e-10;
    const auto a = implicit_step(lw, c, s0, Vec2(du, 0.0), kFn, dt, kResidualTol);
    EXPECT_TRUE(a.ok) << "n=" << n << ": " << a.why << " after " << a.iterations << " iterations";
    if (a.ok) {
      const double r_trial = c.alpha_t * du / (kFn * p.friction.mu_s);
      // The viscoplastic slip is ~1e-63 of du: r equals the trial ratio to rounding.
      EXPECT_NEAR(a.state.r, r_trial, 1e-12 * r_trial);
      EXPECT_LE(a.state.law.r_s, a.state.r);
    }
  }
}

// Impact: as the speed grows the steady r approaches r_hat from below (3.9).
TEST(ContactBounds, ImpactSteadyRatioApproachesRhat) {
  const auto p = paper_law();
  double previous_gap = std::numeric_limits<double>::infinity();
  for (double v = 1e2; v <= 1e8 * 1.001; v *= 10.0) {
    const Segment seg = slide(Vec2(v, 0.0), 20.0, 200, 1e4);
    const Trace t = run(make_model(p), {seg});
    const ContactState& end = t.states.back();
    const double gap = p.overstress.r_hat - end.r;
    const double expected_gap = p.overstress.r_hat - steady_r(p, v);
    EXPECT_GT(gap, 0.0) << "v=" << v;
    EXPECT_LT(gap, previous_gap) << "v=" << v;
    EXPECT_NEAR(gap, expected_gap,
                ratio_resolution(1e6, last_increment_slip(seg), steady_mu(p.friction, v)))
        << "v=" << v;
    previous_gap = gap;
  }
  EXPECT_LT(previous_gap, 1e-5);  // analytically 3.8e-6 at 1e8 mm/min
}

// ---------------------------------------------------------------------------------------------
// 7. Integrator convergence.
// ---------------------------------------------------------------------------------------------

namespace {

// The ratio at a quarter of the slide and the peak ratio, for uniform increments.
struct Probe {
  double quarter;
  double peak;
};
Probe probe(const ContactModel& m, double v, double length, int increments, Method method) {
  const Trace t = run(m, {slide(Vec2(v, 0.0), length, increments)}, method);
  return {t.states[static_cast<size_t>(increments / 4)].traction_ratio(), peak_ratio(t, 0)};
}

// Forward Euler at N, 2N, 4N, 8N increments against a converged implicit reference; returns the
// observed orders (quarter-point value, peak).
std::pair<double, double> forward_euler_order(const ContactModel& m, const char* label) {
  const double v = 1.0, length = 0.5;
  // Reference: the implicit integrator at 32000 and 64000 increments; its own change under
  // halving must be negligible against the smallest forward Euler error (checked below).
  const Probe ref = probe(m, v, length, 32000, Method::implicit);
  const Probe ref2 = probe(m, v, length, 64000, Method::implicit);
  std::vector<double> h, e_quarter, e_peak;
  for (int n : {16000, 32000, 64000, 128000}) {
    const Probe fe = probe(m, v, length, n, Method::forward_euler);
    h.push_back(length / v / n);
    e_quarter.push_back(std::abs(fe.quarter - ref.quarter));
    e_peak.push_back(std::abs(fe.peak - ref.peak));
    measured() << "" << label << " FE N=" << n << ": |error| at u/4 " << e_quarter.back()
               << ", of peak " << e_peak.back() << "\n";
  }
  EXPECT_LT(std::abs(ref.quarter - ref2.quarter), 1e-2 * e_quarter.back());
  EXPECT_LT(std::abs(ref.peak - ref2.peak), 1e-2 * e_peak.back());
  for (size_t i = 1; i < h.size(); ++i) {
    EXPECT_LT(e_quarter[i], e_quarter[i - 1]);
    EXPECT_LT(e_peak[i], e_peak[i - 1]);
  }
  // The finest forward Euler result agrees with the implicit one to 1e-5 relative.
  EXPECT_LT(e_quarter.back(), 1e-5 * ref.quarter);
  EXPECT_LT(e_peak.back(), 1e-5 * ref.peak);
  return {observed_order(h, e_quarter), observed_order(h, e_peak)};
}

}  // namespace

// Forward Euler is first order; its error constant is what it is, but the ratio of errors at
// halved steps must tend to 2. The window [0.8, 1.2] admits the residual pre-asymptotic
// curvature of a 4-point fit and nothing else (order 2 or 0.5 would fail).
// Mildly stiff setting: alpha = 1e3 MPa/mm (the paper's lower range 1e2 GPa/mm is 1e5), so the
// forward Euler stability limit 2/lambda, lambda = alpha (d phi/d r)/(f_n mu) ~ 4e4 /min at
// v = 1 mm/min, is ~5e-5 min: the steps used, 3.1e-5..3.9e-6 min, are stable.
TEST(ContactConvergence, ForwardEulerIsFirstOrderTowardImplicit) {
  const auto [order_quarter, order_peak] =
      forward_euler_order(make_model(paper_law(), 1e3), "exponential alpha=1e3");
  measured() << "exponential FE observed order: " << order_quarter << " (u/4), " << order_peak
             << " (peak)\n";
  EXPECT_GE(order_quarter, 0.8);
  EXPECT_LE(order_quarter, 1.2);
  EXPECT_GE(order_peak, 0.8);
  EXPECT_LE(order_peak, 1.2);
}

// 9. The rate-independent forward Euler (plastic multiplier (2.44)) and the rate-independent
// implicit integrator agree as the forward Euler step shrinks, at first order.
TEST(ContactConvergence, RateIndependentForwardEulerConvergesToImplicit) {
  const auto [order_quarter, order_peak] = forward_euler_order(
      make_model(paper_law(law::OverstressForm::rate_independent), 1e3), "rate-independent");
  measured() << "rate-independent FE observed order: " << order_quarter << " (u/4), " << order_peak
             << " (peak)\n";
  EXPECT_GE(order_quarter, 0.8);
  EXPECT_LE(order_quarter, 1.2);
  EXPECT_GE(order_peak, 0.8);
  EXPECT_LE(order_peak, 1.2);
}

// The implicit result does not depend on the step size beyond its discretisation error: the
// paper setting with 2000 and 20000 graded increments agrees on the peak to better than 1e-3
// relative, and on the bottom to the ratio resolution.
TEST(ContactConvergence, ImplicitIsStepSizeIndependent) {
  const auto p = paper_law();
  for (double v : {1.0, 200.0}) {
    const Segment coarse = slide(Vec2(v, 0.0), 20.0, 2000, 1e5);
    const Segment fine = slide(Vec2(v, 0.0), 20.0, 20000, 1e5);
    const Trace tc = run(make_model(p), {coarse});
    const Trace tf = run(make_model(p), {fine});
    const double pc = peak_ratio(tc, 0), pf = peak_ratio(tf, 0);
    EXPECT_LT(std::abs(pc / pf - 1.0), 1e-3) << "v=" << v;
    const double mu_ss = steady_mu(p.friction, v);
    EXPECT_NEAR(tc.states.back().traction_ratio(), tf.states.back().traction_ratio(),
                mu_ss * ratio_resolution(1e6, last_increment_slip(coarse), mu_ss));
    measured() << "implicit v=" << v << ": peak 2000 steps " << pc << ", 20000 steps " << pf
               << ", relative difference " << std::abs(pc / pf - 1.0) << "\n";
  }
}

// One increment for the whole 20 mm slide: the implicit step's slip rate is
// ds/dt = v (1 - f_t/(alpha L)), and mu, r_s reach their attractors (e^-47, r_s = 1), so the
// state is the analytical steady state at that rate, to the slip resolution of a 20 mm step.
TEST(ContactConvergence, SingleWholeSlideStepReproducesSteadyState) {
  for (auto form : kAllForms) {
    for (double v : {1.0, 200.0}) {
      const auto p = paper_law(form);
      const double alpha = 1e6, length = 20.0;
      const Trace t = run(make_model(p, alpha), {slide(Vec2(v, 0.0), length, 1)});
      ASSERT_EQ(t.states.size(), 2u);
      const ContactState& end = t.states.back();
      ASSERT_EQ(inadmissible(end, p), "");
      const double mu_ss = steady_mu(p.friction, v);
      const double r_ss = steady_r(p, v);
      // The rate deficit f_t/(alpha L) shifts r by (f_t/(alpha L)) v / phi_r.
      const double deficit = end.traction_ratio() * kFn / (alpha * length);
      const double shift = form == law::OverstressForm::rate_independent
                               ? 0.0
                               : deficit * v / phi_r_ref(p.overstress, r_ss, 1.0);
      const double tol_r = ratio_resolution(alpha, length, mu_ss) + 2.0 * shift;
      EXPECT_NEAR(end.r, r_ss, tol_r) << law::to_string(form) << " v=" << v;
      // ... and mu by deficit * (d ln mu_ss/d ln v) relative, with
      // d ln mu_ss/d ln v = kappa v/(kappa v + xi) - (kappa v/mu_k)/(kappa v/mu_k + xi/mu_s).
      const auto& f = p.friction;
      const double dlnmu = f.kappa * v / (f.kappa * v + f.xi) -
                           (f.kappa * v / f.mu_k) / (f.kappa * v / f.mu_k + f.xi / f.mu_s);
      const double tol_mu = (2.0 * deficit * std::abs(dlnmu) + 1e-13) * mu_ss;
      EXPECT_NEAR(end.law.mu, mu_ss, tol_mu) << law::to_string(form) << " v=" << v;
      EXPECT_NEAR(end.traction_ratio(), r_ss * mu_ss, tol_r * mu_ss + tol_mu * r_ss);
    }
  }
}

// One increment for a 2 m slide: the slid part of the trial traction is 1e9 times the traction
// kept (alpha ds against f_t), so the slip increment resolves r only to alpha ulp(ds) /
// (f_n mu), about 4e-7. The step still meets its flow rule to the residual tolerance: r is the
// root of phi(r, 1) = ds/dt, the step's own rate v (1 - f_t/(alpha L)), to kResidualTol
// (dG/dr >= 1), at sliding and at impact speed.
TEST(ContactConvergence, LongSlidingStepMeetsTheFlowRuleToItsTolerance) {
  for (auto form : {law::OverstressForm::exponential, law::OverstressForm::power}) {
    for (double v : {1.0, 1e4}) {
      const auto p = paper_law(form);
      const double alpha = 1e6, length = 2000.0;
      const Trace t = run(make_model(p, alpha), {slide(Vec2(v, 0.0), length, 1)});
      ASSERT_EQ(t.states.size(), 2u);
      const ContactState& end = t.states.back();
      ASSERT_EQ(inadmissible(end, p), "");
      ASSERT_EQ(end.law.r_s, 1.0);  // 2 m of slip at u_tilde = 80 /mm
      const double rate = v * (1.0 - end.traction_t.norm() / (alpha * length));
      EXPECT_NEAR(end.r, steady_r(p, rate), 2.0 * kResidualTol)
          << law::to_string(form) << " v=" << v;
    }
  }
}

// ---------------------------------------------------------------------------------------------
// 8. Two-dimensional sliding.
// ---------------------------------------------------------------------------------------------

TEST(Contact2D, DirectionChangeRotatesTractionTowardNewSlip) {
  const auto p = paper_law();
  // 20 mm after the turn so that the mu transient (e^{-(kappa/mu_k) u}) is gone.
  const std::vector<Segment> segs = {slide(Vec2(1.0, 0.0), 2.0, 400, 1e4),
                                     slide(Vec2(0.0, 1.0), 20.0, 2000, 1e8)};
  const Trace t = run(make_model(p), segs);
  double previous_angle = 0.0;
  for (size_t i = 0; i < t.states.size(); ++i) {
    const ContactState& s = t.states[i];
    ASSERT_EQ(inadmissible(s, p), "") << i;
    // |f_t|/f_n <= r_hat mu (the dynamic loading surface never passes the limit surface).
    EXPECT_LT(s.traction_ratio(), p.overstress.r_hat * s.law.mu) << i;
    if (t.segment[i] != 1) continue;
    EXPECT_GE(s.traction_t.x(), 0.0) << i;  // never overshoots past +y
    EXPECT_GE(s.traction_t.y(), 0.0) << i;
    const double angle = std::atan2(s.traction_t.y(), s.traction_t.x());
    // Monotone rotation toward +y: each trial adds a +y component, and the return keeps the
    // trial direction (2.39). Rounding of atan2 only.
    EXPECT_GE(angle, previous_angle - 4 * kEps) << i;
    previous_angle = angle;
  }
  const ContactState& end = t.states.back();
  // The old x component decays over a slip of |f_t|/alpha ~ 1e-6 mm (d f_x/d u_vp = -alpha
  // f_x/|f_t|); after 20 mm it is gone to any precision, so 1e-12 only allows rounding.
  EXPECT_LE(std::abs(end.traction_t.x()), 1e-12 * end.traction_t.norm());
  EXPECT_NEAR(previous_angle, 0.5 * kPi, 1e-12);
  // Isotropy: after the transient the steady state is the one of a straight slide.
  const double mu_ss = steady_mu(p.friction, 1.0);
  EXPECT_NEAR(end.traction_ratio(), steady_r(p, 1.0) * mu_ss,
              mu_ss * ratio_resolution(1e6, last_increment_slip(segs[1]), mu_ss) + 1e-12 * mu_ss);
}

// Rate-independent sliding at r_s = 1 (1 - r_s decays like e^{-u_tilde pi/2 u}: below an ulp
// after 1 mm) turned by 90 degrees: consistency keeps |f_t| = r_s mu f_n, and r_s never falls
// while sliding (dr_s = U(r_s) ds >= 0), so |f_t|/f_n stays mu_s (kappa = xi = 0: mu is mu_s)
// exactly however the turn is stepped. 20000 steps of 5e-10 mm each: a step that left r_s a
// residual below its flow-rule value on each of them would drift r_s down by their sum.
TEST(Contact2D, RateIndependentTurnOfManyStepsStaysOnTheYieldSurface) {
  auto p = paper_law(law::OverstressForm::rate_independent);
  p.friction.kappa = 0.0;
  p.friction.xi = 0.0;
  const std::vector<Segment> segs = {slide(Vec2(1.0, 0.0), 1.0, 200, 1e4),
                                     slide(Vec2(0.0, 1.0), 1e-5, 20000)};
  const Trace t = run(make_model(p), segs);
  ASSERT_EQ(t.states.size(), 1u + 200u + 20000u);
  double lowest = 1.0;
  for (size_t i = 0; i < t.states.size(); ++i) {
    if (t.segment[i] != 1) continue;
    const ContactState& s = t.states[i];
    ASSERT_EQ(inadmissible(s, p), "") << i;
    lowest = std::min(lowest, s.traction_ratio() / p.friction.mu_s);
  }
  EXPECT_EQ(t.states[200].law.r_s, 1.0);  // the turn starts from r_s = 1
  // Rounding of |f_t| / f_n only (a few ulps).
  EXPECT_LT(1.0 - lowest, 8 * kEps);
}

TEST(Contact2D, ReversalChangesSignAndPassesThroughZero) {
  for (auto form : {law::OverstressForm::exponential, law::OverstressForm::rate_independent}) {
    SCOPED_TRACE(std::string(law::to_string(form)));
    const auto p = paper_law(form);
    const double alpha = 1e6;
    // 20 mm backwards so that the mu transient is gone at the end; increments graded from
    // ~1e-10 mm so that the zero crossing (within ~1e-6 mm) is resolved.
    const std::vector<Segment> segs = {slide(Vec2(1.0, 0.0), 2.0, 400, 1e4),
                                       slide(Vec2(-1.0, 0.0), 20.0, 3000, 1e10)};
    const auto dts = increment_lengths(segs[1]);  // = slip lengths at 1 mm/min
    const Trace t = run(make_model(p, alpha), segs);
    size_t first = 0;
    for (size_t i = 0; i < t.states.size(); ++i) {
      ASSERT_EQ(inadmissible(t.states[i], p), "") << i;
      EXPECT_EQ(t.states[i].traction_t.y(), 0.0) << i;  // exactly one-dimensional
      if (t.segment[i] == 1 && first == 0) first = i;
    }
    const double f_rev = t.states[first - 1].traction_t.x();
    ASSERT_GT(f_rev, 0.0);
    size_t cross = 0;
    for (size_t i = first; i < t.states.size(); ++i) {
      if (t.states[i].traction_t.x() <= 0.0) {
        cross = i;
        break;
      }
    }
    ASSERT_GT(cross, 0u) << "the traction never changed sign";
    const double before = t.states[cross - 1].traction_t.x(),
                 after = t.states[cross].traction_t.x();
    const double du = dts[cross - first];  // the increment that produced states[cross]
    // The ratio passes through zero within that increment: the jump |f_before| + |f_after| is at
    // most the elastic change alpha |du| (viscoplastic slip only reduces |trial|).
    EXPECT_LE(std::abs(before) + std::abs(after), alpha * du * (1.0 + 1e-12));
    // And it happens within the elastic unloading length f_t/alpha of the reversal (plus that
    // increment): relaxation of the overstress can only make it earlier.
    double since_reversal = 0.0;
    for (size_t j = 0; j <= cross - first; ++j) since_reversal += dts[j];
    EXPECT_LE(since_reversal, (f_rev / alpha + du) * (1.0 + 1e-12));
    // After 2 mm backwards: steady sliding in -x.
    const ContactState& end = t.states.back();
    EXPECT_LT(end.traction_t.x(), 0.0);
    const double mu_ss = steady_mu(p.friction, 1.0);
    EXPECT_NEAR(
        end.traction_ratio(), steady_r(p, 1.0) * mu_ss,
        mu_ss * ratio_resolution(alpha, last_increment_slip(segs[1]), mu_ss) + 1e-12 * mu_ss);
  }
}

// ---------------------------------------------------------------------------------------------
// 10. Failure reporting.
// ---------------------------------------------------------------------------------------------

TEST(ContactFailure, ForwardEulerBeyondStabilityNeverYieldsNonFinite) {
  // The paper setting's forward Euler stability limit is ~2/lambda ~ 5e-8 min at v = 1 mm/min
  // (lambda = alpha phi_r/(f_n mu) with alpha = 1e6); the increments here are 0.1..20 min.
  int thrown = 0, completed = 0;
  for (auto form : kAllForms) {
    const auto p = paper_law(form);
    for (double v : {1.0, 200.0}) {
      for (int increments : {1, 10, 100}) {
        for (int cutbacks : {0, 4, 8}) {
          std::ostringstream tag;
          tag << law::to_string(form) << " v=" << v << " increments=" << increments
              << " max_cutbacks=" << cutbacks;
          SCOPED_TRACE(tag.str());
          ContactState last;
          IntegratorOptions opt;
          opt.method = Method::forward_euler;
          opt.max_cutbacks = cutbacks;
          try {
            run_history(make_model(p), {slide(Vec2(v, 0.0), 20.0, increments)}, opt,
                        [&](const ContactState& s, int) {
                          ASSERT_EQ(inadmissible(s, p), "");
                          last = s;
                        });
            ++completed;
          } catch (const StepFailure& e) {
            ++thrown;
            const std::string msg = e.what();
            EXPECT_EQ(msg.find("nan"), std::string::npos) << msg;
            EXPECT_EQ(msg.find("inf"), std::string::npos) << msg;
            // The message names the time and the state (r, r_s, mu) of the last accepted
            // state; they are printed with 6 significant digits.
            auto value_of = [&](const std::string& key) {
              return subslip::testing::number_after(msg, key);
            };
            const double time = value_of("at time ");
            const double mu = value_of("mu = ");
            const double r = value_of(" r = ");
            const double r_s = value_of("r_s = ");
            EXPECT_NEAR(time, last.time, 1e-5 * std::abs(last.time) + 1e-300);
            EXPECT_NEAR(mu, last.law.mu, 1e-5 * last.law.mu);
            EXPECT_NEAR(r, last.r, 1e-5 * std::abs(last.r) + 1e-300);
            EXPECT_NEAR(r_s, last.law.r_s, 1e-5 * std::abs(last.law.r_s) + 1e-300);
          }
        }
      }
    }
  }
  // A single 20 mm elastic predictor with no cut-back allowed (r_trial = alpha 20/(f_n mu) ~ 4e7
  // >> r_hat, or r_s >= 2 for the rate-independent cot branch) must be reported, so the failure
  // path is exercised.
  EXPECT_GT(thrown, 0);
  measured() << "forward Euler beyond stability: " << completed << " runs completed admissibly, "
             << thrown << " reported StepFailure\n";
}

// A failure after a stably integrated stretch, so that the reported state is not the initial
// one: 0.1 mm at 1 mm/min with alpha = 1e3 MPa/mm in 8000 forward Euler increments (1.25e-5 min,
// below the ~5e-5 min stability limit), then a jump to 1e4 mm/min for 20 mm in one increment
// with two cut-backs allowed. Each attempted piece has an elastic predictor alpha (du - dt phi)
// ~ 1e3 * 5 MPa, i.e. r ~ 1e4 >> r_hat: the failure is certain, and must name the state reached
// after the first segment.
TEST(ContactFailure, ForwardEulerFailureNamesTheLastAcceptedState) {
  const auto p = paper_law();
  IntegratorOptions opt;
  opt.method = Method::forward_euler;
  opt.max_cutbacks = 2;
  ContactState last;
  std::string msg;
  try {
    run_history(make_model(p, 1e3),
                {slide(Vec2(1.0, 0.0), 0.1, 8000), slide(Vec2(1e4, 0.0), 20.0, 1)}, opt,
                [&](const ContactState& s, int) {
                  ASSERT_EQ(inadmissible(s, p), "");
                  last = s;
                });
  } catch (const StepFailure& e) {
    msg = e.what();
  }
  ASSERT_FALSE(msg.empty()) << "an impossible forward Euler step was accepted";
  ASSERT_GT(last.time, 0.0);
  ASSERT_GT(last.r, 1.0);
  auto value_of = [&](const std::string& key) { return subslip::testing::number_after(msg, key); };
  // Printed with 6 significant digits: 1e-5 relative.
  EXPECT_NEAR(value_of("at time "), last.time, 1e-5 * last.time) << msg;
  EXPECT_NEAR(value_of("mu = "), last.law.mu, 1e-5 * last.law.mu) << msg;
  EXPECT_NEAR(value_of(" r = "), last.r, 1e-5 * last.r) << msg;
  EXPECT_NEAR(value_of("r_s = "), last.law.r_s, 1e-5 * last.law.r_s) << msg;
}
