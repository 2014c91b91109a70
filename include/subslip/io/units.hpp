// The units of the run model (model/units.hpp) under the names the parsers and writers use.
#pragma once

#include "subslip/model/units.hpp"

namespace subslip::io {

namespace dimension = model::dimension;
using model::base_unit;
using model::convert;
using model::describe;
using model::Dimension;
using model::kDimensionless;
using model::length_unit_names;
using model::parse_unit;
using model::Scale;
using model::stress_unit_names;
using model::supported_units;
using model::time_unit_names;
using model::to_si;
using model::Unit;
using model::unit_names_of;
using model::Units;
using model::units_for;

}  // namespace subslip::io
