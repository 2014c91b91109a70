// Step-size control shared by the adaptive drivers (contact point, crystal aggregate).
//
// Both implicit integrators are backward-Euler-like: the local error of a step of length dt is
// about dt^2/2 |y''|, estimated by dt/2 |y'(end) - y'(start)|. A step whose estimate exceeds the
// tolerance is redone shorter; an accepted step sets the next one. The factor is the classic
// 0.9 (tol/err)^(1/2) (error ~ dt^2), clamped so that one estimate never moves the step too far.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

namespace subslip::integrators {

// Limits of the factor for the next step after an accepted step, and for the retry of a
// refused one.
struct StepFactorLimits {
  double smallest;
  double largest;
};
inline constexpr StepFactorLimits kAfterAccepted{0.2, 4.0};
inline constexpr StepFactorLimits kAfterRejected{0.1, 0.9};

// The factor to scale the step by, given the local error estimate and the tolerance. A zero
// error estimate (nothing changes) grows the step by the largest factor.
inline double step_factor(double error, double tolerance, StepFactorLimits limits) {
  if (!(error > 0.0)) return limits.largest;
  return std::clamp(0.9 * std::sqrt(tolerance / error), limits.smallest, limits.largest);
}

// Whether a forward Euler step checks its stability limit (dt lambda <= 2) and is refused
// beyond it (the default: the drivers then cut it back), or is taken unchecked (for measuring
// where forward Euler goes unstable).
enum class ExplicitStability { refuse_unstable_steps, unchecked };

// Consecutive refused attempts (rejected or failed) of one step before a driver gives up.
inline constexpr int kMaxRefusedAttempts = 200;

// The noise floor of the error estimate. A true local error falls as dt^2, so after the step
// shrank by kFloorShrink over rejected attempts it should be 1e-6 of what it was; an estimate
// that has not even halved is round-off in the rates it compares (near r_hat, or at rates
// resolved no better than the Newton tolerance), and no shorter step will meet the tolerance.
inline constexpr double kFloorShrink = 1e3;

// The clock of one segment [0, duration] walked with adaptive steps: which step to try next,
// and how an accepted, rejected (error too large) or failed (no solution) attempt moves it. The
// last step ends exactly on the segment end.
class AdaptiveSegment {
 public:
  AdaptiveSegment(double duration, double first_step, double tolerance)
      : duration_(duration), dt_(first_step), tolerance_(tolerance) {}
  // Resuming a segment part-way (a restart): `time` into it, `accepted` steps taken, and the
  // step planned next.
  AdaptiveSegment(double duration, double next_step, double tolerance, double time, long accepted)
      : duration_(duration), dt_(next_step), tolerance_(tolerance), t_(time), accepted_(accepted) {}

  bool last() const { return dt_ >= duration_ - t_; }
  // The step to try now: the planned one, or what is left of the segment.
  double step() const { return last() ? duration_ - t_ : dt_; }
  // Time into the segment at the end of the step tried now.
  double end_time() const { return last() ? duration_ : t_ + dt_; }
  double time() const { return t_; }
  // The step planned after the last accepted one (what a checkpoint records to resume with).
  double planned_step() const { return dt_; }
  long accepted() const { return accepted_; }
  int refusals() const { return refusals_; }

  void accept(double error) {
    const double h = step();
    t_ = end_time();
    ++accepted_;
    refusals_ = 0;
    dt_ = h * step_factor(error, tolerance_, kAfterAccepted);
  }
  // A refused attempt shortens the step: by the error estimate when it was too large, by half
  // when the step failed outright. False when the driver should give up: too many refusals in
  // a row, or a step too short to advance the time.
  // Also false at the estimate's noise floor (see kFloorShrink; then at_noise_floor()).
  bool refuse(bool failed, double error) {
    const double h = step();
    if (failed) {
      floor_start_ = {};  // a failed attempt has no estimate: start again after it
    } else if (refusals_ == 0 || floor_start_.error == 0.0) {
      floor_start_ = {h, error};
    }
    dt_ = failed ? 0.5 * h : h * step_factor(error, tolerance_, kAfterRejected);
    ++refusals_;
    noise_floor_ = !failed && floor_start_.error > 0.0 && h <= floor_start_.step / kFloorShrink &&
                   error >= 0.5 * floor_start_.error;
    if (noise_floor_) floor_end_ = {h, error};
    return !noise_floor_ && refusals_ <= kMaxRefusedAttempts && dt_ > 0.0 && t_ + dt_ != t_;
  }
  bool at_noise_floor() const { return noise_floor_; }
  // Why a driver stops at the noise floor, for its failure message.
  std::string noise_floor_message() const {
    char buf[320];
    std::snprintf(buf, sizeof buf,
                  "the local error estimate no longer falls as the step shrinks (%.3g at dt = "
                  "%.3g, %.3g at dt = %.3g): the tolerance %.3g is below what double precision "
                  "resolves here; use a tolerance above %.3g",
                  floor_start_.error, floor_start_.step, floor_end_.error, floor_end_.step,
                  tolerance_, std::max(floor_start_.error, floor_end_.error));
    return buf;
  }

 private:
  double duration_;
  double dt_;
  double tolerance_;
  double t_ = 0.0;
  long accepted_ = 0;
  int refusals_ = 0;
  struct Attempt {
    double step = 0.0;
    double error = 0.0;
  };
  Attempt floor_start_, floor_end_;  // the first rejected attempt in a row, and the last
  bool noise_floor_ = false;
};

}  // namespace subslip::integrators
