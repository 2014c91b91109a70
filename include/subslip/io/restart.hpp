// What `subslip run --restart FILE` needs to know about a result file before it continues it,
// and every reason to refuse (each an InputError naming the file and what is wrong, so the
// command exits with code 2 before it changes anything).
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "subslip/model/case_common.hpp"

namespace subslip::io {

struct RestartInfo {
  std::string scene_kind;     // "contact", "crystal"
  std::string scene_file;     // as the interrupted run was given it
  std::string scene_text;     // /scene, verbatim
  model::SceneMakeup makeup;  // its base scenes and settings as the run read them
  std::vector<std::string> case_names;
  std::filesystem::path restart_file;  // where its checkpoints are (io/result_file.hpp)
  // How the interrupted run computed (root attributes build and simd_kernels; empty where the
  // file does not say).
  std::string build, simd_kernels;
};

// A warning when this run would continue FILE with code that rounds differently from the code
// that started it (another build, or other SIMD kernels of the grain solver): the continued run
// then agrees with an uninterrupted one to the solvers' tolerances, not bit for bit. Empty
// otherwise.
std::string restart_rounding_warning(const std::filesystem::path& file, const RestartInfo& info,
                                     const std::string& build, const std::string& simd_kernels);

// Reads FILE and checks that it is a working result file of this program version (not
// finished: a run killed, or stopped by a failed write) that has the /progress table, and
// that its restart file, if there is one, belongs to the same run (run_id). `scene_text`, when
// given, is the text of a scene file named on the command line: it must equal /scene.
RestartInfo inspect_for_restart(const std::filesystem::path& file,
                                const std::optional<std::string>& scene_text = std::nullopt);

// Checks that the scene parsed from /scene has the cases the file lists (same names, order).
void check_restart_cases(const std::filesystem::path& file, const RestartInfo& info,
                         const std::vector<std::string>& scene_case_names);

}  // namespace subslip::io
