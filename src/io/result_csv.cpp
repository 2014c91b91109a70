// `subslip post --csv`: one CSV file per dataset of a result file (io/result_post.hpp).
#include "subslip/io/result_post.hpp"

#include <fstream>
#include <set>

#include "result_reading.hpp"
#include "subslip/io/h5_writer.hpp"
#include "subslip/io/input_error.hpp"

namespace subslip::io::post {

namespace fs = std::filesystem;
using namespace detail;

namespace {

struct Export {
  std::string group;    // absolute path of the group the dataset path is relative to
  std::string dataset;  // relative to `group`
  fs::path output;
  bool one_grain;                         // a per-grain series written for options.grain only
  std::optional<std::size_t> valid_rows;  // of the case's series (see ResultFile)
};

// The case's time series for a series of `rows` rows: a sibling `time`, the case's `time`, or
// `macro/time`.
std::optional<std::string> time_column(const h5::Group& base, const std::string& path,
                                       std::size_t rows, std::optional<std::size_t> valid) {
  const std::string dir = parent(path);
  for (const std::string& t :
       {dir.empty() ? "time" : dir + "/time", std::string("time"), std::string("macro/time")}) {
    if (t == path || node_kind(base, t) != NodeKind::dataset) continue;
    const h5::Dataset d = base.open_dataset(t);
    const auto shape = d.shape();
    if (shape.size() == 1 && usable_rows(d, shape, valid) == rows) return t;
  }
  return std::nullopt;
}

// A per-grain series whose sibling `row` gives the output row of each of its rows (format 3;
// `row` itself too): those rows of the case's macro/time, and the rows themselves (for the
// step column).
struct GrainTimes {
  std::vector<double> time;
  std::vector<long long> row;
  std::string unit;
};
std::optional<GrainTimes> grain_times(const h5::Group& base, const std::string& path,
                                      std::size_t rows) {
  const std::string dir = parent(path);
  const std::string row_path = dir.empty() ? "row" : dir + "/row";
  if (leaf(dir) != "grains" || node_kind(base, row_path) != NodeKind::dataset ||
      node_kind(base, "macro/time") != NodeKind::dataset)
    return std::nullopt;
  const auto row = base.open_dataset(row_path).read_ints();
  const h5::Dataset t = base.open_dataset("macro/time");
  const auto macro_time = t.read_doubles();
  if (row.size() < rows) return std::nullopt;
  GrainTimes out{{},
                 {row.begin(), row.begin() + static_cast<std::ptrdiff_t>(rows)},
                 attribute_or(t, "unit", "")};
  for (long long k : out.row) {
    if (k < 0 || static_cast<std::size_t>(k) >= macro_time.size()) return std::nullopt;
    out.time.push_back(macro_time[static_cast<std::size_t>(k)]);
  }
  return out;
}

// Writes one dataset as CSV. Layouts (n rows, G grains, k components; a tensor's [3, 3] is k = 9
// columns 11 12 ... 33):
//   [n] / [n, k] series        step, time, value(s)
//   [n, G, k] series           step, time, grain, values   (one row per step and grain)
//   [n, G, k] with `grain`     step, time, values of that grain
//   fixed arrays               row (or label), values
// A series has only its first `valid` rows written (when given); the rest are reserved.
void write_table(std::ostream& out, const h5::Group& base, const std::string& path,
                 std::optional<std::size_t> grain, std::optional<std::size_t> valid) {
  const h5::Dataset d = base.open_dataset(path);
  auto shape = table_shape(d);
  const std::size_t rows = usable_rows(d, shape, valid);
  if (shape.empty()) shape = {1};  // a scalar: one row
  const std::vector<double> values = d.read_doubles();
  const std::size_t grains = shape.size() == 3 ? shape[1] : 1;
  const std::size_t k = shape.size() == 1 ? 1 : shape.back();
  const bool series = !d.chunk_shape().empty();
  const std::string unit = attribute_or(d, "unit", "");
  const std::string name = leaf(path);

  std::vector<std::string> header{series ? "step" : "row"};
  const std::optional<GrainTimes> per_grain = series ? grain_times(base, path, rows) : std::nullopt;
  std::optional<std::string> time_path =
      series && !per_grain ? time_column(base, path, rows, valid) : std::nullopt;
  std::vector<double> time;
  if (per_grain) {  // the steps are the output rows these per-grain rows are at
    time = per_grain->time;
    header.push_back(csv_field(headed("time", per_grain->unit)));
  } else if (time_path) {
    const h5::Dataset t = base.open_dataset(*time_path);
    time = t.read_doubles();
    header.push_back(csv_field(headed("time", attribute_or(t, "unit", ""))));
  }
  std::vector<std::string> labels;
  if (!series && has_string_attribute(d, "labels") && d.attribute_size("labels") == rows) {
    labels = d.attribute_strings("labels");
    header.front() = "label";
  }
  const bool long_format = shape.size() == 3 && !grain;
  if (long_format) header.push_back("grain");
  if (shape.size() == 1) {
    header.push_back(csv_field(headed(name, unit)));
  } else {
    for (const auto& c : component_names(base, path, k)) {
      header.push_back(csv_field(headed(name + "_" + c, unit)));
    }
  }
  write_line(out, header);

  std::string line;
  const auto emit = [&](std::size_t row, std::size_t g, bool with_grain) {
    line = !labels.empty() ? csv_field(labels[row])
           : per_grain     ? std::to_string(per_grain->row[row])
                           : std::to_string(row);
    // append(): GCC 12 gives a false -Wrestrict warning on "literal" + std::string&&.
    if (!time.empty()) line.append(",").append(exact_number(time[row]));
    if (with_grain) line.append(",").append(std::to_string(g));
    const std::size_t first = (row * grains + g) * k;
    for (std::size_t c = 0; c < k; ++c) line.append(",").append(exact_number(values[first + c]));
    line.append("\n");
    out << line;
  };
  for (std::size_t row = 0; row < rows; ++row) {
    if (grain) {
      emit(row, *grain, false);
    } else {
      for (std::size_t g = 0; g < grains; ++g) emit(row, g, long_format);
    }
  }
}

// ---------------------------------------------------------------- planning the export

class Planner {
 public:
  Planner(const ResultFile& r, const CsvOptions& o) : r_(r), o_(o) {}

  std::vector<Export> plan() {
    const auto cases = select_cases(r_, o_.case_name);
    if (o_.datasets.empty()) {
      for (const auto& c : cases) add_all(c, "");
    }
    for (const auto& request : o_.datasets) {
      if (!request.empty() && request.front() == '/') {
        add_absolute(request);
      } else {
        for (const auto& c : cases) add_relative(c, request);
      }
    }
    return exports_;
  }

 private:
  static std::string case_group(const std::string& c) { return "/cases/" + c; }

  void add_relative(const std::string& c, const std::string& request) {
    const h5::Group g = r_.root.open_group(case_group(c).substr(1));
    const NodeKind kind = node_kind(g, request);
    if (kind == NodeKind::missing) {
      std::vector<std::string> available;
      collect_datasets(g, "", available);
      throw InputError(
          r_.name, 0, "--dataset",
          "no dataset '" + request + "' in case '" + c + "'; it has: " + join(available, ", "));
    }
    if (kind == NodeKind::group) {
      add_all(c, request);
    } else {
      add(case_group(c), c, request, true);
    }
  }

  void add_absolute(const std::string& request) {
    const NodeKind kind = node_kind(r_.root, request);
    if (kind == NodeKind::missing) {
      throw InputError(r_.name, 0, "--dataset",
                       "no dataset or group '" + request + "' in the file");
    }
    // Under /cases/<case>/...: relative to the case, so that the time column is found.
    const auto parts = split(request, '/');
    if (parts.size() >= 2 && parts[0] == "cases") {
      const std::string rest = join(std::vector<std::string>(parts.begin() + 2, parts.end()), "/");
      if (kind == NodeKind::group) {
        add_all(parts[1], rest);
      } else {
        add(case_group(parts[1]), parts[1], rest, true);
      }
      return;
    }
    if (kind == NodeKind::group) {
      std::vector<std::string> paths;
      collect_datasets(r_.root.open_group(request.substr(1)), "", paths);
      const std::string prefix = join(parts, "/");
      for (const auto& p : paths) add("/", "", prefix + "/" + p, false);
    } else {
      add("/", "", join(parts, "/"), true);
    }
  }

  // Every numeric dataset of case `c` below `sub` ("" for the whole case).
  void add_all(const std::string& c, const std::string& sub) {
    const h5::Group g = r_.root.open_group(case_group(c).substr(1));
    std::vector<std::string> paths;
    if (sub.empty()) {
      collect_datasets(g, "", paths);
    } else {
      collect_datasets(g.open_group(sub), sub, paths);
    }
    for (const auto& p : paths) add(case_group(c), c, p, false);
  }

  // `explicit_request`: named by the user, so text is an error rather than skipped.
  void add(const std::string& group, const std::string& c, const std::string& path,
           bool explicit_request) {
    const h5::Group base =
        group == "/" ? r_.root.open_group(".") : r_.root.open_group(group.substr(1));
    const h5::Dataset d = base.open_dataset(path);
    const std::string full = (group == "/" ? "" : group) + "/" + path;
    const auto cls = d.value_class();
    if (cls != h5::ValueClass::floating && cls != h5::ValueClass::integer) {
      if (!explicit_request) return;
      throw InputError(r_.name, 0, "--dataset",
                       "'" + full + "' holds " +
                           (cls == h5::ValueClass::string ? "text" : "non-numeric data") +
                           ", not numbers; print it with: h5dump -d " + full + " " + r_.name);
    }
    const auto shape = table_shape(d);  // (a tensor's 3x3 counted as one axis)
    if (shape.size() > 3) {
      throw InputError(r_.name, 0, "--dataset",
                       "'" + full + "' has rank " + std::to_string(shape.size()) +
                           "; only ranks 0 to 3 (and tensors of rank 3 and 4) are exported");
    }
    const bool per_grain = shape.size() == 3 && o_.grain.has_value();
    if (per_grain && *o_.grain >= shape[1]) {
      throw InputError(r_.name, 0, "--grain",
                       "grain " + std::to_string(*o_.grain) + " is out of range: '" + full +
                           "' has " + std::to_string(shape[1]) + " grains (0 to " +
                           std::to_string(shape[1] - 1) + ")");
    }
    if (!seen_.insert(full).second) return;  // asked for twice
    std::string stem = c.empty() ? "" : file_safe(c) + "_";
    stem += file_safe(join(split(path, '/'), "_"));
    if (per_grain) stem += "_grain" + std::to_string(*o_.grain);
    std::string file = stem + ".csv";
    for (int n = 2; !names_.insert(file).second; ++n) {
      file = stem + "_" + std::to_string(n) + ".csv";  // two names made the same by file_safe
    }
    const auto valid = c.empty() ? std::nullopt : r_.valid_rows(c, path);
    exports_.push_back({group, path, o_.directory / file, per_grain, valid});
  }

  const ResultFile& r_;
  const CsvOptions& o_;
  std::vector<Export> exports_;
  std::set<std::string> seen_;
  std::set<std::string> names_;
};

}  // namespace

std::vector<fs::path> export_csv(const fs::path& file, const CsvOptions& options) {
  const ResultFile r = open_result(file);
  const std::vector<Export> exports = Planner(r, options).plan();
  for (const auto& e : exports) {
    if (fs::exists(e.output) && !options.force) {
      throw h5::OutputPathError(e.output.string() +
                                ": already exists; use --force to overwrite it");
    }
  }
  prepare_directory(options.directory);
  std::vector<fs::path> written;
  for (const auto& e : exports) {
    std::ofstream out(e.output, std::ios::binary | std::ios::trunc);
    if (!out) throw h5::OutputPathError(e.output.string() + ": cannot be written");
    const h5::Group base =
        e.group == "/" ? r.root.open_group(".") : r.root.open_group(e.group.substr(1));
    write_table(out, base, e.dataset, e.one_grain ? options.grain : std::nullopt, e.valid_rows);
    out.close();
    if (!out) throw h5::OutputPathError(e.output.string() + ": write failed");
    written.push_back(e.output);
  }
  return written;
}

}  // namespace subslip::io::post
