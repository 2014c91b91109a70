// The result file of a run, as `subslip run` opens, checks and finishes it: a new file is
// created under a temporary name and renamed once its header is complete (so the result path
// never names a half-written header); a restart continues the file of the interrupted run. A
// failed write becomes one error naming the file, what was being written and why, and the file
// records it.
#pragma once

#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "subslip/driver/sink_error.hpp"
#include "subslip/io/h5_writer.hpp"
#include "subslip/io/restart.hpp"
#include "subslip/io/result_file.hpp"
#include "subslip/io/result_protocol.hpp"
#include "subslip/io/run_size.hpp"
#include "subslip/io/yaml_checked.hpp"
#include "subslip/parallel/team.hpp"

namespace subslip::io {

// The valid rows of every case in a result file (0 when it cannot be read).
long long rows_in(const std::filesystem::path& file);

// Where a run writes: a new file, created under a temporary name and renamed once its header
// is complete (so the result path never names a half-written header), or, with --restart, the
// file of the interrupted run.
struct RunOutput {
  std::filesystem::path path;
  std::filesystem::path partial;  // empty on a restart
  h5::File file;
  bool keep_restart = false;
  bool restart() const { return partial.empty(); }
  void header_written() { std::filesystem::rename(partial, path); }
  std::filesystem::path restart_file() const { return restart_file_for(path); }

  // MPI ranks write the file together (run_collectively): after the root laid it out
  // (or reopened it) and closed it, they open it for their writes; when they have closed it,
  // they finish it together (finish_result over the team), or the root reports `failure` as
  // write() does. Collective: `root_output` is the root's (null on the other ranks); a failure
  // is thrown on the root and stops the others (parallel::StoppedByRoot) with `exit_code_of`.
  static void finish_collective_run(RunOutput* root_output, const parallel::Team& team,
                                    const std::optional<driver::SinkWriteError>& failure,
                                    parallel::ExitCodeOf exit_code_of);

  // Runs `run` (which writes into `file`), then closes the file and, when every case ended,
  // rewrites it as the finished file (exactly its rows) and deletes the restart file (unless
  // --keep-restart). A failed write (a full disk, a file-size limit) becomes one error naming
  // the file, what was being written and the system's reason; the file records it and keeps
  // the rows written before, or is removed when it holds none (it would only take space on a
  // disk that is already full).
  template <class Run>
  auto write(Run&& run) -> decltype(run()) {
    try {
      auto result = run();
      file.close();
      finish();
      return result;
    } catch (const h5::Error& e) {
      throw std::runtime_error(write_failure(e));
    }
  }

 private:
  // The working file, closed, becomes the finished file. A failure leaves the working file as
  // it was (every row in it, /progress counting them) and says how to finish it later.
  void finish();
  // Whether the (closed) working file is to be finished: every case ended. Its restart file
  // then goes (unless kept): no run needs the checkpoints again.
  bool ready_to_finish();
  // The finished file could not be written (`why`): the working file records it; throws the
  // error that says how to finish it later.
  [[noreturn]] void finish_failed(const std::string& why);
  std::string write_failure(const driver::SinkWriteError& e);
};

// What the command line asks of a run's result file.
struct OutputRequest {
  std::filesystem::path path;  // the result file (with `restart`, the file continued)
  bool restart = false;        // --restart: continue `path` in place
  bool force = false;          // --force: an existing result (and restart file) may be replaced
  bool keep_restart = false;   // --keep-restart: keep the restart file when the run finishes
};

// The checks of the output, then the file: `size` is what the run will write and need;
// `restart`: what the file of an interrupted run holds (null for a new run); `inputs`: the
// run's input files, which the result must not replace; `checkpoints`: the run writes a
// restart file.
RunOutput open_output(const OutputRequest& request, const YamlDocument& document,
                      const std::vector<std::string>& case_names, const RestartInfo* restart,
                      const std::vector<std::filesystem::path>& inputs, const RunSize& size,
                      bool checkpoints = false);

}  // namespace subslip::io
