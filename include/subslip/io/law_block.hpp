// The `law:` block of a scene (friction, subloading, overstress), shared by every scene kind.
#pragma once

#include <string>

#include "subslip/io/scene_common.hpp"
#include "subslip/io/yaml_checked.hpp"
#include "subslip/law/parameter_table.hpp"
#include "subslip/law/subloading_friction.hpp"

namespace subslip::io {

// The units of the law's dimensional constants. The slip measure is a length for a contact
// (kappa and u_tilde per length, eta_v time per length) and dimensionless for slip systems
// (kappa and u_tilde per unit slip, eta_v a time); xi is per time in both.
struct LawUnits {
  Unit per_slip;       // kappa, u_tilde
  Unit per_time;       // xi
  Unit time_per_slip;  // eta_v
};
LawUnits contact_law_units(const Units& units);
LawUnits crystal_law_units(const Units& units);

// The unit a law constant of unit kind `kind` is read in, and the range its bound admits
// (law/parameter_table.hpp): what the scene parsers and the fit file's bounds check.
const Unit& law_constant_unit(const LawUnits& units, law::ParameterUnit kind);
Range law_constant_range(law::ParameterBound bound);

// The unit of a law constant of unit kind `kind` (law/parameter_table.hpp) as a result file
// writes it: "1/mm", "min/mm" for a contact; "1", "s" for slip systems (`crystal`).
std::string law_unit_name(law::ParameterUnit kind, bool crystal, const Units& units);

// Reads a law block over `base`, each constant in `units` (a value written with a unit is
// converted). A complete block (partial == false: a contact law or a phase
// law) must give every key; a partial one (per-family overrides) replaces only the keys it gives
// and inherits the rest from `base`.
law::LawParameters parse_law_block(const CheckedNode& node, const LawUnits& units,
                                   law::LawParameters base = {}, bool partial = false);

}  // namespace subslip::io
