// Test helper: the friction law of the paper's section 5 fit (figure 11a), in MPa, mm, min.
#pragma once

#include "subslip/law/subloading_friction.hpp"

namespace subslip::testing {

// mu_s 0.097, mu_k 0.085, kappa 0.2 /mm, xi 0.009 /min, u_tilde 80 /mm, eta_v 950 min/mm, n 16,
// r_hat 1.8; with the exponential overstress and the cot subloading function unless told.
inline law::LawParameters paper_law(
    law::OverstressForm form = law::OverstressForm::exponential,
    law::SubloadingFunction function = law::SubloadingFunction::cot) {
  law::LawParameters p;
  p.friction = {0.097, 0.085, 0.2, 0.009};
  p.subloading = {function, 80.0};
  p.overstress = {form, 950.0, 16.0, 1.8};
  return p;
}

}  // namespace subslip::testing
