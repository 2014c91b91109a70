// Test helper: the FCC copper phase several crystal tests share (cubic elasticity C11, C12,
// C44 = 168400, 121400, 75400 MPa; {111}<110>; a hardening law with the exponential overstress).
#pragma once

#include "subslip/crystal/elasticity.hpp"
#include "subslip/crystal/phase_builder.hpp"

namespace subslip::testing {

// tau0 [MPa] sets the stiffness ratio: C44/tau0 = 3770 at 20 MPa, 1e5 at 0.754 MPa.
inline crystal::PhaseDescription copper_phase(double tau0) {
  law::LawParameters p;
  p.friction = {1.0, 1.5, 2.0, 0.0};
  p.subloading = {law::SubloadingFunction::cot, 300.0};
  p.overstress = {law::OverstressForm::exponential, 0.05, 16.0, 1.8};
  crystal::PhaseDescription d;
  d.families = {crystal::SlipFamily::fcc_111_110};
  d.family_settings = {{p, tau0, 0.0}};
  d.stiffness = crystal::cubic_stiffness(168400.0, 121400.0, 75400.0);
  return d;
}

}  // namespace subslip::testing
