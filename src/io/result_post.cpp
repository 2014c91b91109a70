#include "subslip/io/result_post.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <system_error>
#include <utility>

#include "subslip/crystal/measures.hpp"
#include "subslip/io/h5_writer.hpp"
#include "subslip/io/input_error.hpp"
#include "subslip/io/result_file.hpp"
#include "subslip/io/result_protocol.hpp"
#include "subslip/io/text_layout.hpp"

namespace subslip::io::post {

namespace fs = std::filesystem;

namespace {

// ---------------------------------------------------------------- opening and navigating

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

bool has_string_attribute(const h5::Object& o, const std::string& name) {
  return o.has_attribute(name) && o.attribute_class(name) == h5::ValueClass::string;
}

std::string ResultFile::shown_name(const std::string& c) const {
  if (!root.has("cases") || !root.open_group("cases").has(c)) return c;
  const h5::Group g = root.open_group("cases/" + c);
  return has_string_attribute(g, "name") ? g.attribute_string("name") : c;
}

// The case names in run order (`/cases` attribute `names`), plus any group it does not list.
std::vector<std::string> case_names(const h5::Group& root) {
  if (!root.has("cases")) return {};
  const h5::Group cases = root.open_group("cases");
  std::vector<std::string> names;
  if (has_string_attribute(cases, "names")) names = cases.attribute_strings("names");
  for (const auto& m : cases.members()) {
    if (std::find(names.begin(), names.end(), m) == names.end()) names.push_back(m);
  }
  return names;
}

// /progress/rows and /progress/state, when the file has both with one entry per case.
void read_progress(ResultFile& r) {
  if (!r.root.has("progress") || !r.root.is_group("progress")) return;
  const h5::Group g = r.root.open_group("progress");
  if (!g.has("rows") || !g.has("state")) return;
  auto rows = g.open_dataset("rows").read_ints();
  auto states = g.open_dataset("state").read_ints();
  if (rows.size() != r.cases.size() || states.size() != r.cases.size()) return;
  r.rows = std::move(rows);
  r.states = std::move(states);
  if (g.has("grain_rows")) {
    auto grain_rows = g.open_dataset("grain_rows").read_ints();
    if (grain_rows.size() == r.cases.size()) r.grain_rows = std::move(grain_rows);
  }
}

ResultFile open_result(const fs::path& path) {
  const std::string name = path.string();
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError(name, 0, "", "no such file");
  if (fs::is_directory(path, ec)) throw InputError(name, 0, "", "is a directory, not a file");
  std::optional<h5::File> file;
  try {
    file.emplace(h5::File::open_read(path));
  } catch (const h5::Error&) {
    throw InputError(name, 0, "", "not an HDF5 file (or not readable)");
  }
  h5::Group root = file->root();
  if (!has_string_attribute(root, "format") || root.attribute_string("format") != "subslip") {
    throw InputError(name, 0, "format",
                     "not a subslip result file (no root attribute format = \"subslip\")");
  }
  ResultFile r{name, std::move(*file), std::move(root), {}, {}, {}, {}};
  r.cases = case_names(r.root);
  read_progress(r);
  return r;
}

std::vector<std::string> split(const std::string& text, char separator) {
  std::vector<std::string> parts;
  std::string part;
  std::istringstream in(text);
  while (std::getline(in, part, separator)) {
    if (!part.empty()) parts.push_back(part);
  }
  return parts;
}

std::string join(const std::vector<std::string>& parts, const std::string& separator) {
  std::string out;
  for (std::size_t i = 0; i < parts.size(); ++i) out += (i > 0 ? separator : "") + parts[i];
  return out;
}

enum class NodeKind { missing, group, dataset };

// What `path` (components separated by '/', relative to `base`) names. Walks one component at
// a time: H5Lexists on a multi-component path fails when an intermediate link is missing.
NodeKind node_kind(const h5::Group& base, const std::string& path) {
  const auto parts = split(path, '/');
  if (parts.empty()) return NodeKind::group;
  std::optional<h5::Group> current;
  const h5::Group* g = &base;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    if (!g->has(parts[i])) return NodeKind::missing;
    const bool group = g->is_group(parts[i]);
    if (i + 1 == parts.size()) return group ? NodeKind::group : NodeKind::dataset;
    if (!group) return NodeKind::missing;
    h5::Group next = g->open_group(parts[i]);
    current = std::move(next);
    g = &*current;
  }
  return NodeKind::missing;
}

// Every dataset below `g`, as paths relative to `g`, in creation order.
void collect_datasets(const h5::Group& g, const std::string& prefix,
                      std::vector<std::string>& out) {
  for (const auto& m : g.members()) {
    const std::string path = prefix.empty() ? m : prefix + "/" + m;
    if (g.is_group(m)) {
      collect_datasets(g.open_group(m), path, out);
    } else {
      out.push_back(path);
    }
  }
}

// The group of the case `wanted` names, by its name as shown or as stored; nullopt if none.
std::optional<std::string> find_case(const ResultFile& r, const std::string& wanted) {
  for (const auto& c : r.cases) {
    if (c == wanted || r.shown_name(c) == wanted) return c;
  }
  return std::nullopt;
}

// The cases to work on (their groups): `wanted`, or every case that has a group (was started).
std::vector<std::string> select_cases(const ResultFile& r, const std::string& wanted) {
  std::vector<std::string> started;
  for (const auto& n : r.cases) {
    if (r.started(n)) started.push_back(n);
  }
  if (wanted.empty()) return started;
  const std::optional<std::string> c = find_case(r, wanted);
  if (c && r.started(*c)) return {*c};
  std::vector<std::string> shown;
  for (const auto& n : r.cases) shown.push_back(r.shown_name(n));
  throw InputError(r.name, 0, "--case",
                   c ? "case '" + wanted + "' was not started (the run stopped before it)"
                     : "no case '" + wanted + "'; the file has: " + join(shown, ", "));
}

std::string attribute_or(const h5::Object& o, const std::string& name, const std::string& dflt) {
  return has_string_attribute(o, name) ? o.attribute_string(name) : dflt;
}

// ---------------------------------------------------------------- summary

// The least room beside its label a wrapped value keeps; with less it starts on the next line.
constexpr int kMinValueColumns = 30;

// `prefix` and, on the lines below, `value` wrapped and indented by six.
void print_below(std::ostream& out, const std::string& prefix, const std::string& value) {
  const std::string indent(6, ' ');
  out << prefix.substr(0, prefix.find_last_not_of(' ') + 1) << "\n";
  if (value.empty()) return;
  for (const auto& line : text::wrap_words(indent + value, text::kTextColumns, indent))
    out << line << "\n";
}

// `prefix` (a label, or the left columns of a table row) and `value`, in lines of at most 80
// columns: the value wrapped at its spaces, continued lines indented to where it starts, or, when
// that leaves under kMinValueColumns, below (print_below).
void print_hanging(std::ostream& out, const std::string& prefix, const std::string& value) {
  const int start = text::display_width(prefix);
  const int room = text::kTextColumns - start;
  if (room < kMinValueColumns && text::display_width(value) > room) {
    print_below(out, prefix, value);
    return;
  }
  const auto lines = text::wrap_words(value, room, "");
  std::string first = prefix + lines.front();
  first.erase(first.find_last_not_of(' ') + 1);
  out << first << "\n";
  for (std::size_t k = 1; k < lines.size(); ++k)
    out << std::string(static_cast<std::size_t>(start), ' ') << lines[k] << "\n";
}

std::string short_number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

// One line for a list of values: "v", "v (x12)" when all equal, "[a, b, c]", or the first six
// and the count.
std::string compact(const std::vector<std::string>& values) {
  if (values.empty()) return "[]";
  if (values.size() == 1) return values.front();
  if (std::all_of(values.begin(), values.end(), [&](const auto& v) { return v == values[0]; })) {
    return values.front() + " (x" + std::to_string(values.size()) + ")";
  }
  if (values.size() <= 9) return "[" + join(values, ", ") + "]";
  const std::vector<std::string> head(values.begin(), values.begin() + 6);
  return "[" + join(head, ", ") + ", ...] (" + std::to_string(values.size()) + " values)";
}

std::string attribute_text(const h5::Object& o, const std::string& name) {
  switch (o.attribute_class(name)) {
    case h5::ValueClass::string:
      return compact(o.attribute_strings(name));
    case h5::ValueClass::floating:
    case h5::ValueClass::integer: {
      std::vector<std::string> values;
      for (double v : o.attribute_doubles(name)) values.push_back(short_number(v));
      return compact(values);
    }
    case h5::ValueClass::other:
      break;
  }
  return "(unsupported type)";
}

bool ends_with(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

std::string shape_text(const std::vector<std::size_t>& shape) {
  std::vector<std::string> dims;
  for (auto d : shape) dims.push_back(std::to_string(d));
  return "[" + join(dims, ", ") + "]";
}

// Whether the file is finished (each series exactly its rows) or a working file a run can
// continue, and what its restart file beside it is.
void print_finished(std::ostream& out, const ResultFile& r) {
  const h5::Group& root = r.root;
  const bool finished = root.has_attribute("finished") &&
                        root.attribute_class("finished") != h5::ValueClass::string &&
                        root.attribute_double("finished") == 1.0;
  print_hanging(out, "finished:    ",
                finished ? "yes (every series holds exactly its valid rows)"
                         : "NO: a working file (series hold reserved rows; /progress counts the "
                           "valid ones); subslip run --restart " +
                               r.name + " continues or finishes it");
  const std::filesystem::path restart = restart_file_for(r.name);
  switch (restart_file_role(r.name)) {
    case RestartFileRole::continues:
      print_hanging(out, "restart:     ", restart.string() + " (the checkpoints of this run)");
      break;
    case RestartFileRole::left_over:
      print_hanging(
          out, "restart:     ",
          restart.string() + " (left over from this finished run; no run continues it: delete it)");
      break;
    case RestartFileRole::none:
    case RestartFileRole::foreign:
      break;
  }
}

// The base scenes and settings the scene was made of (none: nothing printed).
void print_scene_makeup(std::ostream& out, const model::SceneMakeup& makeup) {
  for (std::size_t k = 0; k < makeup.bases.size(); ++k) {
    print_hanging(out, "base scene:  ",
                  makeup.bases[k].first + " (/scene_bases/" + std::to_string(k + 1) + ")");
  }
  for (const std::string& setting : makeup.settings) print_hanging(out, "set:         ", setting);
}

void print_file_header(std::ostream& out, const ResultFile& r) {
  const h5::Group& root = r.root;
  const auto text = [&](const char* name) { return attribute_or(root, name, "-"); };
  const std::string version =
      root.has_attribute("format_version") ? attribute_text(root, "format_version") : "-";
  print_hanging(out, "file:        ", r.name);
  print_hanging(
      out, "format:      ",
      "subslip, format_version " + version + ", written by subslip " + text("program_version"));
  if (root.has_attribute("build")) {
    // How it was computed (results of builds or kernels that round differently differ by
    // round-off).
    std::string how = text("build") + " build";
    if (root.has_attribute("simd_kernels")) how += ", SIMD kernels " + text("simd_kernels");
    print_hanging(out, "computed:    ", how);
  }
  print_hanging(out,
                "scene kind:  ", text("scene_kind") + " (scene file " + text("scene_file") + ")");
  print_hanging(out, "title:       ", text("title"));
  print_hanging(out, "created:     ", text("created"));
  const bool completed = root.has_attribute("completed") &&
                         root.attribute_class("completed") != h5::ValueClass::string &&
                         root.attribute_double("completed") == 1.0;
  print_hanging(out, "completed:   ",
                completed ? "yes"
                          : "NO (the run was interrupted, failed or is still running; see the "
                            "cases)");
  print_finished(out, r);
  // Why a failed write stopped the run (a full disk); the attribute is empty otherwise.
  const std::string write_error = text("write_error");
  if (!write_error.empty() && write_error != "-") print_hanging(out, "write error: ", write_error);
  std::vector<std::string> units;
  if (root.has("units")) {
    const h5::Group u = root.open_group("units");
    for (const auto& n : u.attribute_names()) units.push_back(n + " " + attribute_text(u, n));
  }
  print_hanging(out, "units:       ", units.empty() ? "-" : join(units, ", "));
  if (root.has("scene")) out << "scene:       /scene (the scene YAML; h5dump -d /scene FILE)\n";
  print_scene_makeup(out, h5::read_scene_makeup(root));
}

void print_case_attributes(std::ostream& out, const h5::Group& g) {
  std::vector<std::pair<std::string, std::string>> lines;
  for (const auto& n : g.attribute_names()) {
    if (n == "name" || n == "index" || ends_with(n, ".unit")) continue;
    std::string value = attribute_text(g, n);
    // (a swept value stored as text is as written, its own unit included: "1 mm/min")
    const bool text = g.attribute_class(n) == h5::ValueClass::string;
    const std::string unit = text ? "" : attribute_or(g, n + ".unit", "");
    if (!unit.empty() && unit != "1") value += " " + unit;
    lines.emplace_back(n, value);
  }
  std::size_t width = 0;
  for (const auto& l : lines) width = std::max(width, l.first.size());
  out << "  attributes:\n";
  for (const auto& [name, value] : lines)
    print_hanging(out, "    " + name + std::string(width - name.size(), ' ') + " = ", value);
}

// The rows of `d` to use: for a time series (chunked, extendible) at most `valid`.
std::size_t usable_rows(const h5::Dataset& d, const std::vector<std::size_t>& shape,
                        std::optional<std::size_t> valid) {
  if (shape.empty()) return 1;
  if (!valid || d.chunk_shape().empty()) return shape[0];
  return std::min(shape[0], *valid);
}

void print_case_datasets(std::ostream& out, const h5::Group& g, const ResultFile& r,
                         const std::string& c) {
  std::vector<std::string> paths;
  collect_datasets(g, "", paths);
  struct Row {
    std::string path, shape, unit, description;
  };
  std::vector<Row> rows;
  std::size_t w_path = 0, w_shape = 0, w_unit = 0;
  for (const auto& p : paths) {
    const h5::Dataset d = g.open_dataset(p);
    const bool text = d.value_class() == h5::ValueClass::string;
    auto shape = d.shape();
    if (!shape.empty()) shape[0] = usable_rows(d, shape, r.valid_rows(c, p));
    // Appended, not "[" + unit + "]": GCC 12 at -O3 reports a false overflow in that
    // operator+ once the attribute's read is inlined here.
    std::string unit = "[";
    unit += attribute_or(d, "unit", "-");
    unit += ']';
    Row row{p, text ? "text" : shape_text(shape), std::move(unit),
            attribute_or(d, "description", "")};
    w_path = std::max(w_path, row.path.size());
    w_shape = std::max(w_shape, row.shape.size());
    w_unit = std::max(w_unit, row.unit.size());
    rows.push_back(std::move(row));
  }
  out << "  datasets:\n";
  // Descriptions beside the columns when they fit there, else all below theirs (a table that
  // changes its layout from row to row reads badly).
  const std::size_t columns = 4 + w_path + 2 + w_shape + 2 + w_unit + 2;
  const int room = text::kTextColumns - static_cast<int>(columns);
  const bool beside =
      room >= kMinValueColumns || std::all_of(rows.begin(), rows.end(), [&](const Row& r) {
        return text::display_width(r.description) <= room;
      });
  for (const auto& r : rows) {
    const std::string prefix = "    " + r.path + std::string(w_path - r.path.size() + 2, ' ') +
                               r.shape + std::string(w_shape - r.shape.size() + 2, ' ') + r.unit +
                               std::string(w_unit - r.unit.size() + 2, ' ');
    if (beside) {
      print_hanging(out, prefix, r.description);
    } else {
      print_below(out, prefix, r.description);
    }
  }
}

// ": FAILED", ": RUNNING or interrupted, N valid rows", or "" for a completed case.
std::string case_state_text(const ResultFile& r, const std::string& c, const h5::Group& g) {
  const auto rows = r.valid_rows(c);
  const std::string valid = rows ? ", " + std::to_string(*rows) + " valid rows" : "";
  switch (r.state(c)) {
    case CaseState::failed:
      return ": FAILED" + valid;
    case CaseState::running:
      return ": RUNNING or interrupted" + valid;
    case CaseState::unknown:
      return h5::failure_message(g).empty() ? "" : ": FAILED";
    case CaseState::not_started:
    case CaseState::completed:
      break;
  }
  return "";
}

// ---------------------------------------------------------------- CSV

// The shortest text that reads back to the same double ("0.1", "-1", "nan").
std::string exact_number(double v) {
  char buf[64];
  const auto result = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, result.ptr);
}

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string quoted = "\"";
  for (char c : s) quoted += (c == '"') ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

// Letters, digits and ._=+- are kept in file names; anything else becomes '_'.
std::string file_safe(const std::string& s) {
  std::string out = s;
  for (char& c : out) {
    const bool keep = std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' ||
                      c == '=' || c == '+' || c == '-';
    if (!keep) c = '_';
  }
  return out;
}

std::string leaf(const std::string& path) {
  const auto parts = split(path, '/');
  return parts.empty() ? path : parts.back();
}

std::string parent(const std::string& path) {
  const auto slash = path.rfind('/');
  return slash == std::string::npos ? "" : path.substr(0, slash);
}

struct Export {
  std::string group;    // absolute path of the group the dataset path is relative to
  std::string dataset;  // relative to `group`
  fs::path output;
  bool one_grain;                         // a per-grain series written for options.grain only
  std::optional<std::size_t> valid_rows;  // of the case's series (see ResultFile)
};

// A second-order tensor dataset of format 3 and later: two trailing axes of 3, and the
// `components` attribute says so (h5::kTensorConvention).
bool is_tensor(const h5::Dataset& d, const std::vector<std::size_t>& shape) {
  const std::size_t n = shape.size();
  return n >= 3 && shape[n - 1] == 3 && shape[n - 2] == 3 &&
         has_string_attribute(d, "components") &&
         d.attribute_string("components") == h5::kTensorConvention;
}

// The shape a table sees: a tensor's two trailing axes as one of 9 components (11 12 ... 33).
std::vector<std::size_t> table_shape(const h5::Dataset& d) {
  auto shape = d.shape();
  if (is_tensor(d, shape)) {
    shape.pop_back();
    shape.back() = 9;
  }
  return shape;
}

// Names of the last axis (k values): 11 12 ... 33 for a tensor, the slip-system labels when the
// `components` attribute says "per slip system", the words of `components` / `layout` (after a
// ':', format 2) when they are k, the contact layouts of docs/scenes.md, else 0..k-1.
std::vector<std::string> component_names(const h5::Group& base, const std::string& path,
                                         std::size_t k) {
  const h5::Dataset d = base.open_dataset(path);
  if (is_tensor(d, d.shape())) return {"11", "12", "13", "21", "22", "23", "31", "32", "33"};
  const std::string dir = parent(path);
  for (const char* attr : {"components", "layout"}) {
    if (!has_string_attribute(d, attr)) continue;
    std::string text = d.attribute_string(attr);
    const std::string systems = dir.empty() ? "slip_systems" : dir + "/slip_systems";
    if (text.find("slip_systems") != std::string::npos &&
        node_kind(base, systems) == NodeKind::dataset) {
      const h5::Dataset s = base.open_dataset(systems);
      if (has_string_attribute(s, "labels") && s.attribute_size("labels") == k) {
        return s.attribute_strings("labels");
      }
    }
    if (const auto colon = text.rfind(':'); colon != std::string::npos) text.erase(0, colon + 1);
    auto words = split(text, ' ');
    if (words.size() == k) return words;
  }
  const std::string name = leaf(path);
  if (name == "slip" && k == 2) return {"x", "y"};
  if (name == "traction" && k == 3) return {"x", "y", "n"};
  if (name == "slip_systems" && k == 6) return {"s1", "s2", "s3", "m1", "m2", "m3"};
  std::vector<std::string> out;
  for (std::size_t i = 0; i < k; ++i) out.push_back(std::to_string(i));
  return out;
}

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

std::string headed(const std::string& name, const std::string& unit) {
  return unit.empty() ? name : name + " [" + unit + "]";
}

void write_line(std::ostream& out, const std::vector<std::string>& fields) {
  for (std::size_t i = 0; i < fields.size(); ++i) out << (i > 0 ? "," : "") << fields[i];
  out << "\n";
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

void prepare_directory(const fs::path& dir) {
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec)) {
    throw h5::OutputPathError(dir.string() + ": exists and is not a directory");
  }
  fs::create_directories(dir, ec);
  if (ec) {
    throw h5::OutputPathError(dir.string() + ": cannot create the directory (" + ec.message() +
                              ")");
  }
}

// ---------------------------------------------------------------- one table per case

// A quantity of a case table, read or computed: [rows, k] or, per grain, [rows, grains, k]; its
// rows are the case's output rows, or its per-grain rows (`grain_rows`: output.grains_at may
// write those at fewer rows; grains/row says which).
struct Quantity {
  std::string name;  // the column names' stem ("stress", "von_mises_stress")
  std::string unit;
  std::vector<std::string> components;  // one column name suffix each; empty: one column
  bool grain_rows = false;
  bool per_grain = false;
  std::size_t rows = 0, grains = 1;
  std::vector<double> values;

  std::size_t k() const { return components.empty() ? 1 : components.size(); }
};

// The case a table is made of: its group and how many rows of its series are valid.
struct CaseSource {
  const ResultFile& r;
  std::string name;
  h5::Group group;

  bool has(const std::string& path) const { return node_kind(group, path) == NodeKind::dataset; }
  std::optional<std::size_t> valid(const std::string& path) const {
    return r.valid_rows(name, path);
  }
  [[noreturn]] void fail(const std::string& what) const {
    throw InputError(r.name, 0, "--quantity", "case '" + name + "': " + what);
  }
  // `path`, else an error naming the scene's output setting that writes it.
  void need(const std::string& path, const std::string& for_what) const {
    if (has(path)) return;
    const auto slash = path.find('/');
    const std::string group_name = path.substr(0, slash), field = path.substr(slash + 1);
    const bool own_field = field != "weight" && field != "slip_systems";
    fail(for_what + " needs " + path + ", which the file does not hold; ask the scene for it: " +
         (own_field ? "output: {" + group_name + ": [" + field + "]}"
                    : "output: {grains: [...]} (any grain field)"));
  }
};

// A stored time series of the case, cut to its valid rows; a tensor's [3, 3] as 9 columns.
Quantity stored(const CaseSource& c, const std::string& path) {
  const h5::Dataset d = c.group.open_dataset(path);
  const auto cls = d.value_class();
  if (cls != h5::ValueClass::floating && cls != h5::ValueClass::integer)
    c.fail("'" + path + "' holds no numbers");
  if (d.chunk_shape().empty())
    c.fail("'" + path + "' is no time series (one value per output row); export it with --dataset");
  const auto shape = table_shape(d);
  if (shape.size() > 3) c.fail("'" + path + "' has more axes than a table can show");
  Quantity q;
  q.name = leaf(path);
  q.unit = attribute_or(d, "unit", "");
  q.rows = usable_rows(d, shape, c.valid(path));
  q.per_grain = shape.size() == 3;
  q.grain_rows = path.rfind("grains/", 0) == 0;
  q.grains = q.per_grain ? shape[1] : 1;
  if (shape.size() >= 2) q.components = component_names(c.group, path, shape.back());
  q.values = d.read_doubles();
  q.values.resize(q.rows * q.grains * q.k());
  return q;
}

// The derived quantities a table offers, each from stored series (crystal/measures.hpp), and
// the datasets each needs.
struct DerivedQuantity {
  const char* path;
  const char* what;  // for the summary and messages
  std::vector<const char*> needs;
};
const std::vector<DerivedQuantity> kDerived = {
    {"macro/von_mises_stress", "von Mises stress of macro/stress", {"macro/stress"}},
    {"macro/von_mises_strain", "von Mises strain of macro/strain", {"macro/strain"}},
    {"macro/equivalent_plastic_strain",
     "grain-weighted mean of grains/equivalent_plastic_strain (at the per-grain rows)",
     {"grains/slip", "grains/slip_systems", "grains/weight"}},
    {"macro/slip_activity",
     "grain-weighted mean |slip rate| per slip system (at the per-grain rows)",
     {"grains/slip_rate", "grains/weight"}},
    {"grains/von_mises_stress",
     "von Mises stress of each grain's grains/stress",
     {"grains/stress"}},
    {"grains/equivalent_plastic_strain",
     "accumulated sqrt(2/3 dE:dE) of each grain, dE from grains/slip between output rows",
     {"grains/slip", "grains/slip_systems"}},
    {"grains/slip_activity", "|slip rate| per slip system of each grain", {"grains/slip_rate"}},
};

// The derived quantities whose datasets case group `g` holds.
std::vector<std::string> derived_available(const h5::Group& g) {
  std::vector<std::string> out;
  for (const auto& d : kDerived) {
    if (std::all_of(d.needs.begin(), d.needs.end(),
                    [&](const char* path) { return node_kind(g, path) == NodeKind::dataset; }))
      out.emplace_back(d.path);
  }
  return out;
}

std::vector<std::string> derived_names() {
  std::vector<std::string> out;
  for (const auto& d : kDerived) out.emplace_back(d.path);
  return out;
}

Quantity von_mises(const CaseSource& c, const std::string& source, bool stress) {
  c.need(source, "von Mises " + std::string(stress ? "stress" : "strain"));
  Quantity q = stored(c, source);
  if (q.k() != 9) c.fail(source + " is no 3x3 tensor");
  q.values = stress ? crystal::von_mises_stress(q.values) : crystal::von_mises_strain(q.values);
  q.name = stress ? "von_mises_stress" : "von_mises_strain";
  if (!stress) q.unit = "1";
  q.components.clear();
  return q;
}

std::vector<double> grain_weights(const CaseSource& c, const std::string& for_what) {
  c.need("grains/weight", for_what);
  return c.group.open_dataset("grains/weight").read_doubles();
}

Quantity equivalent_plastic_strain(const CaseSource& c, bool aggregate) {
  const std::string what = "the equivalent plastic strain";
  c.need("grains/slip", what);
  c.need("grains/slip_systems", what);
  Quantity q = stored(c, "grains/slip");
  const auto systems = c.group.open_dataset("grains/slip_systems").read_doubles();
  q.values = crystal::equivalent_plastic_strain(q.values, q.rows, q.grains, systems);
  q.name = "equivalent_plastic_strain";
  q.unit = "1";
  q.components.clear();
  if (aggregate) {
    q.values = crystal::weighted_mean_abs(q.values, q.rows, q.grains, grain_weights(c, what));
    q.per_grain = false;
    q.grains = 1;
  }
  return q;
}

Quantity slip_activity(const CaseSource& c, bool aggregate) {
  const std::string what = "the slip activity";
  c.need("grains/slip_rate", what);
  Quantity q = stored(c, "grains/slip_rate");
  q.name = "slip_activity";
  if (aggregate) {
    q.values = crystal::weighted_mean_abs(q.values, q.rows, q.grains, grain_weights(c, what));
    q.per_grain = false;
    q.grains = 1;
  } else {
    for (double& v : q.values) v = std::abs(v);
  }
  return q;
}

Quantity derived(const CaseSource& c, const std::string& path) {
  if (path == "macro/von_mises_stress") return von_mises(c, "macro/stress", true);
  if (path == "macro/von_mises_strain") return von_mises(c, "macro/strain", false);
  if (path == "grains/von_mises_stress") return von_mises(c, "grains/stress", true);
  if (path == "macro/equivalent_plastic_strain") return equivalent_plastic_strain(c, true);
  if (path == "grains/equivalent_plastic_strain") return equivalent_plastic_strain(c, false);
  if (path == "macro/slip_activity") return slip_activity(c, true);
  return slip_activity(c, false);
}

// Every time series of the case, for the message on an unknown name.
std::vector<std::string> table_names(const CaseSource& c) {
  std::vector<std::string> paths, out;
  collect_datasets(c.group, "", paths);
  for (const auto& p : paths) {
    if (!c.group.open_dataset(p).chunk_shape().empty()) out.push_back(p);
  }
  for (const auto& d : derived_names()) out.push_back(d);
  return out;
}

Quantity quantity(const CaseSource& c, const std::string& path) {
  const auto names = derived_names();
  if (std::find(names.begin(), names.end(), path) != names.end()) {
    if (attribute_or(c.r.root, "scene_kind", "") == "contact")
      c.fail("'" + path + "' is derived from a crystal run's series; this is a contact result");
    return derived(c, path);
  }
  if (!c.has(path)) {
    c.fail("no quantity '" + path +
           "'; stored series and derived quantities: " + join(table_names(c), ", "));
  }
  return stored(c, path);
}

// Column names: each quantity's own (`stress`, `von_mises_stress`), or, where two share one
// (macro/stress and grains/stress), the path with '_' for '/' (`macro_stress`, `grains_stress`).
// `paths` are the quantities' names as asked, in order, duplicates already dropped from `qs`.
void name_columns(std::vector<Quantity>& qs, const std::vector<std::string>& paths) {
  std::vector<std::string> unique_paths;
  for (const auto& p : paths) {
    if (std::find(unique_paths.begin(), unique_paths.end(), p) == unique_paths.end())
      unique_paths.push_back(p);
  }
  std::vector<bool> shared(qs.size());
  for (std::size_t i = 0; i < qs.size(); ++i) {
    shared[i] = std::count_if(qs.begin(), qs.end(),
                              [&](const Quantity& q) { return q.name == qs[i].name; }) > 1;
  }
  for (std::size_t i = 0; i < qs.size(); ++i) {
    if (shared[i]) qs[i].name = file_safe(join(split(unique_paths[i], '/'), "_"));
  }
}

// The table's rows: the output rows of each table row (the `step` column) and, when a quantity
// is on the per-grain rows, the per-grain row each one is.
struct TableRows {
  std::vector<std::size_t> step;  // output (macro) row
  bool on_grain_rows = false;
};

TableRows table_rows(const CaseSource& c, const std::vector<Quantity>& qs) {
  TableRows t;
  t.on_grain_rows =
      std::any_of(qs.begin(), qs.end(), [](const Quantity& q) { return q.grain_rows; });
  std::size_t rows = qs.front().rows;
  for (const auto& q : qs) {
    if (q.grain_rows == t.on_grain_rows) rows = std::min(rows, q.rows);
  }
  std::vector<long long> at;
  if (t.on_grain_rows && c.has("grains/row")) at = c.group.open_dataset("grains/row").read_ints();
  for (std::size_t i = 0; i < rows; ++i) {
    t.step.push_back(i < at.size() ? static_cast<std::size_t>(std::max(at[i], 0LL)) : i);
  }
  for (const auto& q : qs) {  // a macro quantity needs every output row a grain row is at
    if (!q.grain_rows && !t.step.empty() && t.step.back() >= q.rows)
      c.fail("'" + q.name + "' has fewer rows than the per-grain rows refer to");
  }
  return t;
}

// The time column: macro/time (crystal) or time (contact), when the case has one.
std::optional<Quantity> time_of(const CaseSource& c) {
  for (const char* path : {"macro/time", "time"}) {
    if (c.has(path)) return stored(c, path);
  }
  return std::nullopt;
}

std::vector<std::string> table_header(const std::optional<Quantity>& time, bool grain_column,
                                      const std::vector<Quantity>& qs) {
  std::vector<std::string> header{"step"};
  if (time) header.push_back(csv_field(headed("time", time->unit)));
  if (grain_column) header.push_back("grain");
  for (const auto& q : qs) {
    if (q.components.empty()) header.push_back(csv_field(headed(q.name, q.unit)));
    for (const auto& comp : q.components)
      header.push_back(csv_field(headed(q.name + "_" + comp, q.unit)));
  }
  return header;
}

// A case's table as it will be written, every row and grain checked.
struct TablePlan {
  TableRows rows;
  std::optional<Quantity> time;
  std::size_t grains = 1;  // of the per-grain quantities
  std::optional<std::size_t> grain;
  bool long_format() const { return grains > 1 && !grain; }
};

TablePlan plan_table(const CaseSource& c, const std::vector<Quantity>& qs,
                     std::optional<std::size_t> grain) {
  TablePlan plan{table_rows(c, qs), time_of(c), 1, grain};
  if (plan.time && !plan.rows.step.empty() && plan.rows.step.back() >= plan.time->rows)
    plan.time.reset();  // the per-grain rows refer past the valid times: no time column
  for (const auto& q : qs) {
    if (!q.per_grain) continue;
    if (grain && *grain >= q.grains) {
      throw InputError(c.r.name, 0, "--grain",
                       "grain " + std::to_string(*grain) + " is out of range: case '" + c.name +
                           "' has " + std::to_string(q.grains) + " grains (0 to " +
                           std::to_string(q.grains - 1) + ")");
    }
    plan.grains = q.grains;
  }
  return plan;
}

// Writes the table of one case: one line per table row, or per table row and grain when a
// per-grain quantity is shown for every grain (no `grain` given).
void write_case_table(std::ostream& out, const TablePlan& plan, const std::vector<Quantity>& qs) {
  const bool long_format = plan.long_format();
  write_line(out, table_header(plan.time, long_format, qs));
  std::string line;
  const auto& step = plan.rows.step;
  for (std::size_t i = 0; i < step.size(); ++i) {
    for (std::size_t g = 0; g < (long_format ? plan.grains : 1); ++g) {
      line = std::to_string(step[i]);
      if (plan.time) line.append(",").append(exact_number(plan.time->values[step[i]]));
      if (long_format) line.append(",").append(std::to_string(g));
      for (const auto& q : qs) {
        const std::size_t row = q.grain_rows ? i : step[i];
        const std::size_t at_grain = q.per_grain ? plan.grain.value_or(g) : 0;
        const std::size_t first = (row * q.grains + at_grain) * q.k();
        for (std::size_t k = 0; k < q.k(); ++k)
          line.append(",").append(exact_number(q.values[first + k]));
      }
      out << line << "\n";
    }
  }
}

}  // namespace

void print_summary(std::ostream& out, const fs::path& file, const std::string& case_name) {
  const ResultFile r = open_result(file);
  const auto selected = select_cases(r, case_name);
  print_file_header(out, r);
  const auto& all = r.cases;
  std::vector<std::string> shown;
  for (const auto& c : all) shown.push_back(r.shown_name(c));
  print_hanging(out, "cases:       ",
                std::to_string(all.size()) + (all.empty() ? "" : ": " + join(shown, ", ")));
  for (const auto& c : selected) {
    const h5::Group g = r.root.open_group("cases/" + c);
    const std::string name = r.shown_name(c);
    std::vector<std::string> where;
    if (name != c) where.push_back("group /cases/" + c);  // a '/' of the name, stored as '_'
    if (g.has_attribute("index")) where.push_back("index " + attribute_text(g, "index"));
    out << "\ncase " << name << (where.empty() ? "" : " (" + join(where, ", ") + ")")
        << case_state_text(r, c, g) << "\n";
    print_case_attributes(out, g);
    print_case_datasets(out, g, r, c);
    const auto derived = derived_available(g);
    if (!derived.empty()) print_hanging(out, "  derived (post --quantity): ", join(derived, ", "));
  }
  for (const auto& c : all) {
    if (std::find(selected.begin(), selected.end(), c) == selected.end() && case_name.empty()) {
      out << "\ncase " << r.shown_name(c) << ": not started\n";
    }
  }
}

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

std::vector<fs::path> export_table(const fs::path& file, const TableOptions& options) {
  const ResultFile r = open_result(file);
  if (options.quantities.empty())
    throw InputError(r.name, 0, "--quantity", "name at least one quantity");
  struct Planned {
    fs::path output;
    std::vector<Quantity> quantities;
    TablePlan plan;
  };
  std::vector<Planned> planned;
  for (const auto& c : select_cases(r, options.case_name)) {
    const CaseSource source{r, c, r.root.open_group("cases/" + c)};
    Planned p{options.directory / (file_safe(c) + ".csv"), {}, {}};
    std::set<std::string> asked;
    for (const auto& name : options.quantities) {
      if (asked.insert(name).second) p.quantities.push_back(quantity(source, name));
    }
    name_columns(p.quantities, options.quantities);
    p.plan = plan_table(source, p.quantities, options.grain);
    if (fs::exists(p.output) && !options.force) {
      throw h5::OutputPathError(p.output.string() +
                                ": already exists; use --force to overwrite it");
    }
    planned.push_back(std::move(p));
  }
  prepare_directory(options.directory);
  std::vector<fs::path> written;
  for (const auto& p : planned) {
    std::ofstream out(p.output, std::ios::binary | std::ios::trunc);
    if (!out) throw h5::OutputPathError(p.output.string() + ": cannot be written");
    write_case_table(out, p.plan, p.quantities);
    out.close();
    if (!out) throw h5::OutputPathError(p.output.string() + ": write failed");
    written.push_back(p.output);
  }
  return written;
}

std::vector<std::pair<std::string, std::string>> derived_quantities() {
  std::vector<std::pair<std::string, std::string>> out;
  for (const auto& d : kDerived) out.emplace_back(d.path, d.what);
  return out;
}

}  // namespace subslip::io::post
