#include "fit_report.hpp"

#include <cmath>
#include <cstdio>
#include <iomanip>
#include <ostream>
#include <sstream>

#include "subslip/io/law_block.hpp"
#include "subslip/law/parameter_table.hpp"

namespace subslip::cli {

namespace {

// A JSON number (null for a value JSON cannot hold: an undetermined interval).
std::string json_number(double x) {
  if (!std::isfinite(x)) return "null";
  std::ostringstream s;
  s << std::setprecision(17) << x;
  return s.str();
}

std::string json_string(const std::string& text) {
  std::string out = "\"";
  for (const char c : text) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buffer[8];
      std::snprintf(buffer, sizeof buffer, "\\u%04x", c);
      out += buffer;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

std::string json_array(const std::vector<double>& v) {
  std::string out = "[";
  for (std::size_t i = 0; i < v.size(); ++i) out += (i ? ", " : "") + json_number(v[i]);
  return out + "]";
}

std::string unit_of(const calibration::FitResult& r, std::size_t j, const model::Units& units) {
  const auto* info = law::find_law_parameter(r.names[j]);
  return io::law_unit_name(info->unit, false, units);
}

}  // namespace

void print_fit_table(std::ostream& out, const io::FitFile& f, const calibration::FitResult& r) {
  out << "subslip fit " << f.file << (f.title.empty() ? "" : ": " + f.title) << "\n";
  out << r.termination << "; " << r.points << " points, residual s.d. " << r.residual_sd << "\n\n";
  out << std::left << std::setw(9) << "constant" << std::right << std::setw(14) << "estimate"
      << std::setw(13) << "std. error" << std::setw(29) << "95 % interval"
      << "  unit\n";
  for (std::size_t j = 0; j < r.names.size(); ++j) {
    std::ostringstream interval;
    interval << "[" << std::setprecision(5) << r.lower[j] << ", " << r.upper[j] << "]";
    out << std::left << std::setw(9) << r.names[j] << std::right << std::setprecision(6)
        << std::setw(14) << r.estimate[j] << std::setw(13) << std::setprecision(3)
        << r.standard_error[j] << std::setw(29) << interval.str() << "  " << unit_of(r, j, f.units)
        << "\n";
  }
  out << "\ncorrelation\n" << std::setw(9) << "";
  for (const auto& n : r.names) out << std::setw(9) << n;
  out << "\n";
  for (std::size_t i = 0; i < r.names.size(); ++i) {
    out << std::left << std::setw(9) << r.names[i] << std::right;
    for (std::size_t k = 0; k < r.names.size(); ++k)
      out << std::setw(9) << std::fixed << std::setprecision(3)
          << r.correlation(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(k))
          << std::defaultfloat;
    out << "\n";
  }
}

void write_fit_json(std::ostream& out, const io::FitFile& f, const calibration::FitResult& r) {
  auto by_name = [&](auto value) {
    std::string s = "{";
    for (std::size_t j = 0; j < r.names.size(); ++j)
      s += std::string(j ? ", " : "") + json_string(r.names[j]) + ": " + value(j);
    return s + "}";
  };
  out << "{\n  \"file\": " << json_string(f.file) << ",\n";
  out << "  \"converged\": " << (r.converged ? "true" : "false") << ",\n";
  out << "  \"termination\": " << json_string(r.termination) << ",\n";
  out << "  \"points\": " << r.points << ",\n";
  out << "  \"residual_sd\": " << json_number(r.residual_sd) << ",\n";
  out << "  \"estimate\": " << by_name([&](std::size_t j) { return json_number(r.estimate[j]); })
      << ",\n";
  out << "  \"standard_error\": "
      << by_name([&](std::size_t j) { return json_number(r.standard_error[j]); }) << ",\n";
  out << "  \"interval\": " << by_name([&](std::size_t j) {
    return json_array({r.lower[j], r.upper[j]});
  }) << ",\n";
  out << "  \"unit\": "
      << by_name([&](std::size_t j) { return json_string(unit_of(r, j, f.units)); }) << ",\n";
  out << "  \"correlation\": " << by_name([&](std::size_t i) {
    std::vector<double> row;
    for (std::size_t k = 0; k < r.names.size(); ++k)
      row.push_back(r.correlation(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(k)));
    return json_array(row);
  }) << ",\n";
  out << "  \"warnings\": [";
  for (std::size_t k = 0; k < r.warnings.size(); ++k)
    out << (k ? ", " : "") << json_string(r.warnings[k]);
  out << "],\n  \"length_unit\": " << json_string(f.units.length) << ",\n";
  out << "  \"time_unit\": " << json_string(f.units.time) << ",\n";
  out << "  \"curves\": [";
  const auto& curves = f.problem.curves;
  for (std::size_t c = 0; c < curves.size(); ++c) {
    out << (c ? ",\n" : "\n") << "    {\"name\": " << json_string(curves[c].name)
        << ", \"speed\": " << json_number(curves[c].speed)
        << ", \"slip\": " << json_array(curves[c].slip)
        << ", \"data\": " << json_array(curves[c].ratio) << ", \"fit\": " << json_array(r.fitted[c])
        << "}";
  }
  out << "\n  ]\n}\n";
}

}  // namespace subslip::cli
