// When a crystal case writes a checkpoint (its full state, so that --restart continues it bit
// for bit), and how large the store has to be. The driver decides; the sink stores.
#pragma once

#include <cstddef>
#include <optional>

#include "subslip/model/crystal_case.hpp"

namespace subslip::driver {

// Every `every_increments` increments and/or whenever `every_seconds` of wall time have passed
// since the last one (after the increment that crosses it); neither set: no checkpoints.
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
CheckpointPolicy checkpoint_policy(const model::CrystalCase& c, std::optional<long> command_line);

// Grain values in a checkpoint of case `c` (grains x values per grain).
std::size_t checkpoint_values(const model::CrystalCase& c);

// The largest checkpoint of the scene's cases that write checkpoints (grain values); 0: none.
// One store serves every case of a run, so it is sized for this.
std::size_t checkpoint_capacity(const model::CrystalScene& scene, std::optional<long> command_line);

}  // namespace subslip::driver
