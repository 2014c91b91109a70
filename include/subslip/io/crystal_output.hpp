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
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "subslip/crystal/aggregate.hpp"
#include "subslip/crystal/phase_builder.hpp"
#include "subslip/io/crystal_scene.hpp"
#include "subslip/io/h5_writer.hpp"
#include "subslip/io/run_size.hpp"

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
// The case's valid rows are counted in /progress (index `index`).
class CrystalCaseWriter {
 public:
  // Creates the case's group with everything the run will write into (the layout, before any
  // computation): attributes, summary placeholders, the series with their rows reserved.
  static void lay_out(const h5::Group& cases, const CrystalCase& c, int index, const Units& units);
  // The group lay_out made, written from row `rows` on (0: a case that starts; else a restart
  // continuing from a checkpoint). Throws InputError when the case's orientations are not those
  // the group was laid out for.
  CrystalCaseWriter(const h5::Group& cases, const CrystalCase& c, int index, const Units& units,
                    h5::CaseProgress& progress, std::size_t rows);
  // One row in every dataset.
  void append(const crystal::MacroState& m, const crystal::GrainFields& grains);
  // Writes the rows gathered so far and then their number to /progress.
  void commit();
  // Commits and writes the summary attributes (in place).
  void finish(const CrystalSummary& summary);
  // finish(), and records why the case stopped in the reserved `failed` attribute.
  void mark_failed(const CrystalSummary& summary, const std::string& why);
  const crystal::MacroState& last_state() const { return last_; }
  void set_last_state(const crystal::MacroState& m) { last_ = m; }  // a restart
  std::size_t rows() const;                                         // appended so far
  const h5::Group& group() const { return group_; }

 private:
  void close_series();

  h5::Group group_;
  Units units_;
  h5::CaseProgress& progress_;
  std::size_t index_;
  std::array<std::optional<h5::Series>, kAllMacroFields.size()> macro_;
  std::array<std::optional<h5::Series>, kAllGrainFields.size()> grains_;
  std::array<std::size_t, kAllGrainFields.size()> grain_width_{};  // values per step
  std::optional<h5::Series> grain_row_;  // grains/row: the output row of each per-grain row
  std::vector<bool> grain_mask_;         // output.grains_at: the output rows with grain rows
  std::vector<double> matrices_;         // the orientation matrices of one step, before conversion
  std::vector<double> row_;              // one step of a per-grain field
  crystal::MacroState last_;
};

struct CrystalCaseResult {
  std::string name;
  CrystalSummary summary;
  std::string failure;  // non-empty when the case stopped on a crystal::CrystalStepFailure
};

// When a crystal case writes a checkpoint (io/checkpoint.hpp): every `every_increments`
// increments and/or whenever `every_seconds` of wall time have passed since the last one (after
// the increment that crosses it); neither set: no checkpoints.
struct CheckpointPolicy {
  long every_increments = 0;
  double every_seconds = 0.0;
  bool enabled() const { return every_increments > 0 || every_seconds > 0.0; }
};

// The default when neither the scene (output.checkpoint_every) nor the command line says: a
// checkpoint about once a minute, which costs nothing noticeable and loses at most a minute.
inline constexpr double kDefaultCheckpointSeconds = 60.0;

// The policy of a case: `command_line` (--checkpoint-every N, N increments, 0 none) if given,
// else the scene's output.checkpoint_every, else every kDefaultCheckpointSeconds.
CheckpointPolicy checkpoint_policy(const CrystalCase& c, std::optional<long> command_line);

struct CrystalRunOptions {
  // Rows are committed after every output step unless that costs more than ~5 % (WritePacer);
  // never more often than this.
  std::chrono::duration<double> flush_interval{0.0};
  double write_cost_ratio = h5::WritePacer::kCostRatio;  // 0: every output step (benchmarks)
  // Continue the run whose file this is (header, /cases and /progress exist): completed and
  // failed cases are kept, an interrupted case continues, the others run.
  bool restart = false;
  // --checkpoint-every: overrides every case's checkpoint_policy.
  std::optional<long> checkpoint_every;
  // Where checkpoints go (io/result_file.hpp: restart_file_for(result)); empty: nowhere, so
  // no checkpoints. Created with the layout when a case writes checkpoints; on a restart, the
  // existing one of the same run_id is continued (else a new one is created).
  std::filesystem::path restart_file;
  // Called once the file holds its whole layout (not on a restart): the
  // command line writes to a temporary name and renames it here, so that the result path never
  // names a file that is not a readable result file.
  std::function<void()> on_header_written;
  // Called as each case is written.
  std::function<void(std::size_t index, const CrystalCase&, const CrystalCaseResult&)> on_case_done;
  // How far case `index` is: the fraction of its loading time done. `resumed` marks the point a
  // restart continues from (work done before this session), and completed cases it skips.
  std::function<void(std::size_t index, double fraction, bool resumed)> on_progress;
  // Called with every state the aggregate reports, after it is written (tests, progress).
  std::function<void(std::size_t index, const crystal::MacroState&, const crystal::GrainFields&)>
      on_state;
};

// Writes the result header, runs every case in order (the grains of a case run in parallel
// inside the aggregate) into /cases. Each output step is streamed to the file as it is
// computed. The file stays a working file (completed = 0, rows reserved): the caller closes it
// and, when every case ended, finishes it (io/result_file.hpp, finish_result). A case that fails
// numerically (crystal::CrystalStepFailure) keeps the rows it reached, writes its `failed`
// attribute and gets a result with `failure` set; the other cases still run and the file stays
// completed = 0. Other errors (HDF5) are thrown. The result size (checkpoints with
// `checkpoint_every`, as run_crystal_scene would write them) and the memory of the largest case,
// from the layout the run would write.
RunSize estimate_crystal_run(const CrystalScene& scene, std::optional<long> checkpoint_every);

std::vector<CrystalCaseResult> run_crystal_scene(const CrystalScene& scene, h5::File& file,
                                                 const CrystalRunOptions& options = {});

}  // namespace subslip::io
