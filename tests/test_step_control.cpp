// The adaptive step clock (integrators/step_control.hpp) and the extrapolation tableau
// (integrators/extrapolation.hpp). The clock's stops: an estimate at its round-off level (the
// resolution the driver gives) is the noise floor, and the message names the smallest tolerance
// that runs; backward Euler's estimate, which falls as dt^2 wherever it measures the step, stops
// the segment when it has not even halved while the step shrank 1e3-fold, instead of crawling
// down to dt ~ 1e-20; an estimate that falls more slowly than dt^2 is no stop.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include "subslip/integrators/extrapolation.hpp"
#include "subslip/integrators/step_control.hpp"

using subslip::integrators::AdaptiveSegment;
using subslip::integrators::EstimateNoise;

namespace {
// Backward Euler's estimate with a resolution far below the tolerances used here.
constexpr EstimateNoise kBackwardEuler{1e-15, true, true};
}  // namespace

// Backward Euler's estimate that does not fall: stopped once the step is 1e3 times shorter, with
// a message that says what it compares is not determined, not that the tolerance is too small.
TEST(StepControl, BackwardEulersEstimateThatDoesNotFallStops) {
  AdaptiveSegment clock(1.0, 1e-2, 1e-9);
  int refusals = 0;
  while (clock.refuse(false, 3e-9, kBackwardEuler)) ++refusals;
  EXPECT_TRUE(clock.estimate_does_not_fall());
  EXPECT_FALSE(clock.at_noise_floor());
  EXPECT_FALSE(clock.below_time_resolution());
  EXPECT_LE(clock.step(), 1e-5);
  EXPECT_LT(refusals, 20);  // 0.1 x per refusal at most: a few refusals, not a crawl to 1e-20
  const std::string why = clock.not_falling_message();
  EXPECT_NE(why.find("does not fall as the step shrinks (3e-09 at dt = 0.01"), std::string::npos)
      << why;
  EXPECT_NE(why.find("not determined by the step's equations"), std::string::npos) << why;
  EXPECT_EQ(why.find("double precision"), std::string::npos) << why;
}

// An estimate that falls as dt^2 is a real error: retried until it fits, never a stop.
TEST(StepControl, EstimateThatFallsAsDtSquaredIsRetriedUntilItFits) {
  AdaptiveSegment clock(1.0, 1e-2, 1e-9);
  const double c = 1e-3 / (1e-2 * 1e-2);  // error 1e-3 at the first step
  double error = c * clock.step() * clock.step();
  int refusals = 0;
  while (error > 1e-9) {
    ASSERT_TRUE(clock.refuse(false, error, kBackwardEuler));
    ASSERT_FALSE(clock.at_noise_floor());
    ASSERT_FALSE(clock.estimate_does_not_fall());
    error = c * clock.step() * clock.step();
    ++refusals;
  }
  EXPECT_GT(refusals, 2);
  clock.accept(error);
  EXPECT_FALSE(clock.at_noise_floor());
}

// An estimate that falls only as dt (noise proportional to the step, as backward Euler's
// estimate carries where the rates are steep in r) or as dt^(1/2) is no stop either: the step
// shrinks until it fits, far beyond the 1e3-fold shrink.
TEST(StepControl, EstimateThatFallsMoreSlowlyThanDtSquaredIsNoStop) {
  for (const double power : {1.0, 0.5}) {
    SCOPED_TRACE(power);
    AdaptiveSegment clock(1.0, 1e-2, 1e-9);
    const auto estimate = [&] { return 3e-5 * std::pow(clock.step() / 1e-2, power); };
    double error = estimate();
    while (error > 1e-9) {
      ASSERT_TRUE(clock.refuse(false, error, kBackwardEuler)) << "dt = " << clock.step();
      ASSERT_FALSE(clock.estimate_does_not_fall());
      error = estimate();
    }
    EXPECT_LT(clock.step(), 1e-2 / 1e3 * (power == 1.0 ? 1.0 : 1e-3));
    clock.accept(error);
  }
}

// Failed attempts (no solution) halve the step without an estimate: no stop from them.
TEST(StepControl, FailedAttemptsAreNoNoiseFloor) {
  AdaptiveSegment clock(1.0, 1e-2, 1e-9);
  for (int i = 0; i < 15; ++i) ASSERT_TRUE(clock.refuse(true, 0.0, kBackwardEuler));
  EXPECT_FALSE(clock.at_noise_floor());
  EXPECT_FALSE(clock.estimate_does_not_fall());
  EXPECT_TRUE(clock.refuse(false, 3e-9, kBackwardEuler));  // the first estimate: a new start
  EXPECT_FALSE(clock.at_noise_floor());
  EXPECT_FALSE(clock.estimate_does_not_fall());
}

// Backward Euler's estimate at its resolution, once it stops falling, is the noise floor: the
// message names a tolerance at least the resolution.
TEST(StepControl, BackwardEulersEstimateAtItsResolutionIsTheNoiseFloor) {
  AdaptiveSegment clock(1.0, 1e-2, 1e-13);
  const EstimateNoise noise{2.5e-12, true, true};
  EXPECT_TRUE(clock.refuse(false, 2e-12, noise));  // below the resolution, but the first
  EXPECT_TRUE(clock.refuse(false, 1e-12, noise));  // still falling
  EXPECT_FALSE(clock.refuse(false, 1.2e-12, noise));
  EXPECT_TRUE(clock.at_noise_floor());
  EXPECT_FALSE(clock.estimate_does_not_fall());
  const std::string why = clock.noise_floor_message();
  EXPECT_NE(why.find("use a tolerance of at least 2.50e-12"), std::string::npos) << why;
}

// With the estimate's resolution given (the extrapolated integrators), a flat estimate above it
// keeps shrinking the step (no 1000-fold rule), and one at the resolution stops with its message.
TEST(StepControl, KnownResolutionDecidesTheNoiseFloor) {
  AdaptiveSegment clock(1.0, 1e-2, 1e-9, 3);
  for (int k = 0; k < 12; ++k) ASSERT_TRUE(clock.refuse(false, 1e-6, {1e-11})) << "refusal " << k;
  EXPECT_LT(clock.step(), 1e-2 / 1e6);  // shrunk far below 1000-fold, still going
  EXPECT_FALSE(clock.refuse(false, 1e-11, {1e-11}));
  EXPECT_TRUE(clock.at_noise_floor());
  const std::string why = clock.noise_floor_message();
  EXPECT_NE(why.find("round-off"), std::string::npos) << why;
  EXPECT_NE(why.find("1e-09"), std::string::npos) << why;
  EXPECT_NE(why.find("use a tolerance of at least 1.00e-11"), std::string::npos) << why;
}

// The tolerance a refusal at the known resolution names is at least that resolution, shown in
// three digits rounded up, so a clock at the named tolerance is never stopped by the floor: its
// estimates at the resolution are accepted.
TEST(StepControl, NamedToleranceIsAtLeastTheResolutionAndPassesTheFloor) {
  for (const double resolution : {2.0000000000004e-12, 1.234567e-10, 9.996e-9, 3e-9}) {
    SCOPED_TRACE(resolution);
    AdaptiveSegment clock(1.0, 1e-2, 0.1 * resolution, 2);
    EXPECT_FALSE(clock.refuse(false, resolution, {resolution}));
    ASSERT_TRUE(clock.at_noise_floor());
    const std::string why = clock.noise_floor_message();
    const std::string key = "use a tolerance of at least ";
    const auto at = why.find(key);
    ASSERT_NE(at, std::string::npos) << why;
    const double named = std::stod(why.substr(at + key.size()));
    EXPECT_GE(named, resolution);
    EXPECT_LE(named, resolution * (1.0 + 1e-2));  // three digits, rounded up by one at most
    AdaptiveSegment at_named(1.0, 1e-2, named, 2);
    EXPECT_TRUE(at_named.refuse(false, 1.5 * named, {resolution}));
    EXPECT_FALSE(at_named.at_noise_floor());
  }
}

// A step shorter than the time it starts at resolves (kSameTime of it: its end, or the end of a
// substep of it, would round onto its start) is none. An estimate that stays above the
// tolerance and above its known resolution shrinks the step down to there, and the clock gives
// up with its own message; it never hands a solver a step whose substeps have length zero.
TEST(StepControl, StepBelowTheTimesResolutionEndsTheSegment) {
  using subslip::integrators::kSameTime;
  AdaptiveSegment clock(1.0, 0.0514, 1e-9, 2);
  clock.accept(1e-12);  // t = 0.0514 s into the segment
  const double t = clock.time();
  ASSERT_GT(t, 0.05);
  int refusals = 0;
  for (;;) {
    const double h = clock.step();
    for (int k = 1; k <= 4; ++k) EXPECT_NE(t + h / k, t) << "a substep of length zero";
    if (!clock.refuse(false, 2.2e-9, {1e-12})) break;
    ++refusals;
  }
  // From the second retry on the flat estimate shrinks the step tenfold (its observed order is
  // zero): 0.0514 s to kSameTime of the time in 15 or 16 retries (at the order's factor, 0.61
  // each, about 70).
  EXPECT_GE(refusals, 14);
  EXPECT_LE(refusals, 17);
  EXPECT_FALSE(clock.at_noise_floor());
  EXPECT_TRUE(clock.below_time_resolution());
  EXPECT_LE(clock.planned_step(), kSameTime * t);
  const std::string why = clock.time_resolution_message();
  EXPECT_NE(why.find("fell below what the time 0.0514"), std::string::npos) << why;
}

// Where the time stops the step from shrinking, the shortest step tried is the least this run
// reaches there: the stop names its estimate as the tolerance that runs past it (in three
// digits, rounded up), as a noise-floor stop names its resolution, and a study's reference
// reruns at it. A last attempt that failed outright has no estimate and names none.
TEST(StepControl, StopBelowTheTimesResolutionNamesTheToleranceThatRunsPastIt) {
  AdaptiveSegment clock(1.0, 0.0514, 1e-9, 2);
  clock.accept(1e-12);  // t = 0.0514 s into the segment
  double last_estimate = 0.0;
  for (int k = 0;; ++k) {
    // Above the tolerance and far above the estimate's resolution (1e-12): no noise floor.
    last_estimate = 2.2e-9 + 1e-12 * k;
    if (!clock.refuse(false, last_estimate, {1e-12})) break;
  }
  ASSERT_TRUE(clock.below_time_resolution());
  const double named = clock.named_tolerance();
  EXPECT_GE(named, last_estimate);                 // the shortest step's estimate meets it
  EXPECT_LE(named, last_estimate * (1.0 + 1e-2));  // three digits
  const std::string why = clock.time_resolution_message();
  EXPECT_NE(why.find("use a tolerance of at least"), std::string::npos) << why;

  AdaptiveSegment failing(1.0, 0.0514, 1e-9, 2);
  failing.accept(1e-12);
  while (failing.refuse(true, 0.0, {1e-12})) {
  }
  ASSERT_TRUE(failing.below_time_resolution());
  EXPECT_TRUE(std::isnan(failing.named_tolerance()));
  EXPECT_EQ(failing.time_resolution_message().find("use a tolerance"), std::string::npos);
}

// A step shorter than what is left of the segment whose end rounds onto the segment's end is the
// last one (t = 1.7819370996222488, dt = 0.21806290037775111: t + dt = 2 while 2 - t =
// 0.21806290037775122): the clock ends there instead of planning a step of no length. (Reached on
// a contact of contact_stiffness_exponent.yaml, power form, n = 128, when a refusal held the step.)
TEST(StepControl, StepThatRoundsOntoTheEndIsTheLast) {
  const double t = 1.7819370996222488;
  const double dt = 0.21806290037775111;
  ASSERT_EQ(t + dt, 2.0);
  ASSERT_LT(dt, 2.0 - t);
  AdaptiveSegment clock(2.0, dt, 1e-3, 2, t, 10);
  EXPECT_TRUE(clock.last());
  EXPECT_EQ(clock.end_time(), 2.0);
  EXPECT_EQ(clock.step(), 2.0 - t);
  clock.accept(1e-4);
  EXPECT_EQ(clock.time(), 2.0);
}

// A step accepted right after a refused attempt is not grown, however small its estimate (the
// refused estimate grew faster than the order says: the step that followed is all that is known
// to fit); the next accepted step grows again.
TEST(StepControl, StepAfterARefusalDoesNotGrow) {
  AdaptiveSegment clock(10.0, 1.0, 1e-3);
  ASSERT_TRUE(clock.refuse(false, 4e-3, kBackwardEuler));
  const double retried = clock.step();
  ASSERT_LT(retried, 1.0);
  clock.accept(1e-6);  // a thousandth of the tolerance: 4 x growth without the rule
  EXPECT_EQ(clock.step(), retried);
  clock.accept(1e-6);
  EXPECT_EQ(clock.step(), 4.0 * retried);
}

// A step planned to end within 1 % of itself short of the segment's end takes the rest
// (kLastStepStretch): no sliver of a step is left over; one 2 % short is not stretched.
TEST(StepControl, StepThatEndsWithinAPercentOfTheEndTakesTheRest) {
  {
    AdaptiveSegment clock(10.0, 9.95, 1e-3);  // 0.5 % short
    EXPECT_TRUE(clock.last());
    EXPECT_EQ(clock.step(), 10.0);
    EXPECT_EQ(clock.end_time(), 10.0);
  }
  {
    AdaptiveSegment clock(10.0, 9.8, 1e-3);  // 2 % short
    EXPECT_FALSE(clock.last());
    EXPECT_EQ(clock.step(), 9.8);
  }
}

// A retry after a refused retry shrinks by the order its estimate showed between the two
// (observed_order): flat, by the smallest factor; falling as dt, by (T/err)^1; falling at its own
// order, by the order's factor as after the first refusal.
TEST(StepControl, RetryFollowsTheOrderTheEstimateShowed) {
  using subslip::integrators::kAfterRejected;
  {  // flat: the stiff part of a transient every longer step misses alike
    AdaptiveSegment clock(10.0, 1.0, 1e-3);
    ASSERT_TRUE(clock.refuse(false, 4e-3, kBackwardEuler));
    const double first = clock.step();
    EXPECT_DOUBLE_EQ(first, 0.45);  // 0.9 sqrt(1/4)
    ASSERT_TRUE(clock.refuse(false, 4e-3, kBackwardEuler));
    EXPECT_DOUBLE_EQ(clock.step(), kAfterRejected.smallest * first);  // not 0.45 again
  }
  {  // falling as dt
    AdaptiveSegment clock(10.0, 1.0, 1e-3);
    ASSERT_TRUE(clock.refuse(false, 2e-3, kBackwardEuler));
    const double first = clock.step();
    const double error = 2e-3 * first;
    ASSERT_TRUE(clock.refuse(false, error, kBackwardEuler));
    EXPECT_NEAR(clock.step(), first * 0.9 * (1e-3 / error), 1e-12);
  }
  {  // falling as dt^2: the classic factor, as after the first refusal
    AdaptiveSegment clock(10.0, 1.0, 1e-3);
    ASSERT_TRUE(clock.refuse(false, 0.5, kBackwardEuler));
    const double first = clock.step();
    const double error = 0.5 * first * first;
    ASSERT_TRUE(clock.refuse(false, error, kBackwardEuler));
    EXPECT_NEAR(clock.step(), first * 0.9 * std::sqrt(1e-3 / error), 1e-12);
  }
}

// The step factor of an estimate of order q: the step that would meet the tolerance exactly,
// 0.9 (tol/err)^(1/q), within the limits.
TEST(StepControl, FactorFollowsTheOrderOfTheEstimate) {
  using subslip::integrators::kAfterAccepted;
  using subslip::integrators::step_factor;
  EXPECT_EQ(step_factor(1e-8, 1e-6, 2, kAfterAccepted), 4.0);  // 0.9 x 10, at most 4
  EXPECT_EQ(step_factor(1e-9, 1e-6, 3, kAfterAccepted), 4.0);
  // The extrapolated integrators' estimates grow the step up to 10x.
  using subslip::integrators::after_accepted_limits;
  EXPECT_EQ(after_accepted_limits(1).largest, kAfterAccepted.largest);
  for (int order = 2; order <= 4; ++order) {
    const auto growth = after_accepted_limits(order);
    EXPECT_NEAR(step_factor(1e-8, 1e-6, 2, growth), 9.0, 1e-14);  // 0.9 x 10
    EXPECT_EQ(step_factor(1e-10, 1e-6, 2, growth), 10.0);         // 0.9 x 100, at most 10
    EXPECT_EQ(growth.smallest, kAfterAccepted.smallest);
  }
  EXPECT_NEAR(step_factor(16e-6, 1e-6, 4, kAfterAccepted), 0.45, 1e-14);
  EXPECT_NEAR(step_factor(8e-6, 1e-6, 3, kAfterAccepted), 0.45, 1e-14);
}

// ---- the extrapolation tableau (integrators/extrapolation.hpp) ----

namespace {

using Vec1 = Eigen::Matrix<double, 1, 1>;

// Results y_j = y + sum_m e_m (H/j)^m of j substeps, as backward Euler's error expansion has it.
std::array<Vec1, 4> expanded_results(double y, const std::array<double, 4>& e, double h) {
  std::array<Vec1, 4> out;
  for (int j = 1; j <= 4; ++j) {
    double v = y;
    for (int m = 1; m <= 4; ++m) v += e[static_cast<size_t>(m - 1)] * std::pow(h / j, m);
    out[static_cast<size_t>(j - 1)](0) = v;
  }
  return out;
}

}  // namespace

// Order k removes the error terms up to H^(k-1) exactly; the second-best removes up to H^(k-2),
// so best - second is the H^(k-1) term's leftover: it falls as H^(k-1) ... and best's error as H^k.
TEST(Extrapolation, TableauRemovesTheLeadingErrorTerms) {
  using subslip::integrators::extrapolate_implicit_euler;
  for (int k = 2; k <= 4; ++k) {
    std::array<double, 4> e{0.0, 0.0, 0.0, 0.0};
    for (int m = 0; m < k - 1; ++m) e[static_cast<size_t>(m)] = 1.0 + m;  // up to H^(k-1)
    const auto r = extrapolate_implicit_euler(expanded_results(2.0, e, 0.1), k);
    EXPECT_NEAR(r.best(0), 2.0, 1e-14) << "order " << k;
    EXPECT_GT(std::abs(r.second(0) - 2.0), 1e-6) << "order " << k;  // keeps the H^(k-1) term
    // With an H^k term the best is off by O(H^k): halving H divides it by 2^k.
    std::array<double, 4> f{0.0, 0.0, 0.0, 0.0};
    f[static_cast<size_t>(k - 1)] = 1.0;
    const double big = extrapolate_implicit_euler(expanded_results(0.0, f, 0.1), k).best(0);
    const double small = extrapolate_implicit_euler(expanded_results(0.0, f, 0.05), k).best(0);
    EXPECT_NEAR(big / small, std::pow(2.0, k), 1e-9) << "order " << k;
  }
}

// The guarded estimate of order 4 (guarded_estimate): in the asymptotic range it is of the order
// of the plain one (both fall with the same power of H when the step halves), and across the onset
// of sliding on the 200 mm/min friction fit, whose four backward-Euler solutions (the traction f_t
// in MPa of the step 8.06e-10 ... 3.13e-9 min, f_n mu = 0.539 MPa) agree in the last column by
// accident (6e-7 of the yield against a true error of 2.3e-3), it is the prediction from the
// columns before (3.9e-4), above a tolerance of 1e-4.
TEST(Extrapolation, GuardedEstimateKeepsTheOrderAndCatchesACancellingColumn) {
  using subslip::integrators::earlier_column_estimates;
  using subslip::integrators::extrapolate_implicit_euler;
  using subslip::integrators::guarded_estimate;
  const auto guarded = [](const std::array<Vec1, 4>& y, double scale) {
    const auto r = extrapolate_implicit_euler(y, 4);
    const auto earlier = earlier_column_estimates(y);
    return std::pair{
        std::abs(r.best(0) - r.second(0)) / scale,
        guarded_estimate(std::abs(r.best(0) - r.second(0)) / scale, std::abs(earlier[0](0)) / scale,
                         std::abs(earlier[1](0)) / scale)};
  };
  const std::array<double, 4> e{1.0, -2.0, 3.0, 5.0};
  const auto [plain_big, big] = guarded(expanded_results(0.0, e, 0.02), 1.0);
  const auto [plain_small, small] = guarded(expanded_results(0.0, e, 0.01), 1.0);
  EXPECT_NEAR(std::log2(big / small), std::log2(plain_big / plain_small), 0.3);
  EXPECT_LT(big, 10.0 * plain_big);
  EXPECT_GE(small, plain_small);

  std::array<Vec1, 4> onset;
  const double ft[4] = {0.3916869450, 0.4055719926, 0.4090668404, 0.4106016106};
  for (size_t j = 0; j < 4; ++j) onset[j](0) = ft[j];
  const auto [plain, safe] = guarded(onset, 0.539);
  EXPECT_LT(plain, 1e-6);
  EXPECT_GT(safe, 1e-4);
}

// Backward Euler's results on y' = lambda y combined: the amplification over a step vanishes as
// lambda H -> -infinity (stiff modes are damped) and stays below 1 on the negative real axis.
TEST(Extrapolation, StiffModesAreDampedAtAnyStep) {
  using subslip::integrators::extrapolate_implicit_euler;
  for (int k = 2; k <= 4; ++k) {
    for (double z : {-1e-3, -0.5, -1.0, -3.0, -10.0, -1e3, -1e8}) {
      std::array<Vec1, 4> y;
      for (int j = 1; j <= 4; ++j) y[static_cast<size_t>(j - 1)](0) = std::pow(1.0 - z / j, -j);
      const double amplification = extrapolate_implicit_euler(y, k).best(0);
      EXPECT_LT(std::abs(amplification), 1.0) << "order " << k << ", lambda H = " << z;
      if (z <= -1e3) {
        EXPECT_LT(std::abs(amplification), 30.0 / -z) << "order " << k;
      }
      if (z == -1e-3) {
        EXPECT_NEAR(amplification, std::exp(z), 1e-9) << "order " << k;
      }
    }
  }
}

// The kink model of combination_kink_bound: over a step of length 1 the rate is s (t - t*)+ (a
// start of slip) or s (t* - t)+ (a stop), and the solution with j substeps takes each substep's
// rate at its end (backward Euler). Over every position t* of the kink, the combination's error
// against the exact integral never exceeds the bound times backward Euler's one-step estimate
// 1/2 |rate(1) - rate(0)|, and comes within 1 % of it (the bound is the largest error, not a
// margin); the one-substep solution's own error is up to twice the estimate (at least the
// estimate at a start of slip).
TEST(Extrapolation, KinkBoundIsTheCombinationsLargestError) {
  using subslip::integrators::combination_kink_bound;
  using subslip::integrators::extrapolate_implicit_euler;
  for (int k = 2; k <= 4; ++k) {
    for (const bool onset : {true, false}) {
      double largest = 0.0;
      for (int p = 1; p < 1000; ++p) {
        const double kink = p / 1000.0;
        const auto rate = [&](double t) {
          return onset ? std::max(t - kink, 0.0) : std::max(kink - t, 0.0);
        };
        const double exact = onset ? 0.5 * (1 - kink) * (1 - kink) : 0.5 * kink * kink;
        std::array<Vec1, 4> y;
        for (int j = 1; j <= 4; ++j) {
          double slip = 0.0;
          for (int i = 1; i <= j; ++i) slip += rate(static_cast<double>(i) / j) / j;
          y[static_cast<size_t>(j - 1)](0) = slip;
        }
        const double estimate = 0.5 * std::abs(rate(1.0) - rate(0.0));
        const double one = std::abs(y[0](0) - exact) / estimate;
        if (onset) {
          EXPECT_GE(one, 1.0 - 1e-12);  // (a stop: the one substep sees no rate at all)
        }
        EXPECT_LE(one, 2.0 + 1e-12);
        const double combined = std::abs(extrapolate_implicit_euler(y, k).best(0) - exact);
        largest = std::max(largest, combined / estimate);
      }
      EXPECT_LE(largest, combination_kink_bound(k) + 1e-12) << "order " << k << " onset " << onset;
      EXPECT_GT(largest, 0.99 * combination_kink_bound(k)) << "order " << k << " onset " << onset;
    }
  }
}

// A stop an ulp short of the segment end (an output time computed from another run's times) is
// the end: the step to it is the last and ends exactly on the end, leaving no step of an ulp.
TEST(StepControl, StopWithinRoundOffOfTheEndIsTheEnd) {
  const double duration = 0.02;
  const std::array<double, 2> stops = {0.01, std::nextafter(duration, 0.0)};
  AdaptiveSegment clock(duration, 1e-3, 1e-6, 2);
  clock.set_stops(stops);
  int steps = 0;
  for (; !clock.last(); ++steps) {
    ASSERT_LT(steps, 100);
    clock.accept(0.0);
  }
  EXPECT_EQ(clock.end_time(), duration);
  EXPECT_EQ(clock.step(), duration - clock.time());
  EXPECT_TRUE(clock.accept(0.0));  // it ended on the stop
  EXPECT_EQ(clock.time(), duration);
}
