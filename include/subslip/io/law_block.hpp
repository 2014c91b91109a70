// The `law:` block of a scene (friction, subloading, overstress), shared by every scene kind.
#pragma once

#include "subslip/io/yaml_checked.hpp"
#include "subslip/law/subloading_friction.hpp"

namespace subslip::io {

// Reads a law block over `base`. A complete block (partial == false: a contact law or a phase
// law) must give every key; a partial one (per-family overrides) replaces only the keys it gives
// and inherits the rest from `base`.
law::LawParameters parse_law_block(const CheckedNode& node, law::LawParameters base = {},
                                   bool partial = false);

}  // namespace subslip::io
