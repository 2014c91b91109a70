// Contact scene files (`scene: contact`): one frictional contact point driven through a
// prescribed sliding history, possibly swept over parameters. The format is documented in
// docs/scenes.md; this is its only parser, and what it makes is the run model of
// model/contact_case.hpp.
#pragma once

#include <array>
#include <filesystem>
#include <string_view>

#include "subslip/io/scene_common.hpp"
#include "subslip/io/sweep.hpp"
#include "subslip/io/yaml_checked.hpp"
#include "subslip/model/contact_case.hpp"

namespace subslip::io {

using model::ContactCase;
using model::ContactField;
using model::ContactScene;
using model::kAllContactFields;
using model::last_sliding_speed;
using model::output_count;
using model::to_string;

// Top-level keys a sweep may reach into.
inline constexpr std::array<std::string_view, 6> kContactSweepable = {
    "law", "contact", "initial", "loading", "integrator", "output"};

// Reads, sweeps and checks a contact scene. Every problem is an InputError with file, line and
// key path.
ContactScene load_contact_scene(const std::filesystem::path& path);
ContactScene parse_contact_scene(const YamlDocument& document);

}  // namespace subslip::io
