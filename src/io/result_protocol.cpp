#include "subslip/io/result_protocol.hpp"

#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <random>
#include <string>
#include <utility>
#include <vector>

namespace subslip::io::h5 {

// ---------------------------------------------------------------- CaseProgress

CaseProgress::CaseProgress(Dataset rows, Dataset state, std::vector<long long> r,
                           std::vector<long long> s)
    : rows_ds_(std::move(rows)),
      state_ds_(std::move(state)),
      rows_(std::move(r)),
      state_(std::move(s)) {}

CaseProgress CaseProgress::create(const Group& root, std::size_t cases, bool grain_rows) {
  const Group g = root.create_group("progress");
  g.set_attribute("description",
                  "how far each case got, in /cases names order; updated as the run goes");
  const std::size_t shape[1] = {cases};
  Dataset rows = g.create_fixed("rows", shape, Type::int64,
                                "valid rows of every time series of the case (later rows of a "
                                "case that did not finish are NaN or left over)");
  rows.set_attribute("unit", "1");
  Dataset state = g.create_fixed("state", shape, Type::int64,
                                 "0 not started, 1 running, 2 completed, 3 failed");
  state.set_attribute("unit", "1");
  std::vector<long long> zeros(cases, 0);
  rows.write(zeros);
  state.write(zeros);
  CaseProgress progress(std::move(rows), std::move(state), zeros, zeros);
  if (grain_rows) {
    Dataset d = g.create_fixed("grain_rows", shape, Type::int64,
                               "valid rows of the case's per-grain series (grains/...), written "
                               "after the rows it counts");
    d.set_attribute("unit", "1");
    d.write(zeros);
    progress.grain_rows_ds_.emplace(std::move(d));
    progress.grain_rows_ = zeros;
  }
  return progress;
}

CaseProgress CaseProgress::open(const Group& root) {
  const Group g = root.open_group("progress");
  Dataset rows = g.open_dataset("rows");
  Dataset state = g.open_dataset("state");
  auto r = rows.read_ints();
  auto s = state.read_ints();
  if (r.size() != s.size()) throw Error("HDF5: /progress/rows and /progress/state differ in size");
  CaseProgress progress(std::move(rows), std::move(state), std::move(r), std::move(s));
  if (g.has("grain_rows")) {
    Dataset d = g.open_dataset("grain_rows");
    progress.grain_rows_ = d.read_ints();
    if (progress.grain_rows_.size() != progress.rows_.size())
      throw Error("HDF5: /progress/grain_rows and /progress/rows differ in size");
    progress.grain_rows_ds_.emplace(std::move(d));
  }
  return progress;
}

void CaseProgress::write_element(const Dataset& d, std::size_t index, long long value) const {
  d.write_element(index, value);
}

void CaseProgress::set_rows(std::size_t index, std::size_t rows) {
  rows_.at(index) = static_cast<long long>(rows);
  write_element(rows_ds_, index, rows_[index]);
}

void CaseProgress::set_grain_rows(std::size_t index, std::size_t rows) {
  if (!grain_rows_ds_) return;
  grain_rows_.at(index) = static_cast<long long>(rows);
  write_element(*grain_rows_ds_, index, grain_rows_[index]);
}

void CaseProgress::set_state(std::size_t index, CaseState state) {
  state_.at(index) = static_cast<long long>(state);
  write_element(state_ds_, index, state_[index]);
}

std::string failure_message(const Group& case_group) {
  return case_group.has_attribute("failed") ? case_group.attribute_string("failed") : "";
}

// ---------------------------------------------------------------- result header

namespace {

// What else the scene was made of (none: nothing is written, as for a scene of its own).
void write_scene_makeup(const Group& root, const model::SceneMakeup& makeup) {
  if (!makeup.bases.empty()) {
    const Group bases = root.create_group(kSceneBases);
    for (std::size_t k = 0; k < makeup.bases.size(); ++k) {
      const auto& [file, text] = makeup.bases[k];
      bases
          .write_text(std::to_string(k + 1), text,
                      k == 0 ? "the base scene /scene names, verbatim"
                             : "the base scene the one before names, verbatim")
          .set_attribute("file", file);
    }
  }
  if (!makeup.settings.empty()) root.set_attribute(kSceneSettings, makeup.settings);
}

}  // namespace

model::SceneMakeup read_scene_makeup(const Group& root) {
  model::SceneMakeup makeup;
  if (root.has(kSceneBases)) {
    const Group bases = root.open_group(kSceneBases);
    for (std::size_t k = 1; bases.has(std::to_string(k)); ++k) {
      const Dataset base = bases.open_dataset(std::to_string(k));
      makeup.bases.emplace_back(base.attribute_string("file"), base.read_string());
    }
  }
  if (root.has_attribute(kSceneSettings)) makeup.settings = root.attribute_strings(kSceneSettings);
  return makeup;
}

void write_result_header(File& file, const ResultHeader& header) {
  const Group root = file.root();
  root.set_attribute("format", "subslip");
  root.set_attribute("format_version", kFormatVersion);
  root.set_attribute("program_version", SUBSLIP_VERSION);
  root.set_attribute("build", SUBSLIP_BUILD);
  for (const auto& [name, text] : header.computed_with) root.set_attribute(name, text);
  root.set_attribute("scene_kind", header.scene_kind);
  root.set_attribute("scene_file", header.scene_file);
  root.set_attribute("title", header.title);
  root.set_attribute("created", iso8601_utc_now());
  root.set_attribute("run_id", new_run_id());
  root.set_attribute("completed", 0);
  root.set_attribute("finished", 0);
  root.set_attribute("layout_complete", 0);
  root.reserve_string_attribute("write_error", kFailureMessageBytes);
  root.set_attribute("gzip_level", header.gzip_level);
  root.write_text("scene", header.scene_text, "the scene file, verbatim");
  write_scene_makeup(root, header.makeup);
  const Group units = root.create_group("units");
  for (const auto& [name, unit] : header.units) units.set_attribute(name, unit);
  file.flush("the result's header");
}

void mark_layout_complete(File& file) {
  file.flush("the result's layout");  // everything it created is in the file before it says so
  file.root().set_attribute("layout_complete", 1);
  file.flush();
}

void mark_completed(File& file) {
  file.root().set_attribute("completed", 1);
  file.flush();
}

void mark_running(File& file) {
  const Group root = file.root();
  root.set_attribute("completed", 0);
  if (root.has_attribute("write_error")) root.write_reserved_string("write_error", "");
  file.flush();
}

bool mark_write_failed(File& file, std::string_view message) noexcept {
  try {
    const Group root = file.root();
    if (root.has_attribute("write_error")) root.write_reserved_string("write_error", message);
    file.flush();
    return true;
  } catch (...) {
    return false;  // the disk refuses this too: the message on the terminal is what is left
  }
}

// ---------------------------------------------------------------- run identifiers

std::string new_run_id() {
  std::random_device device;
  const auto now =
      static_cast<std::uint64_t>(std::chrono::system_clock::now().time_since_epoch().count());
  std::uint64_t id = (static_cast<std::uint64_t>(device()) << 32) ^ device() ^ now ^
                     (static_cast<std::uint64_t>(::getpid()) << 16);
  char text[17];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(id));
  return text;
}

}  // namespace subslip::io::h5
