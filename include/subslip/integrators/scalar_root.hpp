// A safeguarded Newton iteration for one monotone scalar equation on a bracket.
//
// Why not a library root finder: the callers need the iteration count (reported per step), a
// result that never leaves the bracket, and failure reported as a value (so a step can be cut
// back) rather than an exception. The method is the classic one (Newton inside the bracket,
// bisection whenever Newton would leave it or stalls), so it always converges for a continuous
// function that changes sign on the bracket.
#pragma once

#include <cmath>
#include <limits>
#include <utility>

namespace subslip {

struct ScalarRoot {
  double x;  // the root (the bracket end on the negative side when it collapses)
  int iterations;
  bool converged;
  // Converged with |F| <= f_tol (not only to what double precision resolves in x).
  bool within_tolerance = false;
};

// Solves F(x) = 0 for x in [lo, hi] where F(lo) >= 0 >= F(hi) or F(lo) <= 0 <= F(hi).
// `eval(x)` returns std::pair{F(x), dF/dx(x)}; F may be +/-infinity outside its domain
// (the side is then known from the sign). Converges when |F| <= f_tol or the bracket is
// narrower than x_tol * max(|x|, x_floor).
template <class Eval>
ScalarRoot safeguarded_newton(Eval&& eval, double lo, double hi, double guess, double f_tol,
                              double x_tol, double x_floor, int max_iterations = 200) {
  const double f_lo = eval(lo).first;
  if (f_lo == 0.0) return {lo, 0, true, true};
  const bool increasing = f_lo < 0.0;  // sign convention of the bracket
  double x = (guess > lo && guess < hi) ? guess : 0.5 * (lo + hi);
  double previous_abs_f = std::numeric_limits<double>::infinity();
  for (int it = 1; it <= max_iterations; ++it) {
    auto [f, df] = eval(x);
    // Converged when |F| is within tolerance or within what double precision can resolve at x
    // (F changes by |dF/dx| ulp(x) between neighbouring doubles: very steep F stop there). An
    // infinite slope (an overflowed derivative, e.g. the power overstress at a slip of 1e-319)
    // says nothing about the resolution and must not declare convergence.
    const double resolution =
        std::isfinite(df)
            ? 4.0 * std::abs(df) * std::numeric_limits<double>::epsilon() * std::abs(x)
            : 0.0;
    if (std::isfinite(f) && std::abs(f) <= std::max(f_tol, resolution))
      return {x, it, true, std::abs(f) <= f_tol};
    // Shrink the bracket with the sign of F at x.
    if ((f < 0.0) == increasing) {
      lo = x;
    } else {
      hi = x;
    }
    if (hi - lo <= x_tol * std::max(std::abs(x), x_floor)) {
      return {increasing ? lo : hi, it, true};
    }
    double next = 0.5 * (lo + hi);
    // Newton only while it makes real progress; otherwise bisect (guards against slow
    // one-sided creep toward a steep root).
    const bool progressing = std::abs(f) < 0.5 * previous_abs_f;
    if (std::isfinite(f) && std::isfinite(df) && df != 0.0 && progressing) {
      const double newton = x - f / df;
      if (newton > lo && newton < hi) next = newton;
    }
    previous_abs_f = std::isfinite(f) ? std::abs(f) : previous_abs_f;
    x = next;
  }
  return {x, max_iterations, false};
}

}  // namespace subslip
