#include "subslip/driver/checkpoint_policy.hpp"

#include <algorithm>

#include "subslip/crystal/phase_builder.hpp"

namespace subslip::driver {

CheckpointPolicy checkpoint_policy(const model::CrystalCase& c, std::optional<long> command_line) {
  CheckpointPolicy p;
  if (command_line) {
    p.every_increments = *command_line;
  } else if (c.output.checkpoint_every >= 0) {
    p.every_increments = c.output.checkpoint_every;
  } else {
    p.every_seconds = kDefaultCheckpointSeconds;
  }
  return p;
}

std::size_t checkpoint_values(const model::CrystalCase& c) {
  const auto slip_count = static_cast<int>(crystal::described_systems(c.phase).size());
  return c.grain_count() *
         static_cast<std::size_t>(crystal::checkpoint_values_per_grain(slip_count));
}

std::size_t checkpoint_capacity(const model::CrystalScene& scene,
                                std::optional<long> command_line) {
  std::size_t most = 0;
  for (const auto& c : scene.cases) {
    if (checkpoint_policy(c, command_line).enabled()) most = std::max(most, checkpoint_values(c));
  }
  return most;
}

}  // namespace subslip::driver
