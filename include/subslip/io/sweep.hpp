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
                     // for "loading[0].L[0][1]"), the full path when two paths share that,
                     // each value as written ("speed=1 mm/min"); "base" when the scene has no
                     // sweep. The result file stores it under case_group_name(name).
  std::vector<SweepOverride> overrides;
  YamlDocument document;  // the scene with this case's values in place
};

// The name of a case's group in a result file: its name with each '/' (which HDF5 takes for a
// path separator) written '_' ("speed=1 mm/min" is stored as "speed=1 mm_min"); the group's
// `name` attribute keeps the name itself.
std::string case_group_name(std::string name);

// Expands the `sweep:` block of `scene` (no block: one case, "base"). Only paths whose first
// key is in `sweepable` may be swept (e.g. not `units`). Throws InputError for a malformed or
// missing path, an empty value list, or two cases with the same name or group name.
std::vector<SweepCase> expand_sweep(const YamlDocument& scene,
                                    std::span<const std::string_view> sweepable);

namespace detail {

// One step of a path into the YAML tree: `.key`, `[i]` or `[*]`.
struct PathStep {
  enum class Kind { key, index, all } kind;
  std::string key;
  std::size_t index = 0;
};

// "loading[0].slide.speed" -> key loading, index 0, key slide, key speed. A malformed path is
// an error at `at`, naming it a `what` path ("sweep", "--set").
std::vector<PathStep> parse_path(const std::string& path, const CheckedNode& at,
                                 std::string_view what);

// Throws the errors of a sweep's cases (errors[k]: those of case k, in the order found), each
// once: an error every case has alike (a written value no swept value touches) as it is, one
// that depends on the case naming the cases it is in.
[[noreturn]] void throw_case_errors(const std::vector<SweepCase>& cases,
                                    const std::vector<std::vector<InputError>>& errors,
                                    bool stopped);

}  // namespace detail

// Parses every case of a scene's sweep with `parse_case(SweepCase)`, and reports the errors of
// all of them together (detail::throw_case_errors).
template <class Parse>
auto parse_sweep_cases(const YamlDocument& scene, std::span<const std::string_view> sweepable,
                       Parse&& parse_case) {
  std::vector<decltype(parse_case(std::declval<SweepCase>()))> cases;
  const std::vector<SweepCase> expanded = expand_sweep(scene, sweepable);
  std::vector<std::vector<InputError>> errors(expanded.size());
  bool failed = false;
  bool stopped = false;
  for (std::size_t k = 0; k < expanded.size(); ++k) {
    try {
      cases.push_back(parse_case(SweepCase(expanded[k])));
    } catch (const InputErrors& e) {
      errors[k] = e.all;
      stopped = stopped || e.stopped;
      failed = true;
    } catch (const InputError& e) {
      errors[k] = {e};
      failed = true;
    }
  }
  if (failed) detail::throw_case_errors(expanded, errors, stopped);
  return cases;
}

}  // namespace subslip::io
