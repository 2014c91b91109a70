// The result-file protocol over the HDF5 wrapper (h5_writer.hpp): the format version and the
// header every result file starts with, /progress (how far each case got), the marks of a
// file's life (layout complete, completed, a failed write), a case's failure message, the run's
// identifier and the tensor convention of its datasets. The writers (crystal_output.hpp,
// contact_output.hpp, case_group.hpp), restarts (restart.hpp, result_file.hpp) and readers
// (result_post.hpp) follow it.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "subslip/io/h5_writer.hpp"
#include "subslip/model/case_common.hpp"

namespace subslip::io::h5 {

// /progress: how far each case of a run got, written in place as the run goes (so a killed
// run's file says which rows are valid). `rows` [cases] int64: the valid rows of every series
// of the case; `state` [cases] int64: CaseState. Cases in /cases `names` order.
enum class CaseState : long long { not_started = 0, running = 1, completed = 2, failed = 3 };
// With `grain_rows` (crystal runs), also `grain_rows` [cases] int64: the valid rows of the
// case's per-grain series (grains/...), which may be fewer than `rows` (output.grains_at).
class CaseProgress {
 public:
  static CaseProgress create(const Group& root, std::size_t cases, bool grain_rows = false);
  static CaseProgress open(const Group& root);  // throws Error when the file has none
  std::size_t size() const { return rows_.size(); }
  long long rows(std::size_t index) const { return rows_[index]; }
  // The valid per-grain rows (rows() when the file does not count them apart).
  long long grain_rows(std::size_t index) const {
    return grain_rows_.empty() ? rows_[index] : grain_rows_[index];
  }
  CaseState state(std::size_t index) const { return static_cast<CaseState>(state_[index]); }
  void set_rows(std::size_t index, std::size_t rows);
  void set_grain_rows(std::size_t index, std::size_t rows);  // (no-op without grain_rows)
  void set_state(std::size_t index, CaseState state);

 private:
  CaseProgress(Dataset rows, Dataset state, std::vector<long long> r, std::vector<long long> s);
  void write_element(const Dataset& d, std::size_t index, long long value) const;
  Dataset rows_ds_, state_ds_;
  std::optional<Dataset> grain_rows_ds_;
  std::vector<long long> rows_, state_, grain_rows_;
};

// A case group's `failed` attribute: reserved at layout time (this many bytes, UTF-8), written
// when the case stops on a numerical failure; empty while it has not.
inline constexpr std::size_t kFailureMessageBytes = 1024;
// The case's failure message ("" when it did not fail, or has no `failed` attribute).
std::string failure_message(const Group& case_group);

// The part of a result file every scene kind shares.
struct ResultHeader {
  std::string scene_kind;  // "contact", "crystal", ...
  std::string scene_file;  // as given on the command line
  std::string scene_text;  // the YAML text, verbatim
  std::string title;
  std::vector<std::pair<std::string, std::string>> units;  // ("stress", "MPa"), ...
  // Further root attributes (name, text) that say how the results were computed, e.g. the
  // crystal solver's SIMD kernels.
  std::vector<std::pair<std::string, std::string>> computed_with;
  // How the finished file will store its series (model::SeriesCompression: 0 none, 1 ... 9
  // deflate at that level after the byte shuffle), kept until the file is finished, also by a
  // later session (--restart).
  int gzip_level = 0;
  // The scene's base scenes and --set settings (io/scene_compose.hpp), when it has any.
  model::SceneMakeup makeup{};
};

// Root attributes format = "subslip", format_version, program_version, build (SUBSLIP_BUILD:
// "portable" or "native"), the header's computed_with, scene_kind,
// scene_file, title, created (ISO-8601 UTC), run_id (new_run_id), completed = 0, finished = 0,
// layout_complete = 0, write_error (reserved, empty: see mark_write_failed), gzip_level; dataset
// /scene; group /units with one string attribute per unit; for a scene made with base scenes
// or settings, the group /scene_bases (text datasets "1", "2", ... with attribute `file`: the
// base /scene names first) and the string list attribute scene_set (the settings, in
// order). Flushes.
void write_result_header(File& file, const ResultHeader& header);

// Where a result file keeps a scene's bases and settings (write_result_header).
inline constexpr const char* kSceneBases = "scene_bases";
inline constexpr const char* kSceneSettings = "scene_set";

// The bases and settings a result file records (none for a scene of its own).
model::SceneMakeup read_scene_makeup(const Group& root);
// Flushes the layout, then sets layout_complete = 1 and flushes: from here on the run writes
// values only (a restart refuses a file whose layout is not complete).
void mark_layout_complete(File& file);
// Sets completed = 1 and flushes.
void mark_completed(File& file);
// After a failed write: records `message` in the root's reserved `write_error` attribute (in
// place, so that it has a chance on a full disk) and flushes; never throws. False when that
// did not work either.
bool mark_write_failed(File& file, std::string_view message) noexcept;
// Sets completed = 0, empties write_error and flushes (a restart, before it changes anything).
void mark_running(File& file);

// A random identifier of a run (16 hex digits), stored in the result as `run_id` and in its
// restart file, which must name the same run.
std::string new_run_id();

// The `components` attribute of every second-order tensor dataset of a result file: the two
// trailing axes are the tensor's row and column.
inline constexpr const char* kTensorConvention =
    "3x3 tensor: [..., i, j] is the component ij (i the row, j the column); symmetric tensors "
    "are stored in full";

// 3: every tensor [n, 3, 3] / [n, G, 3, 3] (components = kTensorConvention); per-grain rows
// counted apart (grains/row, /progress/grain_rows: output.grains_at); a finished file is
// rewritten with exactly its rows (`finished` = 1); checkpoints in a separate restart file.
// 2: the whole layout is written before the run (summary attributes as placeholders, `failed`
// a fixed-length string, series keep their reservation, checkpoints in /checkpoint).
inline constexpr int kFormatVersion = 3;

}  // namespace subslip::io::h5
