// What a crystal run hands to whatever keeps its results (the HDF5 result file:
// io/crystal_output.hpp). The driver (driver/crystal_run.hpp) decides what happens: which
// cases run, from where, when a checkpoint is due; a sink only stores and reports what it
// stored.
//
// Per-grain data arrive as blocks of grains with their place in the case (GrainRange), never as
// a copy of the whole aggregate: today one process holds every grain (one block, offset 0);
// with MPI each rank hands its own block and a sink writes it at its offset (a hyperslab).
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <utility>

#include "subslip/crystal/aggregate.hpp"
#include "subslip/driver/case_status.hpp"

namespace subslip::driver {

struct CrystalSummary {
  crystal::MacroState final_state;  // the last state the aggregate reported
  std::pair<int, int> axis{2, 2};   // loading_component of the case
  double final_von_mises_stress = 0.0;
  double final_von_mises_strain = 0.0;
  double grain_steps_per_second = 0.0;
  double newton_per_grain_solve = 0.0;
  crystal::AggregateStats stats;
};

struct CrystalCaseResult {
  std::string name;
  CrystalSummary summary;
  std::string failure;  // non-empty when the case stopped on a crystal::CrystalStepFailure
};

// Grains [offset, offset + count) of a case of `total` grains, in the order of its
// orientations.
struct GrainRange {
  std::size_t offset = 0;
  std::size_t count = 0;
  std::size_t total = 0;
  bool whole() const { return offset == 0 && count == total; }
};

// The per-grain fields of one output state for a block of grains. `fields` fills the sink's
// own buffers on request (crystal::GrainFields), so only the fields a sink writes are made.
struct GrainBlock {
  GrainRange range;
  const crystal::GrainFields& fields;  // fields.grain_count() == range.count
};

// A checkpoint of the running case: the macro state and position, and the grains of `range`.
struct CheckpointBlock {
  GrainRange range;
  const crystal::AggregateCheckpoint& state;
};

// Where an interrupted case continues: its latest checkpoint and what its output held then.
struct ResumePoint {
  crystal::AggregateCheckpoint state;
  std::size_t rows = 0;             // output rows of the case at the checkpoint
  crystal::MacroState last_output;  // the last state written to them
};

// What an earlier session stored of a case it ended.
struct StoredCrystalCase {
  crystal::MacroState final_state;  // time, stress and strain of the last output
  crystal::AggregateStats stats;
  std::string failure;  // why it stopped, as fail_case stored it; empty: it completed
};

class CrystalSink {
 public:
  virtual ~CrystalSink() = default;

  // --- what an earlier session left (a new run: every case pending, nothing stored)
  virtual CaseStatus status(std::size_t index) const = 0;
  // A case whose status is completed or failed.
  virtual StoredCrystalCase stored_case(std::size_t index) const = 0;
  // The latest checkpoint the sink holds of case `index`, if any.
  virtual std::optional<ResumePoint> latest_checkpoint(std::size_t index) const = 0;
  // Grain values a checkpoint may hold; 0: the sink stores no checkpoints.
  virtual std::size_t checkpoint_capacity() const = 0;

  // --- one case at a time
  // Case `index` starts, or (resume) continues after the output rows of that checkpoint.
  virtual void begin_case(std::size_t index, const ResumePoint* resume) = 0;
  // One output state of the running case.
  virtual void write_state(const crystal::MacroState& state, const GrainBlock& grains) = 0;
  // A checkpoint of the running case; every state written before it is stored first, so that
  // the rows it counts are there when it is.
  virtual void write_checkpoint(const CheckpointBlock& checkpoint,
                                const crystal::MacroState& last_output) = 0;
  // The running case ended: every state written, then its summary, then its status.
  virtual void complete_case(const CrystalSummary& summary) = 0;
  virtual void fail_case(const CrystalSummary& summary, const std::string& why) = 0;

  // Every case has ended (completed or failed).
  virtual void end_run() = 0;
};

}  // namespace subslip::driver
