// What a run will need before it starts: the size of its result file (the checkpoint store
// included) and its memory, against the free space of the output's file system and the
// available memory. A scene that cannot fit is refused before any work (and before the result
// file is created), naming the key that sets the size, rather than failing hours later on a full
// disk or in the kernel's out-of-memory killer.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>

#include "subslip/io/yaml_checked.hpp"

namespace subslip::io {

// Estimated from the scene (the layout: every series with its rows reserved). The disk must
// hold result_bytes + finish_bytes at the end of the run.
struct RunSize {
  double result_bytes = 0.0;      // the result file, checkpoints included
  double checkpoint_bytes = 0.0;  // of which the checkpoint store (the restart file)
  double finish_bytes = 0.0;      // the finished file, written before the working one goes
  double memory_bytes = 0.0;      // the largest case in memory
  std::size_t rows = 0;           // output rows of the case with the most
  std::size_t rows_segment = 0;   // the loading segment with the most output rows in that case
  std::size_t grains = 0;         // grains of the largest case (0: a contact scene)
};

// Free bytes for an unprivileged writer on the file system of `output` (its nearest existing
// ancestor directory), and the memory available to a new process (MemAvailable).
struct Capacity {
  double disk_bytes = 0.0;
  double memory_bytes = 0.0;
};
Capacity capacity_for(const std::filesystem::path& output);

// Throws InputError (file, line and key of the scene) when `size` does not fit in `capacity`:
// the disk at `loading[i].increments` (suggesting output_every, fewer increments or, for
// crystals, fewer grains), memory at `orientations`. `output` names the file in the message.
void check_run_fits(const YamlDocument& scene, const RunSize& size, const Capacity& capacity,
                    const std::filesystem::path& output);

// "75 GB", "1.4 PB": a byte count for messages (decimal units, 3 significant digits).
std::string format_bytes(double bytes);

}  // namespace subslip::io
