#include "subslip/io/result_post.hpp"

#include <algorithm>
#include <cstdio>

#include "result_reading.hpp"
#include "subslip/io/h5_writer.hpp"
#include "subslip/io/result_file.hpp"
#include "subslip/io/text_layout.hpp"

namespace subslip::io::post {

namespace fs = std::filesystem;
using namespace detail;

namespace {

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

}  // namespace subslip::io::post
