// Step-size control shared by the adaptive drivers (contact point, crystal aggregate).
//
// Both implicit integrators are backward-Euler-like: the local error of a step of length dt is
// about dt^2/2 |y''|, estimated by dt/2 |y'(end) - y'(start)|. A step whose estimate exceeds the
// tolerance is redone shorter; an accepted step sets the next one. The factor is the classic
// 0.9 (tol/err)^(1/2) (error ~ dt^2), clamped so that one estimate never moves the step too far.
#pragma once

#include <algorithm>
#include <cmath>

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

// Consecutive refused attempts (rejected or failed) of one step before a driver gives up.
inline constexpr int kMaxRefusedAttempts = 200;

}  // namespace subslip::integrators
