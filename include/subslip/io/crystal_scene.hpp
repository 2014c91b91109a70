// Crystal scene files (`scene: crystal`): a crystal phase (slip systems, elasticity, the
// subloading-overstress law on every slip system), a set of grain orientations, and a loading
// history of velocity gradients under DAMASK-style mixed control, run as a Taylor aggregate.
// The format is documented in docs/scenes.md ("Crystal scenes"); this is its only parser, and
// what it makes is the run model of model/crystal_case.hpp.
#pragma once

#include <array>
#include <filesystem>
#include <string_view>

#include "subslip/driver/orientation_sharing.hpp"
#include "subslip/io/scene_common.hpp"
#include "subslip/io/sweep.hpp"
#include "subslip/io/yaml_checked.hpp"
#include "subslip/model/crystal_case.hpp"

namespace subslip::io {

using model::crystal_output_count;
using model::crystal_units;
using model::CrystalCase;
using model::CrystalOutputSelection;
using model::CrystalScene;
using model::GrainField;
using model::kAllGrainFields;
using model::kAllMacroFields;
using model::MacroField;
using model::OrientationBlock;
using model::OrientationDigest;
using model::orientations_digest;
using model::OrientationSource;
using model::to_string;

// Top-level keys a sweep may reach into.
inline constexpr std::array<std::string_view, 5> kCrystalSweepable = {
    "phase", "orientations", "loading", "integrator", "output"};

// Reads, sweeps and checks a crystal scene. Every problem is an InputError with file, line and
// key path. Orientation files are read relative to the scene file's directory.
CrystalScene load_crystal_scene(const std::filesystem::path& path);
CrystalScene parse_crystal_scene(const YamlDocument& document);

// The same for MPI ranks that will share the grains of each case: each keeps only its block of
// each case's orientations, an orientation file read by rank 0 alone (driver/
// orientation_sharing.hpp says how). Collective.
CrystalScene parse_crystal_scene(const YamlDocument& document,
                                 const driver::OrientationSharing& sharing);

}  // namespace subslip::io
