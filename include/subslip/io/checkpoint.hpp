// Checkpoints of a crystal case, stored in the result file next to the case's series:
//
//   /cases/<case>/checkpoint/
//       a/, b/                           two slots, written alternately:
//           grains    [G, 15 + 4N] f64   per grain: stress (lattice, Mandel) 6, orientation g 9,
//                                        mu N, r_s N, slip N, slip rate N
//           values    [K] f64            attribute names: the K macro numbers (see below)
//           counters  [M] i64            attribute names: position, row count, statistics
//           sequence  scalar i64         1, 2, 3, ... for a complete slot; -1 while written
//
// Why two slots in the result file: a checkpoint is written into the slot that does not hold
// the latest one, and its `sequence` is set to -1 before and to the new number after the data,
// all in place (the datasets are allocated when the first checkpoint is written, so later ones
// change no HDF5 metadata, and the file has no write buffers: the order of the writes is the
// order in the file). A kill while a slot is written leaves that slot at -1 and the other one
// intact. The case's series rows named by a checkpoint are in the file before it.
#pragma once

#include <cstddef>
#include <optional>

#include "subslip/crystal/aggregate.hpp"
#include "subslip/io/h5_writer.hpp"

namespace subslip::io {

struct StoredCheckpoint {
  crystal::AggregateCheckpoint state;
  std::size_t rows = 0;             // valid rows of the case's series at the checkpoint
  crystal::MacroState last_output;  // the last state written to the series
  long long sequence = 0;
};

class CheckpointStore {
 public:
  // The checkpoints of one case group (nothing is created until the first write).
  explicit CheckpointStore(const h5::Group& case_group) : case_(case_group) {}

  // Writes a checkpoint into the slot that does not hold the latest one. The first write
  // creates both slots and flushes `file`.
  void write(h5::File& file, const crystal::AggregateCheckpoint& state, std::size_t rows,
             const crystal::MacroState& last_output);

  // The complete checkpoint with the highest sequence, if any.
  std::optional<StoredCheckpoint> latest() const;

  long long sequence() const { return sequence_; }  // of the latest write (0: none yet)

 private:
  void create_slots(h5::File& file, std::size_t grains, int values_per_grain);

  const h5::Group& case_;
  long long sequence_ = 0;
  int next_slot_ = 0;  // 0: a, 1: b
};

}  // namespace subslip::io
