// Reading a subslip result file for `subslip post` (io/result_post.hpp): the file opened with
// its cases and their valid rows, paths inside it, and the pieces the CSV writers share
// (numbers as exact text, column headings, a component's name). Used by result_post.cpp (the
// summary), result_csv.cpp (one CSV per dataset) and result_table.cpp (one table per case).
#pragma once

#include <algorithm>
#include <cstddef>
#include <filesystem>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "subslip/io/h5_writer.hpp"

namespace subslip::io::post::detail {

// /progress (docs/scenes.md): per case, in /cases `names` order, the valid rows of every time
// series of the case and its state. A run that did not finish leaves reserved rows (NaN or
// left over from before a restart) after the valid ones. Older files have no /progress: every
// row is valid and every case that has a group was run.
enum class CaseState { unknown, not_started, running, completed, failed };

struct ResultFile {
  std::string name;  // the path as given, for messages
  h5::File file;
  h5::Group root;
  std::vector<std::string> cases;     // run order
  std::vector<long long> rows;        // /progress/rows, in `cases` order; empty without it
  std::vector<long long> states;      // /progress/state
  std::vector<long long> grain_rows;  // /progress/grain_rows (format 3, crystal); may be empty

  std::optional<std::size_t> index(const std::string& c) const {
    const auto it = std::find(cases.begin(), cases.end(), c);
    if (it == cases.end()) return std::nullopt;
    return static_cast<std::size_t>(it - cases.begin());
  }
  // The valid rows of the case's time series; nullopt: all of them.
  std::optional<std::size_t> valid_rows(const std::string& c) const {
    const auto i = index(c);
    if (!i || *i >= rows.size() || rows[*i] < 0) return std::nullopt;
    return static_cast<std::size_t>(rows[*i]);
  }
  // The valid rows of the series at `path` (relative to the case): per-grain series under
  // grains/ have their own count (output.grains_at).
  std::optional<std::size_t> valid_rows(const std::string& c, const std::string& path) const {
    const auto i = index(c);
    const bool per_grain = path.rfind("grains/", 0) == 0;
    if (per_grain && i && *i < grain_rows.size() && grain_rows[*i] >= 0)
      return static_cast<std::size_t>(grain_rows[*i]);
    return valid_rows(c);
  }
  CaseState state(const std::string& c) const {
    const auto i = index(c);
    if (!i || *i >= states.size() || states[*i] < 0 || states[*i] > 3) return CaseState::unknown;
    return static_cast<CaseState>(states[*i] + 1);
  }
  bool started(const std::string& c) const {
    const bool has_group = root.has("cases") && root.open_group("cases").has(c);
    return has_group && state(c) != CaseState::not_started;
  }
  // The name of case `c` (its group's name) as the run showed it: the group's `name`
  // attribute ("speed=1 mm/min" for the group "speed=1 mm_min"), else `c`.
  std::string shown_name(const std::string& c) const;
};

// The file at `path`, its cases in run order and their progress; InputError when it is missing
// or no subslip result file.
ResultFile open_result(const std::filesystem::path& path);

bool has_string_attribute(const h5::Object& o, const std::string& name);
// The string attribute `name` of `o`, else `dflt`.
std::string attribute_or(const h5::Object& o, const std::string& name, const std::string& dflt);

// `text` cut at `separator`, empty parts dropped; and the reverse.
std::vector<std::string> split(const std::string& text, char separator);
std::string join(const std::vector<std::string>& parts, const std::string& separator);
// The last component of a '/' path, and everything before it ("" for one component).
std::string leaf(const std::string& path);
std::string parent(const std::string& path);

enum class NodeKind { missing, group, dataset };

// What `path` (components separated by '/', relative to `base`) names.
NodeKind node_kind(const h5::Group& base, const std::string& path);

// Every dataset below `g`, as paths relative to `g` prefixed by `prefix`, in creation order.
void collect_datasets(const h5::Group& g, const std::string& prefix, std::vector<std::string>& out);

// The cases to work on (their groups): `wanted` (by its name as shown or as stored), or every
// case that has a group (was started); InputError naming the cases when there is none such.
std::vector<std::string> select_cases(const ResultFile& r, const std::string& wanted);

// The rows of `d` to use: for a time series (chunked, extendible) at most `valid`.
std::size_t usable_rows(const h5::Dataset& d, const std::vector<std::size_t>& shape,
                        std::optional<std::size_t> valid);

// The shape a table sees: a tensor's two trailing axes as one of 9 components (11 12 ... 33).
std::vector<std::size_t> table_shape(const h5::Dataset& d);

// Names of the last axis (k values) of the dataset at `path`, for column headings.
std::vector<std::string> component_names(const h5::Group& base, const std::string& path,
                                         std::size_t k);

// The shortest text that reads back to the same double ("0.1", "-1", "nan").
std::string exact_number(double v);
// A CSV field, quoted where it holds a comma, a quote or a line break.
std::string csv_field(const std::string& s);
// `s` with every character but letters, digits and ._=+- made '_', for file names.
std::string file_safe(const std::string& s);
// A column heading: `name [unit]`, or `name` without a unit.
std::string headed(const std::string& name, const std::string& unit);
void write_line(std::ostream& out, const std::vector<std::string>& fields);

// Creates `dir` when missing; h5::OutputPathError when it cannot.
void prepare_directory(const std::filesystem::path& dir);

// The derived quantities of `subslip post --quantity` whose datasets case group `g` holds
// (result_table.cpp).
std::vector<std::string> derived_available(const h5::Group& g);

}  // namespace subslip::io::post::detail
