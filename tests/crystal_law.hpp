// Test helper: the slip-system laws of the crystal tests, from their constants.
#pragma once

#include "subslip/law/subloading_friction.hpp"

namespace subslip::testing {

// The cot subloading function and the exponential overstress, with the given constants.
inline law::LawParameters crystal_law(double mu_s, double mu_k, double kappa, double xi,
                                      double u_tilde, double eta_v, double n = 16.0,
                                      double r_hat = 1.8) {
  law::LawParameters p;
  p.friction = {mu_s, mu_k, kappa, xi};
  p.subloading = {law::SubloadingFunction::cot, u_tilde};
  p.overstress = {law::OverstressForm::exponential, eta_v, n, r_hat};
  return p;
}

}  // namespace subslip::testing
