#include "result_reading.hpp"

#include <cctype>
#include <charconv>
#include <sstream>
#include <system_error>
#include <utility>

#include "subslip/io/input_error.hpp"

namespace subslip::io::post::detail {

namespace fs = std::filesystem;

bool has_string_attribute(const h5::Object& o, const std::string& name) {
  return o.has_attribute(name) && o.attribute_class(name) == h5::ValueClass::string;
}

std::string ResultFile::shown_name(const std::string& c) const {
  if (!root.has("cases") || !root.open_group("cases").has(c)) return c;
  const h5::Group g = root.open_group("cases/" + c);
  return has_string_attribute(g, "name") ? g.attribute_string("name") : c;
}

namespace {

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

}  // namespace

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

namespace {

// The group of the case `wanted` names, by its name as shown or as stored; nullopt if none.
std::optional<std::string> find_case(const ResultFile& r, const std::string& wanted) {
  for (const auto& c : r.cases) {
    if (c == wanted || r.shown_name(c) == wanted) return c;
  }
  return std::nullopt;
}

}  // namespace

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

// The rows of `d` to use: for a time series (chunked, extendible) at most `valid`.
std::size_t usable_rows(const h5::Dataset& d, const std::vector<std::size_t>& shape,
                        std::optional<std::size_t> valid) {
  if (shape.empty()) return 1;
  if (!valid || d.chunk_shape().empty()) return shape[0];
  return std::min(shape[0], *valid);
}

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

namespace {

// A second-order tensor dataset of format 3 and later: two trailing axes of 3, and the
// `components` attribute says so (h5::kTensorConvention).
bool is_tensor(const h5::Dataset& d, const std::vector<std::size_t>& shape) {
  const std::size_t n = shape.size();
  return n >= 3 && shape[n - 1] == 3 && shape[n - 2] == 3 &&
         has_string_attribute(d, "components") &&
         d.attribute_string("components") == h5::kTensorConvention;
}

}  // namespace

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

std::string headed(const std::string& name, const std::string& unit) {
  return unit.empty() ? name : name + " [" + unit + "]";
}

void write_line(std::ostream& out, const std::vector<std::string>& fields) {
  for (std::size_t i = 0; i < fields.size(); ++i) out << (i > 0 ? "," : "") << fields[i];
  out << "\n";
}

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

}  // namespace subslip::io::post::detail
