// The lowest loading ratio on a step's straight traction path, for the implicit update and its
// sensitivities (contact_point.cpp, contact_sensitivity.cpp): one formula for double and for
// the automatic-differentiation scalar, so that the two follow the same path.
#pragma once

#include <Eigen/Core>
#include <limits>

namespace subslip::contact::detail {

// The lowest loading ratio r = |f_t|/(f_n mu) on the straight traction path of a step, from
// (f0, fn0) at its start to (f1, fn1) at its end; mu_at(l) is mu at the path parameter l. Where
// r < r_s on that path no viscoplastic sliding occurs and (3.12) makes r_s follow r down, so a
// step whose path passes near zero traction (a reversal) must start r_s from this minimum,
// not from r_s0. |f|^2/fn^2 = (a + 2bl + cl^2)/(p + ql)^2 has one stationary point, where
// (cp - bq) l = qa - bp, a minimum when cp - bq > 0; otherwise the minimum is at an end,
// which the callers already cover (r_s0 <= r0, and r_s <= r at the end). mu only scales the
// ratio and changes little over a step, so it is evaluated at that point.
template <class T>
struct PathMinimum {
  T ratio = T(std::numeric_limits<double>::infinity());
  T at = T(0.0);  // path parameter in [0, 1]
};
template <class T, class MuAt>
PathMinimum<T> lowest_ratio_on_path(const Eigen::Matrix<T, 2, 1>& f0, double fn0,
                                    const Eigen::Matrix<T, 2, 1>& f1, double fn1, MuAt&& mu_at) {
  using Vec = Eigen::Matrix<T, 2, 1>;
  if (!(fn0 > 0.0) || !(fn1 > 0.0)) return {};
  const Vec df = f1 - f0;
  const T a = f0.squaredNorm(), b = f0.dot(df), c = df.squaredNorm();
  const double p = fn0, q = fn1 - fn0;
  const T den = c * p - b * q;
  if (!(den > 0.0)) return {};
  // Clamped to [0, 1] (as std::clamp, which takes one type).
  T l = (q * a - b * p) / den;
  if (l < 0.0) {
    l = T(0.0);
  } else if (l > 1.0) {
    l = T(1.0);
  }
  return {(f0 + l * df).norm() / ((p + l * q) * mu_at(l)), l};
}

}  // namespace subslip::contact::detail
