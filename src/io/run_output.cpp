#include "subslip/io/run_output.hpp"

#include <limits>
#include <string>
#include <system_error>

namespace fs = std::filesystem;

namespace subslip::io {

namespace {

// Before any work: the result (and checkpoints) must fit in the free space of the output's file
// system and the largest case in memory. A restart's file is laid out already: memory only.
void check_fits(const OutputRequest& request, const YamlDocument& document, const RunSize& size) {
  const fs::path& out = request.path;
  io::Capacity capacity = io::capacity_for(out);
  if (request.restart) capacity.disk_bytes = std::numeric_limits<double>::infinity();
  io::check_run_fits(document, size, capacity, out);
}

// A result path naming one of the run's input files would replace it (with --force) by its own
// result: refused, --force or not.
void refuse_output_over_inputs(const fs::path& out, const std::vector<fs::path>& inputs) {
  for (const auto& in : inputs) {
    std::error_code ec;  // (a path that does not exist is no input file)
    if (fs::equivalent(out, in, ec)) {
      throw io::h5::OutputPathError(out.string() + ": is the input file " + in.string() +
                                    " of this run; choose another output path (-o)");
    }
  }
}

// A result path that holds an interrupted run is continued with --restart, replaced only with
// --force; the message says both.
void refuse_interrupted_result(const fs::path& out, bool force) {
  if (force) return;
  const ResultFileStatus status = result_file_status(out);
  if (status.kind != ResultFileKind::working) return;
  throw io::h5::OutputPathError(out.string() + ": holds an interrupted run (" +
                                std::to_string(status.rows) +
                                " output rows written); continue it with: subslip run --restart " +
                                out.string() + " (or replace it with --force)");
}

// The restart file of a new run's result (checkpoints): one left by an interrupted run, or one
// no run can continue (its run finished, or its result file is gone), is replaced only with
// --force, and the message says which it is; anything else at that path is never replaced.
void check_restart_path(const fs::path& out, bool force) {
  const fs::path restart = io::restart_file_for(out);
  std::error_code ec;
  if (!fs::exists(restart, ec)) return;
  if (!force && restart_file_role(out) == RestartFileRole::left_over) {
    const bool finished = result_file_status(out).kind == ResultFileKind::finished;
    throw io::h5::OutputPathError(
        restart.string() + ": already exists, left over from a run of " + out.string() +
        (finished ? " that finished" : " whose result file is gone") +
        ": no run continues from it; delete it, or use --force to replace it");
  }
  if (!io::is_restart_file(restart)) {
    throw io::h5::OutputPathError(restart.string() +
                                  ": exists and is not a subslip restart file, but the "
                                  "checkpoints of " +
                                  out.string() + " go there; move it away or choose another -o");
  }
  if (!force) {
    throw io::h5::OutputPathError(restart.string() +
                                  ": already exists (the checkpoints of an "
                                  "interrupted run of " +
                                  out.string() + "); continue that run with --restart " +
                                  out.string() + ", or use --force to start anew");
  }
}

}  // namespace

long long rows_in(const fs::path& file) {
  try {
    const io::h5::File f = io::h5::File::open_read(file);
    const auto progress = io::h5::CaseProgress::open(f.root());
    long long rows = 0;
    for (std::size_t k = 0; k < progress.size(); ++k) rows += progress.rows(k);
    return rows;
  } catch (const io::h5::Error&) {
    return 0;
  }
}

void RunOutput::finish_collective_run(RunOutput* root_output, const parallel::Team& team,
                                      const std::optional<driver::SinkWriteError>& failure,
                                      parallel::ExitCodeOf exit_code_of) {
  if (failure) {
    parallel::on_root(
        team,
        [&] {
          // (write_failure records the error in the file)
          root_output->file = io::h5::File::open_write(root_output->path);
          throw std::runtime_error(root_output->write_failure(*failure));
        },
        exit_code_of);
  }
  std::vector<double> ready{0.0};
  std::string path;
  parallel::on_root(
      team,
      [&] {
        ready[0] = root_output->ready_to_finish() ? 1.0 : 0.0;
        path = root_output->path.string();
      },
      exit_code_of);
  team.broadcast(ready, 0);
  team.broadcast(path, 0);
  if (ready[0] == 0.0) return;
  std::string why;
  try {
    io::finish_result(path, team);
  } catch (const io::h5::Error& e) {  // (the same on every rank)
    why = e.action + (e.reason.empty() ? "" : ": " + e.reason);
  }
  parallel::on_root(
      team,
      [&] {
        if (!why.empty()) root_output->finish_failed(why);
      },
      exit_code_of);
}

bool RunOutput::ready_to_finish() {
  if (!io::every_case_ended(path)) return false;
  // Every case has ended, so no run needs the checkpoints again (a restart of this file only
  // finishes it): they go before the finished file replaces the working one, and a kill between
  // the two leaves no restart file behind.
  std::error_code ec;
  if (!keep_restart && io::is_restart_file(restart_file())) fs::remove(restart_file(), ec);
  return true;
}

void RunOutput::finish() {
  if (!ready_to_finish()) return;
  std::string why;
  try {
    io::finish_result(path);
  } catch (const io::h5::Error& e) {
    why = e.action + (e.reason.empty() ? "" : ": " + e.reason);
  } catch (const fs::filesystem_error& e) {
    why = e.what();
  }
  if (!why.empty()) finish_failed(why);
}

void RunOutput::finish_failed(const std::string& why) {
  const std::string what = path.string() + ": cannot write the finished file (" + why + ")";
  {
    io::h5::File working = io::h5::File::open_write(path);
    io::h5::mark_write_failed(working, "the run ended but " + what);
    working.close_quietly();
  }
  throw std::runtime_error(what + "; every row is in the working file " + path.string() +
                           " (/progress counts them); free space and finish it with "
                           "--restart " +
                           path.string());
}

std::string RunOutput::write_failure(const driver::SinkWriteError& e) {
  const std::string what =
      path.string() + ": cannot " + e.action + (e.reason.empty() ? "" : ": " + e.reason);
  const bool recorded = io::h5::mark_write_failed(file, "the run stopped: " + what);
  file.close_quietly();
  std::error_code ec;
  if (!restart() && fs::exists(partial, ec)) {
    fs::remove(partial, ec);
    return what + "; the result's layout was not complete, so " + partial.string() + " was removed";
  }
  const long long rows = rows_in(path);
  if (!restart() && rows == 0) {
    fs::remove(path, ec);
    return what + "; no output step had been written, so the file was removed";
  }
  return what + "; the rows written before (" + std::to_string(rows) +
         ") stay readable and the file is marked incomplete (completed = 0" +
         (recorded ? ", write_error" : "") + "); free space and continue with --restart " +
         path.string();
}

RunOutput open_output(const OutputRequest& request, const YamlDocument& document,
                      const std::vector<std::string>& case_names, const RestartInfo* restart,
                      const std::vector<fs::path>& inputs, const RunSize& size, bool checkpoints) {
  const fs::path& out = request.path;
  if (restart != nullptr) {
    io::check_restart_cases(out, *restart, case_names);
    check_fits(request, document, size);
    return {out, {}, io::h5::File::open_write(out), request.keep_restart};
  }
  refuse_output_over_inputs(out, inputs);
  if (checkpoints) refuse_output_over_inputs(io::restart_file_for(out), inputs);
  check_fits(request, document, size);  // before check_output_path creates directories
  refuse_interrupted_result(out, request.force);
  io::h5::check_output_path(out, request.force);
  if (checkpoints) check_restart_path(out, request.force);
  fs::path partial = out;
  partial += ".partial";
  try {
    return {out, partial, io::h5::File::create(partial, true), request.keep_restart};
  } catch (const io::h5::Error& e) {
    std::error_code ec;
    fs::remove(partial, ec);
    throw std::runtime_error(out.string() + ": cannot " + e.action +
                             (e.reason.empty() ? "" : ": " + e.reason));
  }
}

}  // namespace subslip::io
