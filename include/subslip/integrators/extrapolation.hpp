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

#include <array>
#include <cassert>
#include <cmath>

namespace subslip::integrators {

// The highest order offered: beyond 4 the tableau's weights grow (ill-conditioned in round-off)
// and A-stability is lost.
inline constexpr int kMaxExtrapolationOrder = 4;

template <class Vector>
struct Extrapolated {
  Vector best;    // T[k][k-1], order k
  Vector second;  // T[k][k-2], order k - 1: best - second estimates second's local error
};

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

// The order of the adaptive integrator's error estimate (how it falls with the step, what the
// step control needs): k for the order-k extrapolation, 2 for backward Euler's own estimate
// (`order` 1: dt/2 |y'(end) - y'(start)|).
constexpr int estimate_order(int order) {
  return order >= 2 ? order : 2;
}

// How much the estimate best - second amplifies errors of the solutions that do not follow the
// expansion (round-off, Newton tolerances): the sum of abs(weight of y_j in best - second), 2, 4
// and 9.3 for orders 2, 3 and 4. The estimate cannot resolve less than that times those errors.
inline double estimate_noise_gain(int order) {
  assert(order >= 2 && order <= kMaxExtrapolationOrder);
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
