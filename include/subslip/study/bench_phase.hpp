// The phases of the speed and robustness measurements of the crystal kernel (`subslip bench` and
// bench/robustness_grid.cpp): one law and one set of elastic constants per lattice, so
// that both measure the same material.
#pragma once

#include <string>
#include <vector>

#include "subslip/crystal/phase_builder.hpp"

namespace subslip::study {

// The lattice names bench_phase knows, in report order: fcc, bcc48, hcp.
const std::vector<std::string>& bench_lattices();

// FCC {111}<110> (12 systems), BCC {110}+{112}+{123}<111> (48) or HCP basal, prismatic,
// pyramidal <a> and pyramidal <c+a> (24), with room-temperature elastic constants [MPa] of
// copper, alpha iron and alpha titanium and the same hardening law on every system. Throws
// std::invalid_argument for a name not in bench_lattices().
crystal::PhaseDescription bench_phase(const std::string& lattice);

}  // namespace subslip::study
