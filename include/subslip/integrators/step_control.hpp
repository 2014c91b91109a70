// Step-size control shared by the adaptive drivers (contact point, crystal aggregate).
//
// Backward Euler's local error of a step of length dt is about dt^2/2 |y''|, estimated by
// dt/2 |y'(end) - y'(start)|: an estimate of order 2 (it falls as dt^2). The extrapolated
// integrators (extrapolation.hpp) estimate the error of their second-best solution, of order k
// for the order-k integrator. A step whose estimate exceeds the tolerance is redone shorter; an
// accepted step sets the next one. The factor is the classic 0.9 (tol/err)^(1/q) for an estimate
// of order q, clamped so that one estimate never moves the step too far.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <span>
#include <string>
#include <vector>

namespace subslip::integrators {

// Limits of the factor for the next step after an accepted step, and for the retry of a
// refused one. An estimate predicts the error of a longer step only as far as its asymptotic
// form (err ~ dt^q) holds, so a larger growth risks refused steps, and a smaller one turns a
// scene's small first increment into a long ramp of steps the tolerance does not ask for.
// The extrapolated integrators' estimates (on states the grain determines) grow the next step
// at most 10x, the bound of DOPRI5 and of CVODE after its first step (at 4x,
// the 1000-grain aggregate's first increment of 1.4e-6 strain took 8 steps to 1 % at every
// tolerance from 1e-2 down, 0.061 times 1e-2; at 10x 5 steps, 0.11; docs/integrators.md).
// Backward Euler's own estimate (`order: 1`, whose error follows the square root of the
// tolerance anyway) keeps 4x, so that its runs keep their results.
struct StepFactorLimits {
  double smallest;
  double largest;
};
inline constexpr StepFactorLimits kAfterAccepted{0.2, 4.0};
inline constexpr StepFactorLimits kAfterAcceptedExtrapolated{0.2, 10.0};
inline constexpr StepFactorLimits kAfterRejected{0.1, 0.9};

// The limits after an accepted step for the adaptive integrator of `order` (1: backward Euler's
// estimate, 2 .. 4: extrapolated).
constexpr StepFactorLimits after_accepted_limits(int order) {
  return order >= 2 ? kAfterAcceptedExtrapolated : kAfterAccepted;
}

// The factor to scale the step by, given the local error estimate, its order (it falls as
// dt^order) and the tolerance. A zero error estimate (nothing changes) grows the step by the
// largest factor.
inline double step_factor(double error, double tolerance, int order, StepFactorLimits limits) {
  if (!(error > 0.0)) return limits.largest;
  const double ratio = tolerance / error;
  const double power = order == 2 ? std::sqrt(ratio) : std::pow(ratio, 1.0 / order);
  return std::clamp(0.9 * power, limits.smallest, limits.largest);
}

// The factor for the retry of a refused attempt of an estimate of `order` that fell as dt^q since
// the refused attempt before it (observed_order, at most `order`): step_factor at the order where
// it fell as fast as that, and the smallest factor for a q of zero or less (an estimate flat or
// growing as the step shrank).
inline double retry_factor(double error, double tolerance, double q, int order) {
  if (q >= order) return step_factor(error, tolerance, order, kAfterRejected);
  if (!(q > 0.0)) return kAfterRejected.smallest;
  return std::clamp(0.9 * std::pow(tolerance / error, 1.0 / q), kAfterRejected.smallest,
                    kAfterRejected.largest);
}

// The order an estimate showed from a refused attempt (longer_step, longer_error) to the shorter
// one after it (step, error), ln(e1/e2) / ln(h1/h2), at most `order`: an estimate that falls more
// slowly than its order says (the stiff part of a transient that every step longer than it misses
// alike, or an estimate outside its asymptotic range) would otherwise be retried at steps that
// shrink by (T/err)^(1/order) each, many retries for a fall that comes only once the step resolves
// the transient; one that falls faster keeps its order's factor.
inline double observed_order(double longer_step, double longer_error, double step, double error,
                             int order) {
  return std::min(static_cast<double>(order),
                  std::log(longer_error / error) / std::log(longer_step / step));
}

// Whether a forward Euler step checks its stability limit (dt lambda <= 2) and is refused
// beyond it (the default: the drivers then cut it back), or is taken unchecked (for measuring
// where forward Euler goes unstable).
enum class ExplicitStability { refuse_unstable_steps, unchecked };

// Consecutive refused attempts (rejected or failed) of one step before a driver gives up.
inline constexpr int kMaxRefusedAttempts = 200;

// Backward Euler's estimate falls as dt^2 wherever it measures the step, so after the step shrank
// by kFloorShrink over rejected attempts it should be 1e-6 of what it was; one that has not even
// halved compares rates the step's equations do not determine (the split of slip among systems
// that yield together, which the grain solve settles differently from attempt to attempt), and
// no shorter step will meet the tolerance. The factor only has to separate dt^2 from no fall at
// all: an estimate falling at any order of dt (noise proportional to the step, a first-order
// error) falls 1000-fold over it.
inline constexpr double kFloorShrink = 1e3;

// What a refused attempt's error estimate resolves, for the stops of AdaptiveSegment::refuse.
struct EstimateNoise {
  // The estimate's round-off level (> 0): the states or rates it compares are exact to a few ulps
  // and to the Newton tolerances, times the estimate's weights (estimate_noise_gain). An estimate
  // above the tolerance and at most this is the floor: no shorter step resolves more, and from a
  // tolerance of this on the floor no longer refuses a step.
  double resolution = 0.0;
  // The resolution is a bound that the estimate's actual round-off can lie far below, so an
  // estimate at or below it is the floor only once it has stopped falling: it is no smaller than
  // that of the longer attempt refused just before it.
  bool flat_only = false;
  // The estimate is backward Euler's own (dt/2 |y'(end) - y'(start)|, undivided steps): one that
  // does not fall over a kFloorShrink-fold shrink stops the segment as well. (The extrapolated
  // estimates can stay flat over a 1000-fold shrink outside their asymptotic range, a nonlinear
  // relaxation at the start of a hold, many time scales inside one step, where shorter steps do
  // help; and they divide a step into substeps, which need a step longer than the time's
  // resolution, kSameTime of it.)
  bool backward_euler = false;
};

// An output time within this fraction of the segment's duration of an increment's end is that
// end (no step of round-off length is made to reach it).
inline constexpr double kSameTime = 8.0 * std::numeric_limits<double>::epsilon();

// A step planned to end short of the segment's end by less than 1 % of itself is stretched to
// the end (DOPRI5's rule, Hairer, Norsett and Wanner): its error grows by ~1.01^(k+1), a few %,
// where the sliver left over would cost a whole step (the 1000-grain aggregate at 1e-3: a step of
// 2.47 s ended 0.019 s short of the end, and the sliver took a ninth step and 4 % more
// iterations).
inline constexpr double kLastStepStretch = 1.01;

// One step of a segment with fixed increments: the increments, each split at the output times
// that fall strictly inside it, so that a step ends on every output time.
struct FixedStep {
  double length = 0.0;         // of the step
  double end = 0.0;            // time into the segment at its end (exactly the output time)
  long increment = 0;          // the increment it belongs to (1-based)
  bool increment_end = false;  // it ends that increment
  bool output_time = false;    // it ends on an output time
};

// The steps of a segment of `increments` lengths (summing to `duration`) that must end on every
// `output_times` (increasing, in (0, duration]). The ends of unsplit increments are the running
// sum of their lengths, as a driver without output times accumulates them.
inline std::vector<FixedStep> fixed_steps(std::span<const double> increments,
                                          std::span<const double> output_times, double duration) {
  std::vector<FixedStep> steps;
  steps.reserve(increments.size() + output_times.size());
  const double same = kSameTime * duration;
  std::size_t next = 0;  // the first output time not reached yet
  double t = 0.0;
  for (std::size_t i = 0; i < increments.size(); ++i) {
    const bool last = i + 1 == increments.size();
    const double end = last ? duration : t + increments[i];
    double start = t;
    while (next < output_times.size() && output_times[next] < end - same) {
      if (output_times[next] > start + same) {
        steps.push_back({output_times[next] - start, output_times[next], static_cast<long>(i) + 1,
                         false, true});
        start = output_times[next];
      }
      ++next;
    }
    const bool at_output = next < output_times.size() && output_times[next] <= end + same;
    if (at_output) ++next;
    // (The last increment's length, as the driver has always taken it: from the increments.)
    steps.push_back({start == t ? increments[i] : end - start, last ? duration : t + increments[i],
                     static_cast<long>(i) + 1, true, at_output});
    t += increments[i];
  }
  return steps;
}

// The clock of one segment [0, duration] walked with adaptive steps: which step to try next,
// and how an accepted, rejected (error too large) or failed (no solution) attempt moves it. The
// last step ends exactly on the segment end, and with stops (output times) a step that would
// pass one is shortened to end exactly on it.
class AdaptiveSegment {
 public:
  // `order`: that of the error estimate (2 for backward Euler's, k for the order-k
  // extrapolation's); `growth`: the limits after an accepted step (after_accepted_limits).
  AdaptiveSegment(double duration, double first_step, double tolerance, int order = 2,
                  StepFactorLimits growth = kAfterAccepted)
      : duration_(duration),
        dt_(first_step),
        tolerance_(tolerance),
        order_(order),
        growth_(growth) {}
  // Resuming a segment part-way (a restart): `time` into it, `accepted` steps taken, and the
  // step planned next.
  AdaptiveSegment(double duration, double next_step, double tolerance, int order, double time,
                  long accepted, StepFactorLimits growth = kAfterAccepted)
      : duration_(duration),
        dt_(next_step),
        tolerance_(tolerance),
        order_(order),
        growth_(growth),
        t_(time),
        accepted_(accepted) {}

  // Times into the segment (increasing, in (0, duration]) that steps must end on; those up to
  // the current time are passed already.
  void set_stops(std::span<const double> stops) {
    stops_ = stops;
    next_stop_ = 0;
    while (next_stop_ < stops_.size() && stops_[next_stop_] <= t_) ++next_stop_;
  }

  // The step tried now ends on the next stop: it would reach it, or end within round-off of it
  // (kSameTime of the stop's time: a stop computed from another run's times, 1e-145 s into a
  // segment, may lie an ulp beyond this run's step end, and a step of 1e-161 s to reach it is
  // no step a solver resolves).
  bool at_stop() const {
    return next_stop_ < stops_.size() && reaches(t_ + dt_, stops_[next_stop_]);
  }
  // A step shorter than what is left can still end exactly on the segment's end (t + dt rounds to
  // it while dt < duration - t): it is the last, or the next would have no length. One planned to
  // end within kLastStepStretch of it takes the rest.
  bool last() const {
    return at_stop() ? reaches(stops_[next_stop_], duration_)
                     : dt_ >= duration_ - t_ || t_ + kLastStepStretch * dt_ >= duration_;
  }
  // The step to try now: the planned one, or what is left to the next stop or the segment end.
  double step() const {
    if (at_stop()) return stop_time() - t_;
    return last() ? duration_ - t_ : dt_;
  }
  // Time into the segment at the end of the step tried now.
  double end_time() const {
    if (at_stop()) return stop_time();
    return last() ? duration_ : t_ + dt_;
  }
  double time() const { return t_; }
  // How many of the stops the accepted steps have reached or passed.
  std::size_t stops_passed() const { return next_stop_; }
  // The step planned after the last accepted one (what a checkpoint records to resume with).
  double planned_step() const { return dt_; }
  long accepted() const { return accepted_; }
  int refusals() const { return refusals_; }

  // Returns whether the accepted step ended on a stop. A step shortened to a stop does not
  // shorten the next one unless its error asks for that.
  bool accept(double error) {
    const double h = step();
    bool stop = at_stop();
    const bool shortened = stop && !last() && h < dt_;
    const double planned = dt_;
    t_ = end_time();
    if (stop) ++next_stop_;
    // A step not shortened to a stop can still end exactly on it (t + dt rounds to the stop
    // while dt < stop - t): it ended there, and the stop is behind it.
    for (; next_stop_ < stops_.size() && reaches(t_, stops_[next_stop_]); ++next_stop_) stop = true;
    ++accepted_;
    // After a refused attempt the step does not grow (the rule of Hairer, Norsett and Wanner's
    // codes, facmax = 1 after a rejection): the estimate just grew faster than its order says.
    const StepFactorLimits limits =
        refusals_ > 0 ? StepFactorLimits{growth_.smallest, 1.0} : growth_;
    refusals_ = 0;
    refused_error_ = 0.0;
    refused_step_ = 0.0;
    const double factor = step_factor(error, tolerance_, order_, limits);
    dt_ = h * factor;
    if (shortened && factor >= 1.0) dt_ = std::max(dt_, planned);
    return stop;
  }
  // A refused attempt shortens the step: by the error estimate when it was too large, by half
  // when the step failed outright. False when the driver should give up: too many refusals in
  // a row, a step too short to advance the time, the estimate at its noise floor
  // (at_noise_floor(): at most `noise.resolution`, see EstimateNoise), or backward Euler's
  // estimate not falling as the step shrinks (estimate_does_not_fall()).
  bool refuse(bool failed, double error, const EstimateNoise& noise) {
    const double h = step();
    if (failed) {
      first_refused_ = {};  // a failed attempt has no estimate: start again after it
    } else if (refusals_ == 0 || first_refused_.error == 0.0) {
      first_refused_ = {h, error};
    }
    const double before = refused_error_;
    const double q = before > 0.0 && !failed && refused_step_ > h
                         ? observed_order(refused_step_, before, h, error, order_)
                         : static_cast<double>(order_);
    dt_ = failed ? 0.5 * h : h * retry_factor(error, tolerance_, q, order_);
    ++refusals_;
    refused_error_ = failed ? 0.0 : error;
    refused_step_ = failed ? 0.0 : h;
    noise_floor_ = !failed && error <= noise.resolution &&
                   (!noise.flat_only || (before > 0.0 && error >= before));
    if (noise_floor_) floor_ = {h, noise.resolution};
    not_falling_ = !noise_floor_ && noise.backward_euler && !failed && first_refused_.error > 0.0 &&
                   h <= first_refused_.step / kFloorShrink && error >= 0.5 * first_refused_.error;
    if (not_falling_) last_refused_ = {h, error};
    below_time_resolution_ =
        noise.backward_euler ? !(dt_ > 0.0 && t_ + dt_ != t_) : !resolvable(dt_);
    // The attempt whose shorter successor the time no longer resolves: its estimate is the
    // least this run reaches here (none where it failed outright).
    if (below_time_resolution_) shortest_ = {h, failed ? 0.0 : error};
    return !noise_floor_ && !not_falling_ && refusals_ <= kMaxRefusedAttempts &&
           !below_time_resolution_;
  }
  bool at_noise_floor() const { return noise_floor_; }
  // Whether the last refusal gave up because backward Euler's estimate did not fall.
  bool estimate_does_not_fall() const { return not_falling_; }
  // Whether the last refusal gave up because the step it planned is shorter than the time
  // resolves.
  bool below_time_resolution() const {
    return !noise_floor_ && !not_falling_ && below_time_resolution_;
  }
  // Why a driver stops below the time's resolution, for its failure message, with the
  // tolerance that runs past it (named_tolerance) where the last attempt had an estimate.
  std::string time_resolution_message() const {
    char buf[320];
    int n = std::snprintf(buf, sizeof buf,
                          "the step (%.3g) fell below what the time %.17g into the segment "
                          "resolves",
                          dt_, t_);
    if (shortest_.error > 0.0 && n > 0 && static_cast<std::size_t>(n) < sizeof buf) {
      std::snprintf(buf + n, sizeof buf - static_cast<std::size_t>(n),
                    "; the shortest step tried there (%.3g) estimates %.3g: use a tolerance of "
                    "at least %s",
                    shortest_.step, shortest_.error,
                    three_digits_at_least(shortest_.error).c_str());
    }
    return buf;
  }

  // Why a driver stops at the noise floor, for its failure message: the smallest tolerance at
  // or above the estimate's resolution in three digits. An attempt is refused at the floor only
  // when its estimate is above the tolerance and at most the resolution, so from that tolerance
  // on the floor no longer stops the run (where the resolution is the same along the path: the
  // contact point, a crystal under prescribed L; under mixed control it follows the stress).
  std::string noise_floor_message() const {
    char buf[400];
    std::snprintf(buf, sizeof buf,
                  "the local error estimate is at the round-off of what it compares (%.3g at "
                  "dt = %.3g): the tolerance %.3g is below what double precision resolves "
                  "here; use a tolerance of at least %s",
                  floor_.error, floor_.step, tolerance_,
                  three_digits_at_least(floor_.error).c_str());
    return buf;
  }
  // The tolerance the last give-up names, as a number, or NaN: the noise floor's
  // (noise_floor_message), or below the time's resolution the shortest attempt's estimate
  // (time_resolution_message), at which that attempt is accepted. A failure carries it, so that
  // a caller that can use any tolerance (a study's reference) runs at it.
  double named_tolerance() const {
    const double named = noise_floor_                                       ? floor_.error
                         : below_time_resolution() && shortest_.error > 0.0 ? shortest_.error
                                                                            : 0.0;
    return named > 0.0 ? std::strtod(three_digits_at_least(named).c_str(), nullptr)
                       : std::numeric_limits<double>::quiet_NaN();
  }
  // Why a driver stops where backward Euler's estimate does not fall (kFloorShrink).
  std::string not_falling_message() const {
    char buf[500];
    std::snprintf(buf, sizeof buf,
                  "backward Euler's local error estimate does not fall as the step shrinks "
                  "(%.3g at dt = %.3g, %.3g at dt = %.3g): the rates it compares are not "
                  "determined by the step's equations here; the extrapolated integrators' "
                  "estimate (`order: 2`, the default with a tolerance) compares states instead",
                  first_refused_.error, first_refused_.step, last_refused_.error,
                  last_refused_.step);
    return buf;
  }

 private:
  // `x` (> 0) in three significant digits, rounded up: the text read back is at least x.
  static std::string three_digits_at_least(double x) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.2e", x);
    for (double shown = std::strtod(buf, nullptr); shown < x; shown = std::strtod(buf, nullptr)) {
      // One unit of the last digit up, at the exponent of the text as printed.
      const int exponent = std::atoi(std::strchr(buf, 'e') + 1);
      std::snprintf(buf, sizeof buf, "%.2e", shown + std::pow(10.0, exponent - 2));
    }
    return buf;
  }

  // A step of the extrapolated integrators (EstimateNoise::backward_euler false) is one where it is
  // longer than kSameTime of the time it starts at: they divide it into up to 4 substeps whose ends
  // are times, and below that a substep's end rounds onto its start, a step of length zero that no
  // solve resolves. (kSameTime is also what makes a stop that close to a step's end that end, and
  // the fixed steps' rule.) Backward Euler's steps are not divided: for them a step is one that
  // moves the time at all.
  bool resolvable(double dt) const { return dt > kSameTime * std::abs(t_) && t_ + dt != t_; }
  // A time reaches a stop when it is at or past it, or short of it by round-off of the stop's
  // time (kSameTime).
  static bool reaches(double time, double stop) { return time >= stop * (1.0 - kSameTime); }
  // Where the step to the next stop ends: the stop, or the segment end when the stop is within
  // round-off of it (an output time an ulp short of the end, computed from another run's times,
  // would leave a last step of an ulp, which no solve resolves).
  double stop_time() const {
    const double stop = stops_[next_stop_];
    return reaches(stop, duration_) ? duration_ : std::min(stop, duration_);
  }

  double duration_;
  double dt_;
  double tolerance_;
  int order_;
  StepFactorLimits growth_;
  std::span<const double> stops_;
  std::size_t next_stop_ = 0;
  double t_ = 0.0;
  long accepted_ = 0;
  int refusals_ = 0;
  struct Attempt {
    double step = 0.0;
    double error = 0.0;
  };
  Attempt floor_;     // the attempt refused at the noise floor, with the resolution as its error
  Attempt shortest_;  // the last attempt before a step the time does not resolve
  // The first attempt rejected in a row, and the last one, where the estimate did not fall.
  Attempt first_refused_, last_refused_;
  bool noise_floor_ = false;
  bool not_falling_ = false;
  // The estimate of the refused attempt before (0: none, or it failed): where the resolution is
  // a bound (refuse's `flat_only`), the floor is an estimate that stopped falling.
  double refused_error_ = 0.0;
  double refused_step_ = 0.0;           // its step
  bool below_time_resolution_ = false;  // the last refusal gave up on the step's length
};

}  // namespace subslip::integrators
