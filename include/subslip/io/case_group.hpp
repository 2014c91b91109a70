// What the case writers of every scene kind write the same way into a case's group in /cases.
#pragma once

#include <span>
#include <string>
#include <string_view>

#include "subslip/driver/case_status.hpp"
#include "subslip/io/h5_writer.hpp"
#include "subslip/io/result_protocol.hpp"
#include "subslip/io/scene_common.hpp"
#include "subslip/io/sweep.hpp"

namespace subslip::io {

// The kind of scene a sweep path belongs to (the keys and their units differ).
enum class SceneKind { contact, crystal };

// The unit of the value a sweep path sets in a scene of `kind` written in `units` ("mm/min"
// for "loading[0].slide.speed", "1" for dimensionless numbers); empty for a value that is a
// name (`law.subloading.function`, `integrator.method`), which has none.
std::string sweep_unit(SceneKind kind, std::string_view path, const Units& units);

// Creates the group of case `name` in `cases` with the attributes every case group starts with:
// `name`, `index` (the case's place in the /cases `names` attribute) and one `sweep:<path>` per
// swept value (the number, or the value's text when it is not a number) with its unit in
// `sweep:<path>.unit` (sweep_unit; none for a name).
h5::Group create_case_group(const h5::Group& cases, const std::string& name, int index,
                            std::span<const SweepOverride> overrides, SceneKind kind,
                            const Units& units);

// An attribute with its unit in a sibling attribute "<name>.unit".
template <class Value>
void set_with_unit(const h5::Group& g, const std::string& name, const Value& value,
                   std::string_view unit) {
  g.set_attribute(name, value);
  g.set_attribute(name + ".unit", unit);
}

// What a case's /progress state tells the driver.
driver::CaseStatus case_status(h5::CaseState state);

}  // namespace subslip::io
