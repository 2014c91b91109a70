// Reading PROPS: each entry checked by its 1-based index and name, and the law's ten entries
// (mu_s, mu_k, kappa, xi, U function, u_tilde, overstress form, eta_v, n, r_hat) that UMAT and
// FRIC both give in this order.
#pragma once

#include <cmath>
#include <stdexcept>
#include <string>

#include "subslip/law/subloading_friction.hpp"

namespace subslip::fe {

inline std::string prop_name(int index, const char* name) {
  return "PROPS(" + std::to_string(index) + ") (" + name + ")";
}

inline double prop(const double* props, int index, const char* name) {
  const double v = props[index - 1];
  if (!std::isfinite(v)) throw std::invalid_argument(prop_name(index, name) + " is not finite");
  return v;
}

// An integer code in [lo, hi].
inline int prop_code(const double* props, int index, const char* name, int lo, int hi) {
  const double v = prop(props, index, name);
  if (v != std::round(v) || v < lo || v > hi)
    throw std::invalid_argument(prop_name(index, name) + " must be an integer from " +
                                std::to_string(lo) + " to " + std::to_string(hi) + ", got " +
                                std::to_string(v));
  return static_cast<int>(v);
}

// The law from PROPS(first) .. PROPS(first + 9); its values are checked by the point made
// from it (the law's own messages name the parameter).
inline law::LawParameters law_props(const double* p, int first) {
  namespace lw = subslip::law;
  static constexpr lw::SubloadingFunction kFunctions[] = {lw::SubloadingFunction::cot,
                                                          lw::SubloadingFunction::neg_log,
                                                          lw::SubloadingFunction::reciprocal};
  static constexpr lw::OverstressForm kForms[] = {lw::OverstressForm::exponential,
                                                  lw::OverstressForm::power,
                                                  lw::OverstressForm::rate_independent};
  lw::LawParameters law;
  law.friction = {prop(p, first, "mu_s"), prop(p, first + 1, "mu_k"), prop(p, first + 2, "kappa"),
                  prop(p, first + 3, "xi")};
  law.subloading = {kFunctions[prop_code(p, first + 4, "U function", 1, 3) - 1],
                    prop(p, first + 5, "u_tilde")};
  law.overstress = {kForms[prop_code(p, first + 6, "overstress form", 1, 3) - 1],
                    prop(p, first + 7, "eta_v"), prop(p, first + 8, "n"),
                    prop(p, first + 9, "r_hat")};
  return law;
}

}  // namespace subslip::fe
