#include "subslip/io/result_file.hpp"

#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <system_error>
#include <vector>

#include "subslip/io/h5_writer.hpp"
#include "subslip/io/result_protocol.hpp"
#include "subslip/parallel/team.hpp"

namespace subslip::io {

namespace fs = std::filesystem;

fs::path restart_file_for(const fs::path& result) {
  fs::path p = result;
  if (p.extension() == ".h5") {
    p.replace_extension(".restart.h5");
  } else {
    p += ".restart.h5";
  }
  return p;
}

fs::path finishing_file_for(const fs::path& result) {
  fs::path p = result;
  p += ".finishing";
  return p;
}

bool is_restart_file(const fs::path& path, std::string* run_id) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return false;
  try {
    const h5::File f = h5::File::open_read(path);
    const h5::Group root = f.root();
    if (!root.has_attribute("format") || root.attribute_string("format") != kRestartFormat)
      return false;
    if (run_id != nullptr)
      *run_id = root.has_attribute("run_id") ? root.attribute_string("run_id") : "";
    return true;
  } catch (const h5::Error&) {
    return false;
  }
}

ResultFileStatus result_file_status(const fs::path& result) {
  ResultFileStatus status;
  std::error_code ec;
  if (!fs::exists(result, ec)) return status;
  status.kind = ResultFileKind::other;
  if (!fs::is_regular_file(result, ec)) return status;
  try {
    const h5::File f = h5::File::open_read(result);
    const h5::Group root = f.root();
    if (!root.has_attribute("format") || root.attribute_string("format") != "subslip")
      return status;
    if (root.has_attribute("run_id")) status.run_id = root.attribute_string("run_id");
    const bool finished = root.has_attribute("finished") && root.attribute_int("finished") == 1;
    status.kind = finished ? ResultFileKind::finished : ResultFileKind::working;
    if (!finished && root.has("progress")) {
      const h5::CaseProgress progress = h5::CaseProgress::open(root);
      for (std::size_t k = 0; k < progress.size(); ++k) status.rows += progress.rows(k);
    }
  } catch (const h5::Error&) {
    status.kind = ResultFileKind::other;
  }
  return status;
}

RestartFileRole restart_file_role(const fs::path& result) {
  const fs::path restart = restart_file_for(result);
  std::error_code ec;
  if (!fs::exists(restart, ec)) return RestartFileRole::none;
  std::string run_id;
  if (!is_restart_file(restart, &run_id)) return RestartFileRole::foreign;
  const ResultFileStatus owner = result_file_status(result);
  if (owner.kind == ResultFileKind::none) return RestartFileRole::left_over;
  if (owner.run_id != run_id) return RestartFileRole::foreign;
  return owner.kind == ResultFileKind::working ? RestartFileRole::continues
                                               : RestartFileRole::left_over;
}

bool every_case_ended(const fs::path& result) {
  const h5::File f = h5::File::open_read(result);
  const h5::CaseProgress progress = h5::CaseProgress::open(f.root());
  for (std::size_t k = 0; k < progress.size(); ++k) {
    const auto s = progress.state(k);
    if (s != h5::CaseState::completed && s != h5::CaseState::failed) return false;
  }
  return true;
}

namespace {

// Writes the finished file of the working file `result` at `temporary`: every group,
// attribute and dataset, but the values of the datasets `shares` names, which are made and
// returned (for the ranks to write). True when every case completed.
bool write_finished_copy(const fs::path& result, const fs::path& temporary,
                         const h5::SharesValues& shares, std::vector<h5::SharedDataset>* shared) {
  const h5::File source = h5::File::open_read(result);
  const h5::Group root = source.root();
  const auto names = root.open_group("cases").attribute_strings("names");
  const h5::CaseProgress progress = h5::CaseProgress::open(root);
  // "/cases/<name>/" -> its valid rows, "/cases/<name>/grains/" -> its per-grain ones
  std::map<std::string, std::size_t> rows;
  bool completed = true;
  for (std::size_t k = 0; k < names.size() && k < progress.size(); ++k) {
    rows["/cases/" + names[k] + "/"] = static_cast<std::size_t>(progress.rows(k));
    rows["/cases/" + names[k] + "/grains/"] = static_cast<std::size_t>(progress.grain_rows(k));
    completed = completed && progress.state(k) == h5::CaseState::completed;
  }
  // (A file without the attribute was laid out without compression.)
  const int gzip_level =
      root.has_attribute("gzip_level") ? static_cast<int>(root.attribute_int("gzip_level")) : 0;
  h5::File target = h5::File::create(temporary, true);
  const auto keep = [&](const std::string& path) {
    std::optional<std::size_t> n;  // the longest prefix that matches
    std::size_t longest = 0;
    for (const auto& [prefix, count] : rows) {
      if (prefix.size() > longest && path.compare(0, prefix.size(), prefix) == 0) {
        n = count;
        longest = prefix.size();
      }
    }
    return n;
  };
  auto made = h5::write_exact_copy(source, target, keep, gzip_level, shares);
  if (shared != nullptr) *shared = std::move(made);
  const h5::Group out = target.root();
  out.set_attribute("completed", completed ? 1 : 0);
  out.set_attribute("finished", 1);
  target.close();
  return completed;
}

// The finished file replaces the working one (a rename: a kill leaves one or the other).
void rename_into_place(const fs::path& temporary, const fs::path& result) {
  h5::sync_to_disk(temporary);
  fs::rename(temporary, result);
  h5::sync_to_disk(result);
}

// The datasets of a case's grains (/cases/<name>/grains/...): the ones with a value per grain,
// which the ranks that hold the grains copy together (the few others, such as the slip
// systems, are small: split all the same).
bool of_grains(const std::string& path) {
  const std::size_t at = path.find("/grains/");
  return path.rfind("/cases/", 0) == 0 && at != std::string::npos;
}

// Runs `work` on every rank, then agrees: when it threw anywhere, every rank throws the error
// of the lowest rank it was thrown on, as an h5::Error. Collective.
template <class Work>
void agreed(const parallel::Team& team, Work&& work) {
  std::string action, reason;
  bool failed = false;
  try {
    work();
  } catch (const h5::Error& e) {
    failed = true;
    action = e.action;
    reason = e.reason;
  } catch (const std::exception& e) {  // (a rename refused, no memory for a block)
    failed = true;
    action = e.what();
  }
  std::array<std::int64_t, 1> first{failed ? team.rank() : team.size()};
  team.min(first);
  if (first[0] == team.size()) return;
  const int owner = static_cast<int>(first[0]);
  team.broadcast(action, owner);
  team.broadcast(reason, owner);
  throw h5::Error(action, reason);
}

// The shared datasets' names, one a line, with their axes: "1 /cases/base/grains/stress".
std::string packed(const std::vector<h5::SharedDataset>& shared) {
  std::string text;
  for (const auto& d : shared) text += std::to_string(d.axis) + " " + d.path + "\n";
  return text;
}

std::vector<h5::SharedDataset> unpacked(const std::string& text) {
  std::vector<h5::SharedDataset> shared;
  std::size_t at = 0;
  while (at < text.size()) {
    const std::size_t end = text.find('\n', at);
    shared.push_back({text.substr(at + 2, end - at - 2), text[at] - '0'});
    at = end + 1;
  }
  return shared;
}

// Every rank copies its block of each shared dataset from the working file into the finished
// one, which they open together; a failure on any rank stops every rank at the same step.
void copy_blocks_together(const fs::path& result, const fs::path& temporary,
                          const std::vector<h5::SharedDataset>& shared,
                          const parallel::Team& team) {
  std::optional<h5::File> source, target;
  agreed(team, [&] { source.emplace(h5::File::open_read(result)); });
  const h5::MpiAccess mpi{team.mpi_communicator(), team.rank()};
  agreed(team, [&] { target.emplace(h5::File::open_write(temporary, &mpi)); });
  try {
    for (const h5::SharedDataset& d : shared) {
      std::optional<h5::BlockCopy> copy;
      std::size_t extent = 0;
      agreed(team, [&] {
        const auto shape = target->root().open_dataset(d.path).shape();
        extent = shape.at(static_cast<std::size_t>(d.axis));
        const parallel::Block mine = parallel::block_of(extent, team.rank(), team.size());
        const parallel::Block widest = parallel::block_of(extent, 0, team.size());
        copy.emplace(*source, *target, d, mine.offset, mine.count, widest.count);
      });
      for (std::size_t k = 0; k < copy->steps(); ++k) {
        agreed(team, [&] { copy->read(k); });
        agreed(team, [&] { copy->write(k); });
      }
    }
    agreed(team, [&] { target->close(); });
  } catch (const h5::Error&) {
    target->close_quietly();
    throw;
  }
}

}  // namespace

bool finish_result(const fs::path& result) {
  const fs::path temporary = finishing_file_for(result);
  try {
    const bool completed = write_finished_copy(result, temporary, {}, nullptr);
    rename_into_place(temporary, result);
    return completed;
  } catch (...) {
    std::error_code ec;
    fs::remove(temporary, ec);
    throw;
  }
}

bool finish_result(const fs::path& result, const parallel::Team& team) {
  if (team.size() == 1) return finish_result(result);
  const fs::path temporary = finishing_file_for(result);
  try {
    std::vector<h5::SharedDataset> shared;
    std::string names;
    std::vector<double> completed{0.0};
    agreed(team, [&] {
      if (!team.is_root()) return;
      completed[0] = write_finished_copy(result, temporary, of_grains, &shared) ? 1.0 : 0.0;
      names = packed(shared);
    });
    team.broadcast(names, 0);
    team.broadcast(completed, 0);
    copy_blocks_together(result, temporary, unpacked(names), team);
    agreed(team, [&] {
      if (team.is_root()) rename_into_place(temporary, result);
    });
    return completed[0] != 0.0;
  } catch (...) {
    std::error_code ec;
    if (team.is_root()) fs::remove(temporary, ec);
    throw;
  }
}

void close_and_finish(h5::File& file) {
  const fs::path path = file.path();
  file.close();
  if (every_case_ended(path)) finish_result(path);
}

}  // namespace subslip::io
