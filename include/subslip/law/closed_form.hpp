#pragma once
// The law's closed-form step updates written once for a scalar (double) and for a batch of
// systems (an xsimd batch<double>): the friction coefficient after a slip (3.4 integrated at a
// constant rate), the cot subloading start and ratio after a slip (2.28) and the exponential
// overstress residual (3.15 inverted). The scalar law (subloading_friction.cpp) calls them with
// double and keeps its early returns; the crystal's batched flow points
// (src/crystal/flow_point_batch_kernels.hpp) call them with batches, where a branch becomes a
// select over both sides. Each formula is the same sequence of operations for both, so a batch lane
// rounds as the scalar law does wherever the libm functions and their vector counterparts agree.
//
// Unqualified calls (expm1, select, any, ...) resolve to std and the overloads below for double,
// and by argument-dependent lookup to xsimd for batches: this header needs no xsimd itself.

#include <array>
#include <cmath>
#include <numbers>
#include <type_traits>

#include "subslip/law/subloading_friction.hpp"

namespace subslip::law::closed_form {

using std::abs;
using std::asin;
using std::expm1;
using std::log1p;
using std::sqrt;
inline double select(bool condition, double if_true, double if_false) {
  return condition ? if_true : if_false;
}
inline bool any(bool condition) {
  return condition;
}
// A scalar of automatic differentiation (law/parameter_jet.hpp) branches as a double does.
template <class T>
T select(bool condition, const T& if_true, const T& if_false) {
  return condition ? if_true : if_false;
}

template <class V>
struct ValueAndSlopeOf {
  V value;
  V slope;
};

// (1 - e^{-b}) / b and its derivative, regular at b = 0. The series sum_k (-b)^k / (k+1)! to
// k = 9 has a truncation error below b^10/11! < 3e-20 for |b| < 1/16 (its slope: below 4e-18):
// below the rounding of the closed form, which also pays an expm1. Implicit steps evaluate mu
// for every system and trial slip, with b the slip of one small step times kappa/mu_k. Always
// inlined: GCC calls it out of line from the batched flow points, with its batches through
// memory (2 % of a grain step on the ExaCMech anchor's work, measured).
template <class V>
[[gnu::always_inline]] inline ValueAndSlopeOf<V> phi1(const V& b) {
  // Horner from the highest term: c_k = (-1)^k/(k+1)!, slope = sum k c_k b^(k-1).
  constexpr std::array<double, 10> c = {1.0,          -1.0 / 2,      1.0 / 6,    -1.0 / 24,
                                        1.0 / 120,    -1.0 / 720,    1.0 / 5040, -1.0 / 40320,
                                        1.0 / 362880, -1.0 / 3628800};
  V value(c[9]);
  V slope(9 * c[9]);
  for (int k = 8; k >= 0; --k) value = value * b + c[static_cast<size_t>(k)];
  for (int k = 8; k >= 1; --k) slope = slope * b + k * c[static_cast<size_t>(k)];
  const auto beyond_series = !(abs(b) < 0.0625);
  if (any(beyond_series)) {
    const V one_minus_exp = -expm1(-b);
    value = select(beyond_series, V(one_minus_exp / b), value);
    slope = select(beyond_series, V(((1.0 - one_minus_exp) * b - one_minus_exp) / (b * b)), slope);
  }
  return {value, slope};
}

// dmu/dt = a - b mu with a = kappa sdot + xi, b = kappa sdot/mu_k + xi/mu_s is linear in mu
// for a constant slip rate sdot = slip/dt, so the step has the exact solution
//   mu1 = mu0 + (A - B mu0) (1 - e^{-B}) / B,  A = a dt, B = b dt,
// which is unconditionally stable and never crosses mu_s or mu_k. At B = 0 (no slip and no
// recovery time) it gives mu0 and the slope kappa (1 - mu0/mu_k) exactly. F is
// FrictionCoefficientEvolution, or the same constants as automatic-differentiation scalars (and
// then dt may be one).
template <class V, class F, class D>
ValueAndSlopeOf<V> friction_coefficient_after(const F& f, const V& mu0, const V& slip,
                                              const D& dt) {
  // kappa/mu_k once: a product per system where a quotient would cost a division per system
  // (the batches' divisions set the flow points' throughput).
  const auto kappa_per_mu_k = f.kappa / f.mu_k;
  const V A = f.kappa * slip + f.xi * dt;
  const V B = kappa_per_mu_k * slip + f.xi * dt / f.mu_s;
  const V d_drive = f.kappa - kappa_per_mu_k * mu0;
  const ValueAndSlopeOf<V> ph = phi1(B);
  const V drive = A - B * mu0;
  return {mu0 + drive * ph.value, d_drive * ph.value + drive * ph.slope * kappa_per_mu_k};
}

// sin(x) for x in [0, pi/4] by its Taylor series to x^17 (Horner): the first term left out,
// x^19/19!, is below 9e-20 there, under the rounding of the sum (measured against libm: within
// 2.3e-16 relative). The batches' sine: xsimd's carries a non-template helper for large arguments
// (__ieee754_rem_pio2) that an unoptimised build emits as a weak function in every object
// compiled for a wide instruction set, where the linker could take it for every caller
// (tests/check_isa_objects.sh).
template <class V>
V sine_to_quarter_pi(const V& x) {
  // c_k = (-1)^k / (2k + 1)!, k = 0 ... 8.
  constexpr std::array<double, 9> c = {1.0,
                                       -1.0 / 6,
                                       1.0 / 120,
                                       -1.0 / 5040,
                                       1.0 / 362880,
                                       -1.0 / 39916800,
                                       1.0 / 6227020800.0,
                                       -1.0 / 1307674368000.0,
                                       1.0 / 355687428096000.0};
  const V x2 = x * x;
  V sum(c[8]);
  for (int k = 7; k >= 0; --k) sum = sum * x2 + c[static_cast<size_t>(k)];
  return x * sum;
}

// asin(h) for h in [0, 2^-1/2] (angles to pi/4) as h + h^3 P(h^2), P of degree 19 the
// Chebyshev fit of (asin(h)/h - 1)/h^2 over that range at 50 digits (scripts/fit_arcsine.py):
// within 0.75 ulp of asin there, its slope within 2e-15 relative (measured against 50-digit
// values). The batches' arcsine: xsimd's evaluates both of its branches, each a rational
// function, so two divisions and a square root per batch, where this takes twenty products
// (the divisions set the batched flow points' throughput).
template <class V>
V arcsine_to_quarter_pi(const V& h) {
  // Highest power first.
  constexpr std::array<double, 20> c = {
      1.0656658840535,      -4.201910132386749,    7.8829450923016555,   -9.158597380805825,
      7.358619925497615,    -4.297586832199172,    1.8963187485717359,   -0.6297138419141283,
      0.17101146220020227,  -0.025581324215004246, 0.013442391811587493, 0.00917160999006769,
      0.011603298700993395, 0.01396156950707128,   0.017352910485470593, 0.02237215476552006,
      0.03038194452250247,  0.04464285714211393,   0.0750000000000028,   0.16666666666666666};
  const V t = h * h;
  V p(c[0]);
  for (size_t k = 1; k < c.size(); ++k) p = p * t + c[k];
  return h + h * t * p;
}

// The cot subloading start from r0 in [0, 1]: cos(pi r0/2), 1 - cos(pi r0/2) and
// U(r0) = u cot(pi r0/2), from one sine taken where it keeps the digits: 1 - cos through
// sin(pi r0/4) for small r0, cos through the sine of the distance to 1 otherwise. U(r0) =
// u cos/sin needs no tangent; it is +inf at r0 = 0 (a virgin system).
template <class V>
struct CotStartOf {
  V cos0, one_minus_cos0, rate0;
};
template <class V, class U>
CotStartOf<V> cot_subloading_start(const U& u_tilde, const V& r0) {
  constexpr double kPi = std::numbers::pi;
  const auto small = r0 < 0.5;
  const V angle = select(small, V(0.25 * kPi * r0), V(0.5 * kPi * (1.0 - r0)));
  // The scalar law keeps libm's sine (its results as they were); a batch takes the series.
  V h;
  if constexpr (std::is_same_v<V, double>) {
    h = std::sin(angle);
  } else {
    h = sine_to_quarter_pi(angle);
  }
  const V twice_square = 2.0 * h * h;
  const V cos0 = select(small, V(1.0 - twice_square), h);
  const V one_minus_cos0 = select(small, twice_square, V(1.0 - h));
  const V sin0 = sqrt(one_minus_cos0 * (1.0 + cos0));
  return {cos0, one_minus_cos0, u_tilde * cos0 / sin0};
}

// The cot subloading ratio after a slip from a start (r0, cos(pi r0/2), 1 - cos(pi r0/2), U(r0)):
// x = cos(pi r1/2) = cos(pi r0/2) exp(-pi u s/2) (2.28), carried with 1 - x so that small r0
// and small s keep their digits (acos is ill-conditioned next to 1). r1 comes from the half
// angle, pi r1/4 = asin(((1 - x)/2)^(1/2)), whose argument stays within [0, 2^-1/2] where asin
// is well conditioned (x in [0, 1]): one formula over the whole range, no branch. The slope
// U(r1) = u cot(pi r1/2) = u x / sqrt((1 - x)(1 + x)) needs no further trigonometry. No slip,
// a saturated start or a ratio rounded below the start keep the start; r1 stops at 1.
template <class V, class U>
ValueAndSlopeOf<V> cot_subloading_ratio_after(const U& u_tilde, const V& r0, const V& cos0,
                                              const V& one_minus_cos0, const V& rate0,
                                              const V& slip) {
  constexpr double kPi = std::numbers::pi;
  const V a = 0.5 * kPi * u_tilde * slip;
  const V decay = expm1(-a);
  const V x = cos0 * (1.0 + decay);
  const V one_minus_x = one_minus_cos0 - cos0 * decay;
  const V half_angle_sine = sqrt(0.5 * one_minus_x);
  // The scalar law keeps libm's arcsine; a batch takes the fit (arcsine_to_quarter_pi).
  V r1;
  if constexpr (std::is_same_v<V, double>) {
    r1 = (4.0 / kPi) * asin(half_angle_sine);
  } else {
    r1 = (4.0 / kPi) * arcsine_to_quarter_pi(half_angle_sine);
  }
  const V slope = u_tilde * x / sqrt(one_minus_x * (1.0 + x));
  const auto keep_start = (slip <= 0.0) || (r0 >= 1.0) || (r1 <= r0);
  const auto saturated = r1 >= 1.0;
  return {select(keep_start, r0, select(saturated, V(1.0), r1)),
          select(keep_start, rate0, select(saturated, V(0.0), slope))};
}

// The exponential overstress residual G = (r - r_s) - g^-1(eta_v (r_hat - r) slip/dt),
// g^-1(y) = ln(1 + y)/n, with dG/dr and dG/d slip (dG/dr_s = -1). For r < r_hat. O is
// Overstress, or its constants as automatic-differentiation scalars (and then dt may be one).
template <class V>
struct ResidualOf {
  V value;
  V d_r;
  V d_slip;
};
template <class V, class O, class D>
ResidualOf<V> exponential_flow_residual(const O& o, const V& r, const V& r_s, const V& slip,
                                        const D& dt) {
  // 1/dt and 1/n once: products per system where quotients would cost a division per system.
  const auto per_dt = 1.0 / dt;
  const auto per_n = 1.0 / o.n;
  const V gap = o.r_hat - r;
  const V rate = slip * per_dt;
  const V y = o.eta_v * gap * rate;  // = g(r - r_s) on the solution
  const V inv = log1p(y) * per_n;
  const V d_inv_dy = per_n / (1.0 + y);
  const V dy_dr = -o.eta_v * rate;
  const V dy_dslip = o.eta_v * gap * per_dt;
  const V d_slip = -d_inv_dy * dy_dslip;
  const V d_r = 1.0 - select(y > 0.0, V(d_inv_dy * dy_dr), V(0.0));
  return {(r - r_s) - inv, d_r, d_slip};
}

}  // namespace subslip::law::closed_form
