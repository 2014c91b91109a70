// Whether a grain state lies in the law's admissible set: what the robustness grid checks of
// every state it commits, and the material-point API offers its callers.
#pragma once

#include <cmath>
#include <iomanip>
#include <sstream>
#include <string>

#include "subslip/crystal/crystal_kernel.hpp"

namespace subslip::crystal {

// The first admissibility violation of a grain state, e.g. "system 7: r_s > r (r = ..., r_s =
// ...)"; empty when it is admissible: finite (stress, orientation, mu, r_s, slip, rate) and
// 0 <= r_s <= r < r_hat on every slip system, r = loading_ratio (r < r_hat only for the
// rate-dependent forms: the rate-independent one has no overstress).
template <int N>
std::string admissibility_violation(const Phase<N>& ph, const GrainState<N>& s) {
  if (!(s.stress.allFinite() && s.orientation.allFinite() && s.mu.allFinite() &&
        s.r_s.allFinite() && s.slip.allFinite() && s.rate.allFinite()))
    return "non-finite state";
  const auto r = loading_ratio(ph, s);
  for (int a = 0; a < ph.slip_count; ++a) {
    const law::Overstress& o = ph.laws[static_cast<std::size_t>(a)].parameters().overstress;
    const bool bounded = o.form != law::OverstressForm::rate_independent;
    const char* what = !std::isfinite(r(a))           ? "r non-finite"
                       : !(s.r_s(a) >= 0.0)           ? "r_s < 0"
                       : !(s.r_s(a) <= r(a))          ? "r_s > r"
                       : bounded && !(r(a) < o.r_hat) ? "r >= r_hat"
                                                      : nullptr;
    if (what) {
      std::ostringstream text;
      text << "system " << a << ": " << what << " (r = " << std::setprecision(17) << r(a)
           << ", r_s = " << s.r_s(a) << ")";
      return text.str();
    }
  }
  return {};
}

}  // namespace subslip::crystal
