#include "subslip/study/bench_phase.hpp"

#include <stdexcept>

#include "subslip/crystal/elasticity.hpp"

namespace subslip::study {

using namespace subslip::crystal;

const std::vector<std::string>& bench_lattices() {
  static const std::vector<std::string> names{"fcc", "bcc48", "hcp"};
  return names;
}

// Room-temperature constants [MPa]: copper (Simmons & Wang), alpha iron, alpha titanium.
PhaseDescription bench_phase(const std::string& lattice) {
  PhaseDescription d;
  SlipGroupSettings g;
  g.tau0 = 10.0;
  g.law.friction = {1.0, 3.0, 5.0, 0.0};  // hardening from tau0 toward 3 tau0 by slip
  g.law.subloading = {law::SubloadingFunction::cot, 200.0};
  g.law.overstress = {law::OverstressForm::exponential, 1.0e-3, 16.0, 1.6};
  if (lattice == "fcc") {
    d.families = {SlipFamily::fcc_111_110};
    d.stiffness = cubic_stiffness(168400, 121400, 75400);
  } else if (lattice == "bcc48") {
    d.families = {SlipFamily::bcc_110_111, SlipFamily::bcc_112_111, SlipFamily::bcc_123_111};
    d.stiffness = cubic_stiffness(231400, 134700, 116400);
  } else if (lattice == "hcp") {
    d.families = {SlipFamily::hcp_basal_a, SlipFamily::hcp_prismatic_a, SlipFamily::hcp_pyramidal_a,
                  SlipFamily::hcp_pyramidal_ca};
    d.c_over_a = 1.587;
    d.stiffness = hexagonal_stiffness(162400, 92000, 69000, 180700, 46700);
  } else {
    throw std::invalid_argument("bench: unknown lattice '" + lattice + "' (fcc, bcc48, hcp)");
  }
  d.family_settings.assign(d.families.size(), g);
  return d;
}

}  // namespace subslip::study
