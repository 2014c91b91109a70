#include "subslip/io/result_file.hpp"

#include <cstddef>
#include <map>
#include <optional>
#include <system_error>
#include <vector>

#include "subslip/io/h5_writer.hpp"
#include "subslip/io/result_protocol.hpp"

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

bool finish_result(const fs::path& result) {
  const fs::path temporary = finishing_file_for(result);
  bool completed = true;
  try {
    {
      const h5::File source = h5::File::open_read(result);
      const h5::Group root = source.root();
      const auto names = root.open_group("cases").attribute_strings("names");
      const h5::CaseProgress progress = h5::CaseProgress::open(root);
      // "/cases/<name>/" -> its valid rows, "/cases/<name>/grains/" -> its per-grain ones
      std::map<std::string, std::size_t> rows;
      for (std::size_t k = 0; k < names.size() && k < progress.size(); ++k) {
        rows["/cases/" + names[k] + "/"] = static_cast<std::size_t>(progress.rows(k));
        rows["/cases/" + names[k] + "/grains/"] = static_cast<std::size_t>(progress.grain_rows(k));
        completed = completed && progress.state(k) == h5::CaseState::completed;
      }
      // (A file without the attribute was laid out without compression.)
      const int gzip_level =
          root.has_attribute("gzip_level") ? static_cast<int>(root.attribute_int("gzip_level")) : 0;
      h5::File target = h5::File::create(temporary, true);
      h5::write_exact_copy(source, target, [&](const std::string& path) {
        std::optional<std::size_t> keep;  // the longest prefix that matches
        std::size_t longest = 0;
        for (const auto& [prefix, n] : rows) {
          if (prefix.size() > longest && path.compare(0, prefix.size(), prefix) == 0) {
            keep = n;
            longest = prefix.size();
          }
        }
        return keep;
      }, gzip_level);
      const h5::Group out = target.root();
      out.set_attribute("completed", completed ? 1 : 0);
      out.set_attribute("finished", 1);
      target.close();
    }
    h5::sync_to_disk(temporary);
    fs::rename(temporary, result);
    h5::sync_to_disk(result);
  } catch (...) {
    std::error_code ec;
    fs::remove(temporary, ec);
    throw;
  }
  return completed;
}

void close_and_finish(h5::File& file) {
  const fs::path path = file.path();
  file.close();
  if (every_case_ended(path)) finish_result(path);
}

}  // namespace subslip::io
