#include "subslip/io/fit_file.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>
#include <string_view>
#include <vector>

#include "subslip/io/law_block.hpp"
#include "subslip/io/scene_common.hpp"
#include "subslip/law/parameter_table.hpp"

namespace subslip::io {

namespace {

std::string trim(std::string_view s) {
  const auto first = s.find_first_not_of(" \t\r");
  if (first == std::string_view::npos) return {};
  const auto last = s.find_last_not_of(" \t\r");
  return std::string(s.substr(first, last - first + 1));
}

std::vector<std::string> split_fields(const std::string& line) {
  std::vector<std::string> fields;
  std::stringstream in(line);
  std::string field;
  while (std::getline(in, field, ',')) fields.push_back(trim(field));
  if (!line.empty() && line.back() == ',') fields.emplace_back();
  return fields;
}

// A header field "name [unit]": the name and the unit ("" without brackets).
std::pair<std::string, std::string> name_and_unit(const std::string& field) {
  const auto open = field.find('[');
  if (open == std::string::npos || field.back() != ']') return {field, ""};
  return {trim(field.substr(0, open)), trim(field.substr(open + 1, field.size() - open - 2))};
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

// The factor from the header's length unit to the fit's.
double length_factor(const std::string& unit, const model::Units& units, const std::string& file,
                     int line) {
  const auto given = model::parse_unit(unit);
  if (!given || !(given->dimension == model::dimension::length))
    throw InputError(file, line, "slip",
                     "unit '" + unit + "' is not a length (the fit's lengths are in " +
                         units.length + "; write 'slip [" + units.length + "]')");
  const model::Unit fit_unit = units.unit(model::dimension::length);
  return model::convert(1.0, given->scale, fit_unit.scale);
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

}  // namespace

calibration::Curve read_curve_csv(const std::filesystem::path& path, const model::Units& units) {
  const std::string file = path.string();
  std::ifstream in(path);
  if (!in) throw InputError(file, 0, "", "cannot open the curve file");
  calibration::Curve curve;
  curve.name = path.filename().string();
  std::string line;
  int number_of_line = 0, header_line = 0;
  std::vector<std::string> header;
  Column slip{}, ratio{};
  double factor = 1.0;
  while (std::getline(in, line)) {
    ++number_of_line;
    const std::string text = trim(line);
    if (text.empty() || text.front() == '#') continue;
    const std::vector<std::string> fields = split_fields(text);
    if (header.empty()) {
      header = fields;
      header_line = number_of_line;
      slip = find_column(header, "slip", file, header_line, "slip [" + units.length + "]");
      ratio = find_column(header, "ratio", file, header_line, "ratio [-]");
      factor = length_factor(slip.unit, units, file, header_line);
      if (!(ratio.unit == "-" || ratio.unit == "1"))
        throw InputError(file, header_line, "ratio",
                         "unit '" + ratio.unit + "': f_t/f_n is dimensionless, write 'ratio [-]'");
      continue;
    }
    if (fields.size() != header.size())
      throw InputError(file, number_of_line, "",
                       std::to_string(fields.size()) + " fields where the header has " +
                           std::to_string(header.size()));
    const double s = number(fields[slip.index], file, number_of_line, "slip") * factor;
    const double r = number(fields[ratio.index], file, number_of_line, "ratio");
    if (!(s > 0.0))
      throw InputError(file, number_of_line, "slip",
                       "distances are from rest and must be positive, not " + fields[slip.index]);
    if (!curve.slip.empty() && !(s > curve.slip.back()))
      throw InputError(
          file, number_of_line, "slip",
          "distances must increase: " + fields[slip.index] + " does not follow the row before");
    curve.slip.push_back(s);
    curve.ratio.push_back(r);
  }
  if (header.empty())
    throw InputError(file, 0, "", "no header (slip [" + units.length + "], ratio [-])");
  if (curve.slip.empty()) throw InputError(file, header_line, "", "no rows after the header");
  return curve;
}

namespace {

std::vector<calibration::FreeParameter> parse_free(const CheckedNode& node,
                                                   const law::LawParameters& start,
                                                   const LawUnits& units) {
  node.expect_map();
  std::vector<std::string_view> names;
  for (const auto& p : law::kLawParameters) names.push_back(p.name);
  node.allow_keys(names);
  std::vector<calibration::FreeParameter> free;
  for (std::size_t k = 0; k < law::kLawParameters.size(); ++k) {
    const auto& info = law::kLawParameters[k];
    const auto bounds = node.optional(info.name);
    if (!bounds) continue;
    const std::vector<double> b = bounds->as_quantities(law_constant_unit(units, info.unit),
                                                        law_constant_range(info.bound), 2);
    if (!(b[0] < b[1])) bounds->fail("the lower bound must lie below the upper one");
    const double value = info.value(start);
    if (!(value >= b[0] && value <= b[1])) {
      std::ostringstream msg;
      msg << "the bounds exclude the start " << info.name << " = " << value
          << " (the law block's value)";
      bounds->fail(msg.str());
    }
    free.push_back({static_cast<int>(k), b[0], b[1], b[0] > 0.0});
  }
  if (free.empty()) node.fail("no free constant: name at least one with its bounds");
  return free;
}

}  // namespace

FitFile read_fit_file(const std::filesystem::path& path) {
  const YamlDocument document = YamlDocument::from_file(path);
  const CheckedNode root = document.root();
  root.allow_keys({"fit", "title", "units", "law", "contact", "initial", "free", "curves", "steps",
                   "max_iterations"});
  root.required("fit").as_choice({"contact"});
  FitFile f;
  f.file = path.string();
  f.title = root.get_string("title", "");
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
  if (points <= p.free.size())
    curves.fail(std::to_string(points) + " points for " + std::to_string(p.free.size()) +
                " free constants: the fit needs more points than constants");
  return f;
}

}  // namespace subslip::io
