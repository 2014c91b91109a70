// Checkpoints of the running crystal case, stored in the restart file next to the result:
//
//   /checkpoint/                         attribute capacity: grain values a slot holds
//       a/, b/                           two slots, written alternately:
//           grains    [capacity] f64     per grain (G x (15 + 4N), row-major): stress
//                                        (lattice, Mandel) 6, orientation g 9, mu N, r_s N,
//                                        slip N, slip rate N; the rest unused
//           values    [K] f64            attribute names: the K macro numbers (see below)
//           counters  [M] i64            attribute names: position, row count, statistics,
//                                        the case (index in /cases names), G, 15 + 4N
//           sequence  scalar i64         1, 2, 3, ... for a complete slot; -1 while written
//
// One store serves every case of a run (a case's checkpoint is useless once it ends), so its
// size is that of the largest case, not the sum. It is created with the rest of the layout,
// before the run (h5_writer.hpp, crash safety): a checkpoint is written into the slot that does
// not hold the latest one, and its `sequence` is set to -1 before and to the new number after
// the data, all in place, changing no HDF5 metadata; the file has no write buffers, so the
// order of the writes is the order in the file. A kill while a slot is written leaves that
// slot at -1 and the other one intact. The case's series rows named by a checkpoint are in the
// file before it.
//
// The store lives in the result's restart file (io/result_file.hpp), not in the result: a
// finished result holds no checkpoint. Root attributes of a restart file: format =
// "subslip-restart", format_version, program_version, run_id (the result's), description.
#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>

#include "subslip/crystal/aggregate.hpp"
#include "subslip/io/h5_writer.hpp"
#include "subslip/parallel/team.hpp"

namespace subslip::io {

struct StoredCheckpoint {
  crystal::AggregateCheckpoint state;
  std::size_t rows = 0;             // valid rows of the case's series at the checkpoint
  crystal::MacroState last_output;  // the last state written to the series
  long long sequence = 0;
};

// Creates the restart file `path` with a store of `capacity` grain values for the run
// `run_id` (the result's root attribute): under a temporary name, renamed to `path` once
// complete (a kill while it is created leaves no restart file), then opened for writing.
h5::File create_restart_file(const std::filesystem::path& path, const std::string& run_id,
                             std::size_t capacity);
// The restart file `path` opened for writing (by the ranks of `mpi` together, when given),
// when it is one and belongs to `run_id`.
std::optional<h5::File> open_restart_file(const std::filesystem::path& path,
                                          const std::string& run_id,
                                          const h5::MpiAccess* mpi = nullptr);

class CheckpointStore {
 public:
  // Creates /checkpoint under `parent` for checkpoints of up to `capacity` grain values
  // (grains x values per grain); the layout phase, before the run.
  static void create(const h5::Group& parent, std::size_t capacity);
  // The store under `parent` (throws h5::Error when there is none).
  explicit CheckpointStore(const h5::Group& parent);

  // Writes a checkpoint of case `case_index` into the slot that does not hold the latest one.
  // `grains`: the grains of the case that state.grains holds (every grain unless MPI ranks
  // write the store together, each its own block: h5_writer.hpp, collective writes).
  void write(std::size_t case_index, const crystal::AggregateCheckpoint& state, std::size_t rows,
             const crystal::MacroState& last_output, const parallel::Block* grains = nullptr);

  // The complete checkpoint with the highest sequence, if it belongs to case `case_index`.
  // Its grains: those of rank `rank` of `ranks` (parallel::block_of; every grain for 0 of 1).
  std::optional<StoredCheckpoint> latest(std::size_t case_index, int rank = 0, int ranks = 1) const;

  long long sequence() const { return sequence_; }  // of the latest write (0: none yet)
  std::size_t capacity() const;                     // grain values a slot holds

 private:
  h5::Group store_;
  long long sequence_ = 0;
  int next_slot_ = 0;  // 0: a, 1: b
  bool continued_ = false;
};

}  // namespace subslip::io
