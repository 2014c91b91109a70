// The result file of a crystal run (layout in docs/scenes.md, "Crystal result files"):
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

#include <array>
#include <chrono>
#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "subslip/crystal/aggregate.hpp"
#include "subslip/crystal/phase_builder.hpp"
#include "subslip/driver/crystal_sink.hpp"
#include "subslip/io/checkpoint.hpp"
#include "subslip/io/crystal_scene.hpp"
#include "subslip/io/h5_writer.hpp"
#include "subslip/io/result_protocol.hpp"
#include "subslip/io/run_size.hpp"
#include "subslip/parallel/team.hpp"

namespace subslip::io {

// One /cases/<name> group: datasets for the requested fields and the case's attributes.
// The case's valid rows are counted in /progress (index `index`).
class CrystalCaseWriter {
 public:
  // Creates the case's group with everything the run will write into (the layout, before any
  // computation): attributes, summary placeholders, the series with their rows reserved.
  static void lay_out(const h5::Group& cases, const CrystalCase& c, int index, const Units& units);
  // The group lay_out made, written from row `rows` on (0: a case that starts; else a restart
  // continuing from a checkpoint). Throws InputError when the case's orientations are not those
  // the group was laid out for. `grains`: the grains this process writes (MPI ranks writing
  // the file together, each its block); nullptr: every grain.
  CrystalCaseWriter(const h5::Group& cases, const CrystalCase& c, int index, const Units& units,
                    h5::CaseProgress& progress, std::size_t rows,
                    const parallel::Block* grains = nullptr);
  // One row in every dataset (`grains`: the block of grains this writer writes).
  void append(const crystal::MacroState& m, const crystal::GrainFields& grains);
  // Writes the rows gathered so far and then their number to /progress.
  void commit();
  // Commits and writes the summary attributes (in place).
  void finish(const driver::CrystalSummary& summary);
  // finish(), and records why the case stopped in the reserved `failed` attribute.
  void mark_failed(const driver::CrystalSummary& summary, const std::string& why);
  std::size_t rows() const;  // appended so far
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
};

struct CrystalSinkOptions {
  // Rows are committed after every output step unless that costs more than ~5 % (WritePacer);
  // never more often than this.
  std::chrono::duration<double> flush_interval{0.0};
  double write_cost_ratio = h5::WritePacer::kCostRatio;  // 0: every output step (benchmarks)
  // Continue the run whose file this is (header, /cases and /progress exist) instead of laying
  // out a new one.
  bool restart = false;
  // Where checkpoints go (io/result_file.hpp: restart_file_for(result)); empty: nowhere, so
  // no checkpoints. Created with the layout when checkpoint_capacity > 0; on a restart, the
  // existing one of the same run_id is continued (else a new one is created).
  std::filesystem::path restart_file;
  // Grain values of the largest checkpoint the run writes (driver::checkpoint_capacity); 0:
  // the run writes none.
  std::size_t checkpoint_capacity = 0;
  // MPI ranks writing the file together (opened with this MpiAccess by all `ranks`; the
  // restart file is opened so too): this process writes and reads the grains of its block
  // (parallel::block_of) of each case only, and every rank makes every other write alike
  // (h5_writer.hpp, collective writes). Such a sink only continues a file laid out before
  // (`restart`), and commits after every output step (a pace by each rank's clock would differ).
  std::optional<h5::MpiAccess> mpi;
  int ranks = 1;
  // Root attributes of a new file that say how its results were computed (ResultHeader).
  std::vector<std::pair<std::string, std::string>> computed_with;
};

// The groups and files a crystal run writes into, laid out or reopened by CrystalResultSink.
struct CrystalRunFiles {
  h5::Group cases;
  h5::CaseProgress progress;
  std::optional<h5::File> restart_file = {};  // the checkpoint store's file, when there is one
};

// The result file of a crystal run, as the driver's sink (driver/crystal_sink.hpp). Each
// output step is streamed to the file as it is computed. The file stays a working file
// (completed = 0, rows reserved): the caller closes it and, when every case ended, finishes it
// (io/result_file.hpp, finish_result). A failed case keeps the rows it reached and writes its
// `failed` attribute. Errors (HDF5) are thrown.
class CrystalResultSink final : public driver::CrystalSink {
 public:
  // A new run: writes the result header and the whole layout (and the restart file) before
  // anything is computed; the file then says layout_complete. A restart: marks the file
  // running and reopens its restart file.
  CrystalResultSink(const CrystalScene& scene, h5::File& file, const CrystalSinkOptions& options);
  CrystalResultSink(const CrystalResultSink&) = delete;  // the case writer refers to run_
  CrystalResultSink& operator=(const CrystalResultSink&) = delete;

  driver::CaseStatus status(std::size_t index) const override;
  driver::StoredCrystalCase stored_case(std::size_t index) const override;
  std::optional<driver::ResumePoint> latest_checkpoint(std::size_t index) const override;
  std::size_t checkpoint_capacity() const override;
  void begin_case(std::size_t index, const driver::ResumePoint* resume) override;
  void write_state(const crystal::MacroState& state, const driver::GrainBlock& grains) override;
  void write_checkpoint(const driver::CheckpointBlock& checkpoint,
                        const crystal::MacroState& last_output) override;
  void complete_case(const driver::CrystalSummary& summary) override;
  void fail_case(const driver::CrystalSummary& summary, const std::string& why) override;
  void end_run() override;

 private:
  void end_case(h5::CaseState state);
  void write_grain_statics_again();
  std::optional<parallel::Block> grains_of(std::size_t index) const;  // this process's, if a part

  const CrystalScene& scene_;
  h5::File& file_;
  CrystalSinkOptions options_;
  CrystalRunFiles run_;
  // The running case.
  std::size_t index_ = 0;
  std::optional<CrystalCaseWriter> writer_;
  std::optional<CheckpointStore> checkpoints_;
  std::optional<h5::WritePacer> pacer_;
};

// The result size (checkpoints with `checkpoint_every`, as the driver would write them) and
// the memory of the largest case, from the layout the run would write.
RunSize estimate_crystal_run(const CrystalScene& scene, std::optional<long> checkpoint_every);

}  // namespace subslip::io
