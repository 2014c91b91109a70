// `subslip post --quantity`: one CSV table per case of stored and derived quantities
// (io/result_post.hpp; the derived measures are crystal/measures.hpp's).
#include "subslip/io/result_post.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>

#include "result_reading.hpp"
#include "subslip/crystal/measures.hpp"
#include "subslip/io/h5_writer.hpp"
#include "subslip/io/input_error.hpp"

namespace subslip::io::post {

namespace fs = std::filesystem;
using namespace detail;

namespace {

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

// The derived quantities whose datasets case group `g` holds.
std::vector<std::string> detail::derived_available(const h5::Group& g) {
  std::vector<std::string> out;
  for (const auto& d : kDerived) {
    if (std::all_of(d.needs.begin(), d.needs.end(),
                    [&](const char* path) { return node_kind(g, path) == NodeKind::dataset; }))
      out.emplace_back(d.path);
  }
  return out;
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
