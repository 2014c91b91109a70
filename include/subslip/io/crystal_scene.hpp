// Crystal scene files (`scene: crystal`): a crystal phase (slip systems, elasticity, the
// subloading-overstress law on every slip system), a set of grain orientations, and a loading
// history of velocity gradients under DAMASK-style mixed control, run as a Taylor aggregate.
// The format is documented in docs/scenes.md ("Crystal scenes"); this is its only parser, and
// what it makes is the run model of model/crystal_case.hpp.
#pragma once

#include <array>
#include <filesystem>
#include <string>
#include <string_view>

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

// A scene's `phase:` block (slip families or systems, elasticity, tau0, law, initial_mu,
// per_family, latent, pressure_sensitive, kinematics), every error reported; `elasticity_type`
// gets the elasticity's `type`. Each family's initial_mu is resolved (mu_s where none is given).
// The crystal fit file (io/fit_file.hpp) reads its phase with it too.
crystal::PhaseDescription parse_crystal_phase(const CheckedNode& node, SceneValues& values,
                                              std::string& elasticity_type);

// One inline orientation: Bunge Euler angles [phi1, Phi, phi2] in degrees (with `weighted`, an
// optional fourth entry, the weight), checked against the ranges of orientation files.
struct EulerDegrees {
  crystal::Vec3 degrees = crystal::Vec3::Zero();  // as written [deg]
  crystal::Orientation orientation;
};
EulerDegrees parse_euler_degrees(const CheckedNode& node, bool weighted);

// Reads, sweeps and checks a crystal scene, and reads every case's orientations (the whole set
// in this process: model::read_all_orientations). Every problem is an InputError with file,
// line and key path. Orientation files are read relative to the scene file's directory.
CrystalScene load_crystal_scene(const std::filesystem::path& path);
CrystalScene parse_crystal_scene(const YamlDocument& document);

// The run model alone: the same checks, but each case's orientations only described
// (CrystalCase::orientation_origin: a file, a generated texture, the scene's Euler angles), to be
// read by whoever runs it (driver::read_orientations gives each MPI rank its block). A problem
// inside an orientation file is then found when it is read, with the same error.
CrystalScene describe_crystal_scene(const YamlDocument& document);

}  // namespace subslip::io
