// The life of a result file beyond one run's writing (docs/scenes.md, "Result file layout"):
//
// * While a run goes, the result is a *working* file: laid out whole before the first step,
//   series with rows reserved, /progress counting the valid ones (h5_writer.hpp, crash
//   safety), root attribute finished = 0. A kill leaves it readable and continuable.
// * Checkpoints of crystal cases live in a separate *restart file* next to it,
//   "<result stem>.restart.h5", created with the layout, naming the result's run_id.
// * When every case has ended (completed or failed), the working file is rewritten as the
//   *finished* file: every series holds exactly its valid rows, nothing reserved, finished = 1
//   (and completed = 1 when every case completed). The copy is written under a temporary
//   name ("<result>.finishing"), synced to disk and renamed over the working file, so that a
//   kill at any moment leaves either the working file (which --restart finishes) or the
//   finished one. The restart file is deleted (unless it is to be kept) before that rename:
//   once every case has ended no run needs its checkpoints, and a kill then leaves none behind
//   a finished file.
#pragma once

#include <filesystem>
#include <string>

namespace subslip::parallel {
class Team;
}

namespace subslip::io {

namespace h5 {
class File;
}

// "<dir>/<stem>.restart.h5" for "<dir>/<stem>.h5" (any other name: the name + ".restart.h5").
std::filesystem::path restart_file_for(const std::filesystem::path& result);

// The temporary name the finished file is written under before it replaces the result.
std::filesystem::path finishing_file_for(const std::filesystem::path& result);

// The format attribute of a restart file ("subslip-restart").
inline constexpr const char* kRestartFormat = "subslip-restart";

// True when `path` is a restart file (root attribute format = kRestartFormat), whose run is
// then `run_id` (empty when it has none); false for anything else (not HDF5, another file).
bool is_restart_file(const std::filesystem::path& path, std::string* run_id = nullptr);

// What a result path holds, as a run or `subslip post` sees it.
enum class ResultFileKind {
  none,      // no file there
  working,   // a subslip result file not finished: a run killed, stopped or still running
  finished,  // a finished subslip result file
  other,     // anything else (not HDF5, not a subslip result, unreadable)
};
struct ResultFileStatus {
  ResultFileKind kind = ResultFileKind::none;
  std::string run_id;  // the file's run_id (working and finished files)
  long long rows = 0;  // the valid output rows of every case (working files)
};
ResultFileStatus result_file_status(const std::filesystem::path& result);

// What the restart file next to `result` (restart_file_for) is to it.
enum class RestartFileRole {
  none,       // there is none
  continues,  // the checkpoints of the interrupted run `result` holds (same run_id)
  left_over,  // the checkpoints of a run that finished, or whose result file is gone: no run
              // can continue from them (a kill between the finish and their removal, or
              // --keep-restart)
  foreign,    // another run's, or not a restart file
};
RestartFileRole restart_file_role(const std::filesystem::path& result);

// True when every case of the (closed) working file at `result` has ended: completed or failed.
bool every_case_ended(const std::filesystem::path& result);

// Rewrites the working file at `result` (closed, every case ended) as the finished file and
// renames it into place (see above). Throws h5::Error (the temporary file removed) when
// writing fails; the working file is then untouched. Returns true when every case completed.
bool finish_result(const std::filesystem::path& result);
// The same by the ranks of `team` together (collective; a team of one: the above). The root
// writes the finished file's groups, attributes and every dataset but those of the cases'
// grains (/cases/<name>/grains/...) and closes it; then every rank opens it (parallel HDF5)
// and copies its block of the grains of each of those from the working file, which it reads
// by itself; the root renames the file into place. A failure on any rank is agreed: every
// rank throws the same h5::Error (the lowest failing rank's), and the root removes the
// temporary file.
bool finish_result(const std::filesystem::path& result, const parallel::Team& team);

// Closes `file`, a working result file a run wrote into, and finishes it when every case
// ended (what `subslip run` does at its end, for library users and tests).
void close_and_finish(h5::File& file);

}  // namespace subslip::io
