#include "subslip/io/fit_file.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <functional>
#include <sstream>
#include <string_view>
#include <vector>

#include "subslip/io/crystal_scene.hpp"
#include "subslip/io/law_block.hpp"
#include "subslip/io/scene_common.hpp"
#include "subslip/law/parameter_table.hpp"

namespace subslip::io {

namespace {

std::string trimmed(std::string_view s) {
  const auto first = s.find_first_not_of(" \t\r");
  if (first == std::string_view::npos) return {};
  const auto last = s.find_last_not_of(" \t\r");
  return std::string(s.substr(first, last - first + 1));
}

std::vector<std::string> split_fields(const std::string& line) {
  std::vector<std::string> fields;
  std::stringstream in(line);
  std::string field;
  while (std::getline(in, field, ',')) fields.push_back(trimmed(field));
  if (!line.empty() && line.back() == ',') fields.emplace_back();
  return fields;
}

// A header field "name [unit]": the name and the unit ("" without brackets).
std::pair<std::string, std::string> name_and_unit(const std::string& field) {
  const auto open = field.find('[');
  if (open == std::string::npos || field.back() != ']') return {field, ""};
  return {trimmed(field.substr(0, open)), trimmed(field.substr(open + 1, field.size() - open - 2))};
}

struct Column {
  std::size_t index;
  std::string unit;
};

Column find_column(const std::vector<std::string>& header, std::string_view name,
                   const std::string& file, int line, std::string_view example) {
  for (std::size_t k = 0; k < header.size(); ++k) {
    const auto [n, unit] = name_and_unit(header[k]);
    if (n == name) return {k, unit};
  }
  std::string has;
  for (const auto& h : header) has += (has.empty() ? "'" : ", '") + h + "'";
  throw InputError(
      file, line, std::string(name),
      "missing column (write it as '" + std::string(example) + "'); the header has " + has);
}

double number(const std::string& text, const std::string& file, int line, std::string_view key) {
  double x = 0.0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, x);
  if (text.empty() || ec != std::errc() || ptr != end)
    throw InputError(file, line, std::string(key), "not a number: '" + text + "'");
  if (!std::isfinite(x))
    throw InputError(file, line, std::string(key), "not a finite number: '" + text + "'");
  return x;
}

// A column a curve file must have: its name, how to write it (for messages), and the factor
// from the unit its header gives to the fit's (throwing at the header's line for a wrong unit).
struct ColumnSpec {
  std::string name;
  std::string written;  // "slip [mm]"
  std::function<double(const std::string& unit, const std::string& file, int line)> factor;
};

// A column of a dimensionless quantity: its unit is written '-' (or '1').
ColumnSpec dimensionless(const std::string& name, const std::string& what) {
  return {name, name + " [-]",
          [name, what](const std::string& unit, const std::string& file, int line) {
            if (!(unit == "-" || unit == "1"))
              throw InputError(
                  file, line, name,
                  "unit '" + unit + "': " + what + " is dimensionless, write '" + name + " [-]'");
            return 1.0;
          }};
}

// A column of dimension `d`, converted to the fit's unit of it; `what` and `plural` name the
// dimension in messages ("a length", "lengths").
ColumnSpec dimensional(const std::string& name, model::Dimension d, const std::string& what,
                       const std::string& plural, const model::Units& units) {
  const model::Unit fit_unit = units.unit(d);
  return {name, name + " [" + fit_unit.name + "]",
          [name, d, what, plural, fit_unit](const std::string& unit, const std::string& file,
                                            int line) {
            const auto given = model::parse_unit(unit);
            if (!given || !(given->dimension == d))
              throw InputError(file, line, name,
                               "unit '" + unit + "' is not " + what + " (the fit's " + plural +
                                   " are in " + fit_unit.name + "; write '" + name + " [" +
                                   fit_unit.name + "]')");
            return model::convert(1.0, given->scale, fit_unit.scale);
          }};
}

struct TwoColumns {
  std::vector<double> x, y;  // converted to the fit's units
};

// The columns `xs` and `ys` of a curve file: a header naming them (other columns are ignored),
// then one row per point, comma-separated, `#` starting a comment line; every value finite.
// `check` sees each row's x (converted), as written, and its line, with the x before it, and
// throws where the row cannot follow them.
using RowCheck = std::function<void(double x, const std::string& written, int line,
                                    const std::vector<double>& before)>;
TwoColumns read_two_columns(const std::filesystem::path& path, const ColumnSpec& xs,
                            const ColumnSpec& ys, const RowCheck& check) {
  const std::string file = path.string();
  std::ifstream in(path);
  if (!in) throw InputError(file, 0, "", "cannot open the curve file");
  TwoColumns out;
  std::string line;
  int number_of_line = 0, header_line = 0;
  std::vector<std::string> header;
  Column x_column{}, y_column{};
  double x_factor = 1.0, y_factor = 1.0;
  while (std::getline(in, line)) {
    ++number_of_line;
    const std::string text = trimmed(line);
    if (text.empty() || text.front() == '#') continue;
    const std::vector<std::string> fields = split_fields(text);
    if (header.empty()) {
      header = fields;
      header_line = number_of_line;
      x_column = find_column(header, xs.name, file, header_line, xs.written);
      y_column = find_column(header, ys.name, file, header_line, ys.written);
      x_factor = xs.factor(x_column.unit, file, header_line);
      y_factor = ys.factor(y_column.unit, file, header_line);
      continue;
    }
    if (fields.size() != header.size())
      throw InputError(file, number_of_line, "",
                       std::to_string(fields.size()) + " fields where the header has " +
                           std::to_string(header.size()));
    const std::string& written = fields[x_column.index];
    const double x = number(written, file, number_of_line, xs.name) * x_factor;
    const double y = number(fields[y_column.index], file, number_of_line, ys.name) * y_factor;
    check(x, written, number_of_line, out.x);
    out.x.push_back(x);
    out.y.push_back(y);
  }
  if (header.empty())
    throw InputError(file, 0, "", "no header (" + xs.written + ", " + ys.written + ")");
  if (out.x.empty()) throw InputError(file, header_line, "", "no rows after the header");
  return out;
}

}  // namespace

calibration::Curve read_curve_csv(const std::filesystem::path& path, const model::Units& units) {
  const std::string file = path.string();
  const auto check = [&file](double s, const std::string& written, int line,
                             const std::vector<double>& before) {
    if (!(s > 0.0))
      throw InputError(file, line, "slip",
                       "distances are from rest and must be positive, not " + written);
    if (!before.empty() && !(s > before.back()))
      throw InputError(file, line, "slip",
                       "distances must increase: " + written + " does not follow the row before");
  };
  TwoColumns read = read_two_columns(
      path, dimensional("slip", model::dimension::length, "a length", "lengths", units),
      dimensionless("ratio", "f_t/f_n"), check);
  calibration::Curve curve;
  curve.name = path.filename().string();
  curve.slip = std::move(read.x);
  curve.ratio = std::move(read.y);
  return curve;
}

calibration::CrystalCurve read_crystal_curve_csv(const std::filesystem::path& path,
                                                 const model::Units& units, double strain_rate) {
  const std::string file = path.string();
  const double sign = strain_rate > 0.0 ? 1.0 : -1.0;
  const auto check = [&file, sign, strain_rate](double e, const std::string& written, int line,
                                                const std::vector<double>& before) {
    std::ostringstream rate;
    rate << strain_rate;
    // The path starts from the virgin grain at zero strain and runs at one rate.
    if (!(sign * e > 0.0))
      throw InputError(file, line, "strain",
                       "strains are from the unloaded crystal and must be nonzero and of the "
                       "strain rate's sign (" +
                           rate.str() + "), not " + written);
    if (!before.empty() && !(std::abs(e) > std::abs(before.back())))
      throw InputError(
          file, line, "strain",
          "strains must increase in magnitude: " + written + " does not follow the row before");
  };
  TwoColumns read = read_two_columns(
      path, dimensionless("strain", "the logarithmic strain ln F11"),
      dimensional("stress", model::dimension::stress, "a stress", "stresses", units), check);
  calibration::CrystalCurve curve;
  curve.name = path.filename().string();
  curve.strain_rate = strain_rate;
  curve.strain = std::move(read.x);
  curve.stress = std::move(read.y);
  return curve;
}

namespace {

// The bounds `node` gives a free constant `name` (column `index`) that starts at `start`, read
// in `unit` within `range`; `source` says where the start comes from. Positive ranges are fitted
// in log scale.
calibration::FreeParameter bounded(const CheckedNode& node, std::string_view name, int index,
                                   double start, const Unit& unit, const Range& range,
                                   std::string_view source) {
  const std::vector<double> b = node.as_quantities(unit, range, 2);
  if (!(b[0] < b[1])) node.fail("the lower bound must lie below the upper one");
  if (!(start >= b[0] && start <= b[1])) {
    std::ostringstream msg;
    msg << "the bounds exclude the start " << name << " = " << start << " (" << source << ")";
    node.fail(msg.str());
  }
  return {index, b[0], b[1], b[0] > 0.0};
}

std::vector<std::string_view> law_parameter_names() {
  std::vector<std::string_view> names;
  for (const auto& p : law::kLawParameters) names.push_back(p.name);
  return names;
}

// The law's constants `node` frees, in law::kLawParameters' order, from their values in `start`.
std::vector<calibration::FreeParameter> free_law_constants(const CheckedNode& node,
                                                           const law::LawParameters& start,
                                                           const LawUnits& units,
                                                           std::string_view source) {
  std::vector<calibration::FreeParameter> free;
  for (std::size_t k = 0; k < law::kLawParameters.size(); ++k) {
    const auto& info = law::kLawParameters[k];
    if (const auto bounds = node.optional(info.name))
      free.push_back(bounded(*bounds, info.name, static_cast<int>(k), info.value(start),
                             law_constant_unit(units, info.unit), law_constant_range(info.bound),
                             source));
  }
  return free;
}

std::vector<calibration::FreeParameter> parse_free(const CheckedNode& node,
                                                   const law::LawParameters& start,
                                                   const LawUnits& units) {
  node.expect_map();
  node.allow_keys(law_parameter_names());
  std::vector<calibration::FreeParameter> free =
      free_law_constants(node, start, units, "the law block's value");
  if (free.empty()) node.fail("no free constant: name at least one with its bounds");
  return free;
}

// More points than free constants, or nothing is determined.
void check_points(const CheckedNode& curves, std::size_t points, std::size_t free) {
  if (points <= free)
    curves.fail(std::to_string(points) + " points for " + std::to_string(free) +
                " free constants: the fit needs more points than constants");
}

void read_contact(const CheckedNode& root, const std::filesystem::path& path, FitFile& f) {
  root.allow_keys({"fit", "title", "units", "law", "contact", "initial", "free", "curves", "steps",
                   "max_iterations"});
  f.units = parse_units(root.required("units"));
  const SceneValues values(f.units);
  calibration::FitProblem& p = f.problem;
  const LawUnits law_units = contact_law_units(f.units);
  p.model.law = parse_law_block(root.required("law"), law_units);
  const CheckedNode contact = root.required("contact");
  contact.allow_keys({"alpha_n", "alpha_t", "normal_traction"});
  p.model.stiffness.alpha_n =
      values.get(contact, "alpha_n", dimension::stiffness, Range::positive());
  p.model.stiffness.alpha_t =
      values.get(contact, "alpha_t", dimension::stiffness, Range::positive());
  p.model.initial_normal_traction =
      values.get(contact, "normal_traction", dimension::stress, Range::positive());
  p.model.initial_law_state.mu = p.model.law.friction.mu_s;
  if (const auto initial = root.optional("initial")) {
    initial->allow_keys({"mu"});
    p.model.initial_law_state.mu = initial->get_double("mu", Range::positive());
    p.initial_mu_is_mu_s = false;
  }
  p.free = parse_free(root.required("free"), p.model.law, law_units);
  const std::filesystem::path dir = path.parent_path();
  const CheckedNode curves = root.required("curves");
  for (const CheckedNode& c : curves.elements()) {
    c.allow_keys({"file", "speed", "weight"});
    const std::filesystem::path csv = dir / c.get_string("file");
    calibration::Curve curve = read_curve_csv(csv, f.units);
    curve.speed = values.get(c, "speed", dimension::velocity, Range::positive());
    curve.weight = c.get_double("weight", 1.0, Range::positive());
    p.curves.push_back(std::move(curve));
  }
  if (const auto steps = root.optional("steps")) {
    steps->allow_keys({"increments", "growth"});
    p.steps.increments = steps->get_int("increments", p.steps.increments, Range::at_least(1));
    p.steps.growth = steps->get_double("growth", p.steps.growth, Range::positive());
  }
  p.max_iterations = root.get_int("max_iterations", p.max_iterations, Range::at_least(1));
  std::size_t points = 0;
  for (const auto& c : p.curves) points += c.slip.size();
  check_points(curves, points, p.free.size());
}

// ---- fit: crystal

// The settings every slip system of `d` takes (one per family, or the custom systems').
std::vector<crystal::SlipGroupSettings*> slip_groups(crystal::PhaseDescription& d) {
  std::vector<crystal::SlipGroupSettings*> groups;
  if (!d.custom_systems.empty()) {
    groups.push_back(&d.custom_settings);
  } else {
    for (auto& g : d.family_settings) groups.push_back(&g);
  }
  return groups;
}

// Whether the phase block gives an initial friction coefficient (its own or a family's).
bool gives_initial_mu(const CheckedNode& phase) {
  if (phase.has("initial_mu")) return true;
  const auto per_family = phase.optional("per_family");
  if (!per_family) return false;
  for (const std::string& family : per_family->keys())
    if (per_family->required(family).has("initial_mu")) return true;
  return false;
}

// A crystal fit's grain: its sensitivities are those of one law, one tau0 and one initial_mu on
// every slip system, without plane pressure (point::GrainPoint). Where the phase gives no
// initial_mu, every system starts from mu_s, and moves with it when mu_s is free.
void check_fit_phase(const CheckedNode& node, crystal::PhaseDescription& d) {
  if (d.pressure_sensitive)
    node.required("pressure_sensitive")
        .fail(
            "the crystal fit's grain has no plane pressure (its sensitivities do not follow "
            "the normal traction of the slip planes); remove pressure_sensitive");
  const std::vector<crystal::SlipGroupSettings*> groups = slip_groups(d);
  for (std::size_t k = 1; k < groups.size(); ++k) {
    const crystal::SlipGroupSettings &first = *groups.front(), &g = *groups[k];
    const char* differs = !(g.law == first.law)              ? "law"
                          : g.tau0 != first.tau0             ? "tau0"
                          : g.initial_mu != first.initial_mu ? "initial_mu"
                                                             : nullptr;
    if (differs) {
      const auto per_family = node.optional("per_family");
      (per_family ? *per_family : node)
          .fail(
              "the crystal fit needs one law, tau0 and initial_mu on every slip system (it "
              "fits one set of constants): slip family " +
              std::string(crystal::to_string(d.families[k])) + " differs from " +
              std::string(crystal::to_string(d.families.front())) + " in " + differs);
    }
  }
  if (!gives_initial_mu(node))
    for (crystal::SlipGroupSettings* g : groups) g->initial_mu = 0.0;
}

// The free constants of a crystal fit: the law's (from the phase's values) and initial_mu
// (where the phase gives it); tau0 is refused with the reason.
std::vector<calibration::FreeParameter> parse_crystal_free(const CheckedNode& node,
                                                           const crystal::PhaseDescription& d,
                                                           const Units& units) {
  node.expect_map();
  std::vector<std::string_view> names = law_parameter_names();
  names.push_back("initial_mu");
  names.push_back("tau0");
  node.allow_keys(names);
  if (const auto tau0 = node.optional("tau0"))
    tau0->fail(
        "tau0 cannot be fitted: scaling tau0 by c and mu_s, mu_k, kappa, xi and initial_mu by "
        "1/c leaves every stress unchanged, so the curves determine only the products (the "
        "CRSS); keep tau0 fixed and fit the CRSS through mu_s or initial_mu");
  const crystal::SlipGroupSettings& group =
      d.custom_systems.empty() ? d.family_settings.front() : d.custom_settings;
  std::vector<calibration::FreeParameter> free =
      free_law_constants(node, group.law, crystal_law_units(units), "the phase's value");
  if (const auto mu = node.optional("initial_mu")) {
    if (!(group.initial_mu > 0.0))
      mu->fail(
          "the phase gives no initial_mu: its slip systems start from mu_s; free mu_s, or "
          "give phase.initial_mu to fit the initial friction coefficient apart from it");
    free.push_back(bounded(*mu, "initial_mu", crystal::kInitialMuColumn, group.initial_mu,
                           units.unit(dimension::none), Range::positive(), "the phase's value"));
  }
  if (free.empty()) node.fail("no free constant: name at least one with its bounds");
  return free;
}

void read_crystal(const CheckedNode& root, const std::filesystem::path& path, FitFile& f) {
  root.allow_keys({"fit", "title", "units", "phase", "free", "curves", "steps", "max_iterations"});
  f.kind = FitKind::crystal;
  f.units = parse_units_without_length(root.required("units"));
  SceneValues values(f.units);
  calibration::CrystalFitProblem& p = f.crystal;
  const CheckedNode phase = root.required("phase");
  std::string elasticity_type;
  p.phase = parse_crystal_phase(phase, values, elasticity_type);
  check_fit_phase(phase, p.phase);
  p.free = parse_crystal_free(root.required("free"), p.phase, f.units);
  const std::filesystem::path dir = path.parent_path();
  const CheckedNode curves = root.required("curves");
  std::size_t points = 0;
  for (const CheckedNode& c : curves.elements()) {
    c.allow_keys({"file", "orientation", "strain_rate", "weight"});
    const std::filesystem::path csv = dir / c.get_string("file");
    const EulerDegrees euler = parse_euler_degrees(c.required("orientation"), false);
    const double rate = values.get(c, "strain_rate", dimension::per_time);
    if (!(rate != 0.0))
      c.required("strain_rate").fail("must be nonzero (positive: tension, negative: compression)");
    const double weight = c.get_double("weight", 1.0, Range::positive());
    calibration::CrystalCurve curve = read_crystal_curve_csv(csv, f.units, rate);
    curve.orientation = euler.orientation.g;
    curve.weight = weight;
    points += curve.strain.size();
    p.curves.push_back(std::move(curve));
    f.euler_degrees.push_back(euler.degrees);
  }
  if (p.curves.empty()) curves.fail("needs at least one curve");
  if (const auto steps = root.optional("steps")) {
    steps->allow_keys({"increments"});
    p.steps.increments = steps->get_int("increments", p.steps.increments, Range::at_least(1));
  }
  p.max_iterations = root.get_int("max_iterations", p.max_iterations, Range::at_least(1));
  check_points(curves, points, p.free.size());
}

}  // namespace

FitFile read_fit_file(const std::filesystem::path& path) {
  const YamlDocument document = YamlDocument::from_file(path);
  const CheckedNode root = document.root();
  const std::string kind = root.required("fit").as_choice({"contact", "crystal"});
  FitFile f;
  f.file = path.string();
  f.title = root.get_string("title", "");
  if (kind == "crystal") {
    read_crystal(root, path, f);
  } else {
    read_contact(root, path, f);
  }
  return f;
}

}  // namespace subslip::io
