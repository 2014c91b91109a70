// What the case writers of every scene kind write the same way into a case's group in /cases.
#pragma once

#include <span>
#include <string>
#include <string_view>

#include "subslip/io/h5_writer.hpp"
#include "subslip/io/sweep.hpp"

namespace subslip::io {

// Creates the group of case `name` in `cases` with the attributes every case group starts with:
// `name`, `index` (the case's place in the /cases `names` attribute) and one `sweep:<path>` per
// swept value (the number, or the value's text when it is not a number).
h5::Group create_case_group(const h5::Group& cases, const std::string& name, int index,
                            std::span<const SweepOverride> overrides);

// An attribute with its unit in a sibling attribute "<name>.unit".
template <class Value>
void set_with_unit(const h5::Group& g, const std::string& name, const Value& value,
                   std::string_view unit) {
  g.set_attribute(name, value);
  g.set_attribute(name + ".unit", unit);
}

}  // namespace subslip::io
