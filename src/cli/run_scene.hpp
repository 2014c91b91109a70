// `subslip run`: a scene run into its result file, as the command line and the Python module
// (src/python/) call it. One implementation, so that both write the same file.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include "subslip/parallel/team.hpp"

namespace subslip::cli {

struct RunArgs {
  std::string scene;  // the scene file, or the name of scene_text in messages
  // The scene's YAML text when it comes as text rather than a file (a Python dict); empty: read
  // the file `scene`.
  std::string scene_text;
  // --set PATH=VALUE, in order: values set over the scene's (io/scene_compose.hpp).
  std::vector<std::string> settings;
  std::string output;  // empty: results/<scene stem>.h5
  bool force = false;
  bool quiet = false;
  bool verbose = false;  // HDF5's error stack with an HDF5 error
  int threads = 0;
  double flush_interval = 0.0;
  std::string restart;         // --restart FILE: continue the run that wrote FILE
  int checkpoint_every = -1;   // --checkpoint-every N (-1: the scene's, or automatic)
  bool keep_restart = false;   // --keep-restart: keep the restart file when the run finishes
  bool gather_output = false;  // --gather-output: MPI ranks' grains written by rank 0
  // SIGTERM, SIGINT and SIGUSR1 stop a crystal run after an increment (the program's handlers
  // for the run's length). Off inside a Python interpreter, whose handlers are its own and
  // whose threads may run scenes at once.
  bool stop_on_signals = true;
  // Where the scene's warnings go; null: printed to stderr (unless quiet).
  std::vector<std::string>* warnings = nullptr;
};

// A crystal run stopped by a signal: its exit status is 128 + the signal's number, as if the
// signal had ended it.
struct StoppedBySignal : std::runtime_error {
  StoppedBySignal(const std::string& what, int signal)
      : std::runtime_error(what), exit_code(128 + signal) {}
  int exit_code;
};

// The exit status of a failure: 2 bad input or output path, 3 a numerical failure, 1 others.
int exit_code_of(const std::exception_ptr& failure);

// Runs the scene of `a` over the ranks of `team` (a serial run: parallel::serial_team()) into
// its result file; prints the scene's table and summary unless quiet. A failure is thrown (its
// exit status: exit_code_of); returns 0.
int run_scene(const RunArgs& a, const parallel::Team& team);

}  // namespace subslip::cli
