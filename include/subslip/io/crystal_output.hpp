// Running a crystal scene into a result file (layout in docs/scenes.md, "Crystal result files"):
//
//   /                         format, format_version, program_version, scene_kind = "crystal", ...
//   /scene                    the scene YAML, verbatim
//   /units                    attributes stress, time
//   /cases/<name>/            attributes: swept values, resolved parameters (per slip system,
//                             each with a sibling "<name>.unit"), summary
//   /cases/<name>/macro/      time [n], L, F, strain, stress [n, 9] (row-major 3x3), segment [n]
//   /cases/<name>/grains/     only when grain fields are requested: weight [G],
//                             initial_orientation [G, 4], slip_systems [N, 6], and the requested
//                             per-grain series as 3-D datasets [n, G, k]
#pragma once

#include <Eigen/Core>
#include <array>
#include <chrono>
#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "subslip/crystal/aggregate.hpp"
#include "subslip/crystal/phase_builder.hpp"
#include "subslip/io/crystal_scene.hpp"
#include "subslip/io/h5_writer.hpp"

namespace subslip::io {

// The component (i, j) of L that drives a case: the largest prescribed |L_ij| over its
// segments (the tension axis, the shear component, ...). The summary reports strain and stress
// along it.
std::pair<int, int> loading_component(const std::vector<crystal::LoadSegment>& segments);

// sqrt(3/2 s:s) of the deviator s of sym(t); for a strain, sqrt(2/3 e:e).
double von_mises_stress(const Eigen::Matrix3d& stress);
double von_mises_strain(const Eigen::Matrix3d& strain);

struct CrystalSummary {
  crystal::MacroState final_state;  // the last state the aggregate reported
  std::pair<int, int> axis{2, 2};   // loading_component of the case
  double final_von_mises_stress = 0.0;
  double final_von_mises_strain = 0.0;
  double grain_steps_per_second = 0.0;
  double newton_per_grain_solve = 0.0;
  crystal::AggregateStats stats;
};

// One /cases/<name> group: datasets for the requested fields and the case's attributes.
class CrystalCaseWriter {
 public:
  CrystalCaseWriter(const h5::Group& cases, const CrystalCase& c, int index, const Units& units);
  // One row in every dataset.
  void append(const crystal::MacroState& m, const crystal::GrainFields& grains);
  // Writes the rows gathered so far (call before File::flush()).
  void commit();
  // Commits, and writes the summary attributes.
  void finish(const CrystalSummary& summary);
  // Commits, and records why the case stopped.
  void mark_failed(const std::string& why);
  const crystal::MacroState& last_state() const { return last_; }

 private:
  void create_macro(const CrystalCase& c);
  void create_grains(const CrystalCase& c);

  h5::Group group_;
  Units units_;
  std::array<std::optional<h5::Series>, kAllMacroFields.size()> macro_;
  std::array<std::optional<h5::Series>, kAllGrainFields.size()> grains_;
  std::array<std::size_t, kAllGrainFields.size()> grain_width_{};  // values per step
  std::vector<double> matrices_;  // the orientation matrices of one step, before conversion
  std::vector<double> row_;       // one step of a per-grain field
  crystal::MacroState last_;
};

struct CrystalCaseResult {
  std::string name;
  CrystalSummary summary;
  std::string failure;  // non-empty when the case stopped on a crystal::CrystalStepFailure
};

struct CrystalRunOptions {
  // Flush at most this often while streaming (0: after every output step).
  std::chrono::duration<double> flush_interval{0.25};
  // Called as each case is written.
  std::function<void(std::size_t index, const CrystalCase&, const CrystalCaseResult&)> on_case_done;
  // Called with every state the aggregate reports, after it is written (tests, progress).
  std::function<void(std::size_t index, const crystal::MacroState&, const crystal::GrainFields&)>
      on_state;
};

// Writes the result header, runs every case in order (the grains of a case run in parallel
// inside the aggregate) into /cases and, when all succeeded, sets completed = 1. Each output
// step is streamed to the file as it is computed. A case that fails numerically
// (crystal::CrystalStepFailure) keeps the rows it reached, gets a `failed` attribute and a
// result with `failure` set; the other cases still run and the file stays completed = 0.
// Other errors (HDF5) are thrown.
std::vector<CrystalCaseResult> run_crystal_scene(const CrystalScene& scene, h5::File& file,
                                                 const CrystalRunOptions& options = {});

}  // namespace subslip::io
