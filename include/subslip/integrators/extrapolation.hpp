// Richardson extrapolation of backward Euler (the extrapolated implicit Euler method; Hairer &
// Wanner, Solving ODEs II, section IV.9).
//
// A step of length H is taken k times with backward Euler, the j-th time in j equal substeps
// (the harmonic sequence 1, 2, ..., k). Where the solution is smooth, the result of j substeps
// has an error expansion e1 H/j + e2 (H/j)^2 + ... with the same e1, e2, ... for every j, so the
// Aitken-Neville tableau
//   T[j][0] = y_j,  T[j][m] = T[j][m-1] + (T[j][m-1] - T[j-1][m-1]) / (n_j / n_{j-m} - 1)
// cancels the first m terms: T[k][k-1] is of order k. T[k][k-2] is of order k-1, so
// |T[k][k-1] - T[k][k-2]| estimates its local error, which falls as H^k; the step advances with
// the better T[k][k-1] (local extrapolation), which is what makes the global error proportional
// to the tolerance rather than to its square root.
//
// Stability: every entry is a linear combination of implicit Euler solutions with weights summing
// to 1, so for a linear problem y' = lambda y the amplification is a rational function that
// vanishes at lambda H = -infinity (each implicit Euler factor does): L-stable in that sense, and
// A-stable for k = 2 and 3 (A(89.8 deg) for k = 4; Hairer & Wanner, table IV.9.1). Any step is
// stable on the stiff relaxation of these laws.
#pragma once

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>

#include "subslip/integrators/step_control.hpp"

namespace subslip::integrators {

// The highest order offered: beyond 4 the tableau's weights grow (ill-conditioned in round-off)
// and A-stability is lost.
inline constexpr int kMaxExtrapolationOrder = 4;

template <class Vector>
struct Extrapolated {
  Vector best;    // T[k][k-1], order k
  Vector second;  // T[k][k-2], order k - 1: best - second estimates second's local error
};

// The combination's error on a step whose rate has a kink (starts or stops inside the step, as
// a crystal's slip system does where it switches between elastic and slipping) over backward
// Euler's one-step estimate dt/2 |rate(end) - rate(start)|, at most: for a rate that is zero on
// one side of the kink and linear on the other, wherever the kink falls in the step, the
// one-substep solution errs by up to twice that estimate, while the combination's weights
// cancel the kink's error to at most half of it for orders 2 and 3 (the largest with the kink
// at the step's middle) and to at most the estimate itself for order 4 (its weights are larger:
// -1/6, 4, -27/2, 32/3). Derived in Extrapolation.KinkBoundIsTheCombinationsLargestError.
constexpr double combination_kink_bound(int order) {
  return order >= 4 ? 1.0 : 0.5;
}

// `solutions[j]` is the result of j + 1 substeps, j = 0 .. order - 1 (order >= 2; the entries
// beyond are copied, not used: fill them with any value). Vector is any type with +, - and
// scalar *, / (an Eigen vector).
template <class Vector>
Extrapolated<Vector> extrapolate_implicit_euler(
    const std::array<Vector, kMaxExtrapolationOrder>& solutions, int order) {
  assert(order >= 2 && order <= kMaxExtrapolationOrder);
  std::array<Vector, kMaxExtrapolationOrder> row = solutions;  // row[j] = T[j][m]
  Vector second = row[static_cast<size_t>(order - 1)];
  for (int m = 1; m < order; ++m) {
    if (m == order - 1) second = row[static_cast<size_t>(order - 1)];
    // Bottom up, so that row[j - 1] still holds T[j-1][m-1] when T[j][m] is formed.
    for (int j = order - 1; j >= m; --j) {
      const auto uj = static_cast<size_t>(j);
      const double ratio = static_cast<double>(j + 1) / static_cast<double>(j + 1 - m);
      row[uj] = row[uj] + (row[uj] - row[uj - 1]) / (ratio - 1.0);
    }
  }
  return {row[static_cast<size_t>(order - 1)], second};
}

// The estimates |best - second| of the two columns before order 4's last (guarded_estimate):
// those of the order-3 and order-2 combinations of the same solutions, whose tableaus are the
// first rows of order 4's. Computed only where order 4 estimates its error.
template <class Vector>
std::array<Vector, 2> earlier_column_estimates(
    const std::array<Vector, kMaxExtrapolationOrder>& solutions) {
  const auto three = extrapolate_implicit_euler(solutions, 3);
  const auto two = extrapolate_implicit_euler(solutions, 2);
  return {three.best - three.second, two.best - two.second};
}

// The local error estimate of the order-k combination in some norm, from the norms of the last
// three column estimates (`last` = |best - second|, `previous` and `before`: those of
// earlier_column_estimates). In the asymptotic range the estimate of the order-m combination
// falls as H^(m+1), so the columns fall geometrically (by about the same factor C H each), and
// previous^2 / before is, like `last`, of order H^k. Outside it two columns can agree by accident:
// a step of the 200 mm/min friction fit across the onset of sliding (its viscoplastic rate rising
// 2000-fold inside the step) had column estimates 2.6e-2, 3.2e-3 and 6e-7 at order 4, an error
// of 2.3e-3 on the best solution, and was accepted at tolerance 1e-4. The estimate is the larger of
// `last` and its prediction from the two columns before, so that the last column falls no
// faster than the ones before it did. Only extrapolated columns count: backward Euler's own
// difference y_2 - y_1 carries the first-order term alone and falls to the next column by a
// factor unrelated to the later ones (with it as `before` at order 3 the friction fits took
// 12 times the steps at 1e-8, errors 0.04 times the tolerance). So the guard acts at order 4;
// with no such columns (orders 2 and 3), or where the earlier estimates vanish, it is `last`.
inline double guarded_estimate(double last, double previous, double before) {
  if (!(before > 0.0)) return last;
  return std::max(last, previous * (previous / before));
}

// The order of the adaptive integrator's error estimate (how it falls with the step, what the
// step control needs): k for the order-k extrapolation, 2 for backward Euler's own estimate
// (`order` 1: dt/2 |y'(end) - y'(start)|).
constexpr int estimate_order(int order) {
  return order >= 2 ? order : 2;
}

// How much the adaptive integrator's error estimate amplifies errors of the solutions that do
// not follow the expansion (round-off, Newton tolerances); the estimate cannot resolve less than
// that times those errors. Orders 2 ... 4: the sum of abs(weight of y_j in best - second), 2, 4
// and 9.3. Order 1, backward Euler's estimate dt/2 |y'(end) - y'(start)|: its rates are
// increments over their steps, so it carries half of the end state's error and half of the
// start's times this step over the last, at most 4 (the growth after an accepted step): 2.5.
inline double estimate_noise_gain(int order) {
  assert(order >= 1 && order <= kMaxExtrapolationOrder);
  if (order == 1) return 0.5 * (1.0 + kAfterAccepted.largest);
  using Scalar = std::array<double, 1>;
  struct One {  // a one-component vector for the tableau
    Scalar v{};
    One operator+(const One& o) const { return {{v[0] + o.v[0]}}; }
    One operator-(const One& o) const { return {{v[0] - o.v[0]}}; }
    One operator/(double d) const { return {{v[0] / d}}; }
  };
  double gain = 0.0;
  for (int i = 0; i < order; ++i) {
    std::array<One, kMaxExtrapolationOrder> unit{};
    unit[static_cast<size_t>(i)].v[0] = 1.0;
    const auto e = extrapolate_implicit_euler(unit, order);
    gain += std::abs(e.best.v[0] - e.second.v[0]);
  }
  return gain;
}

}  // namespace subslip::integrators
