// Parameter sweeps on the YAML tree, shared by every scene kind.
//
// A scene may carry
//
//   sweep:
//     "loading[0].slide.speed": [1, 10, 100]
//     "law.overstress.eta_v": [950, 1900]
//
// and then stands for one case per element of the cartesian product (the first key varies
// slowest). Each case is the scene's YAML tree with the listed nodes replaced by the case's
// values BEFORE the scene is parsed, so any value can be swept and every swept value goes
// through the same checks as a written one (an error in a swept value points at its line in
// the sweep block). Paths: `.key` steps into a mapping, `[i]` into a sequence element and `[*]`
// into every element of a sequence. A path must name a node that exists in the scene.
#pragma once

#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "subslip/io/yaml_checked.hpp"
#include "subslip/model/case_common.hpp"

namespace subslip::io {

using model::SweepOverride;

struct SweepCase {
  std::string name;  // "speed=10,eta_v=950": each path from its last key on ("L[0][1]=10"
                     // for "loading[0].L[0][1]"), the full path when two paths share that;
                     // "base" when the scene has no sweep
  std::vector<SweepOverride> overrides;
  YamlDocument document;  // the scene with this case's values in place
};

// Expands the `sweep:` block of `scene` (no block: one case, "base"). Only paths whose first
// key is in `sweepable` may be swept (e.g. not `units`). Throws InputError for a malformed or
// missing path, an empty value list, or two cases with the same name.
std::vector<SweepCase> expand_sweep(const YamlDocument& scene,
                                    std::span<const std::string_view> sweepable);

namespace detail {

bool same_input_error(const InputError& a, const InputError& b);

}  // namespace detail

// Parses every case of a scene's sweep with `parse_case(SweepCase)`. An error that depends on
// the case says which case it is in; one that every case has alike (a written value no swept
// value touches) is reported as it is, without a case.
template <class Parse>
auto parse_sweep_cases(const YamlDocument& scene, std::span<const std::string_view> sweepable,
                       Parse&& parse_case) {
  std::vector<decltype(parse_case(std::declval<SweepCase>()))> cases;
  const std::vector<SweepCase> expanded = expand_sweep(scene, sweepable);
  // Whether every case fails with `error` (only asked once a case has failed).
  const auto every_case_fails_alike = [&](const InputError& error) {
    for (const SweepCase& other : expanded) {
      try {
        parse_case(SweepCase(other));
        return false;
      } catch (const InputError& e) {
        if (!detail::same_input_error(e, error)) return false;
      }
    }
    return true;
  };
  for (const SweepCase& swept : expanded) {
    try {
      cases.push_back(parse_case(SweepCase(swept)));
    } catch (const InputError& e) {
      if (swept.overrides.empty() || every_case_fails_alike(e)) throw;
      throw InputError(e.file, e.line, e.key,
                       e.message + " (in sweep case '" + swept.name + "')");
    }
  }
  return cases;
}

}  // namespace subslip::io
