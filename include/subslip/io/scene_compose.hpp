// A scene made of others: a base scene it names, and settings from the command line.
//
//   base: copper_tension.yaml       # relative to the file that names it
//   loading:
//     - {L: [[x, 0, 0], [0, x, 0], [0, 0, -1.0e-3]], stress: ..., duration: 20, increments: 200}
//
//   subslip run compression.yaml --set phase.tau0=12 --set "loading[0].increments=400"
//
// The scene is its base with the scene's own keys over it, merged key by key: a mapping
// present in both is merged again, anything else (a number, a list) is the scene's. A base may
// name a base of its own. The settings then replace (or add) the value at each PATH, in order,
// before the sweep expands. Every part is checked as any key is: an error names the file and
// line it was written at, or the `--set` argument. What a run was made of is stored in its
// result file (io/result_protocol.hpp) and used again by `--restart`.
#pragma once

#include <string>
#include <vector>

#include "subslip/io/yaml_checked.hpp"
#include "subslip/model/case_common.hpp"

namespace subslip::io {

// The sources of `scene`: the scene, the base files it names one after another (read from the
// disk; a missing or unreadable file, or a base that names itself again, is an error at the
// `base:` key that names it), and `settings` ("PATH=VALUE").
SceneSources read_scene_sources(const YamlDocument& scene, std::vector<std::string> settings);

// The scene `scene` and `settings` make (read_scene_sources, then YamlDocument::compose).
YamlDocument compose_scene(const YamlDocument& scene, std::vector<std::string> settings = {});

// The bases and settings of `document`, as the run model records them.
model::SceneMakeup makeup_of(const YamlDocument& document);

}  // namespace subslip::io
