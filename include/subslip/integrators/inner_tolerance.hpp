// The flow-rule residual tolerance an adaptive run solves each step's equations to, tied to the
// tolerance asked of the run.
#pragma once

#include <algorithm>

namespace subslip::integrators {

// A step's error estimate resolves nothing below about 2.5 times the residual tolerance of the
// solves it compares (estimate_noise_gain in step_control.hpp), so a fixed residual tolerance
// would be a floor under every tolerance asked of the run: with 1e-12, a run at 1e-12 was
// refused as "below what double precision resolves" while the same run with its steps solved
// to 1e-15 ran. So a run at tolerance T solves its steps to at most T / kResidualPerTolerance,
// which keeps the estimate's noise 40 times below T. Above T = 1e-10 the default 1e-12 is the
// tighter one, and those runs are solved as before.
inline constexpr double kResidualPerTolerance = 100.0;

// The residual tolerance a run at `tolerance` (0: fixed increments) uses: `residual`, tightened
// to tolerance / kResidualPerTolerance where that is tighter and `follows` (the caller did not
// fix the residual tolerance itself).
inline double residual_tolerance_for(double residual, bool follows, double tolerance) {
  if (!follows || !(tolerance > 0.0)) return residual;
  return std::min(residual, tolerance / kResidualPerTolerance);
}

}  // namespace subslip::integrators
