#include "fit_report.hpp"

#include <cmath>
#include <cstdio>
#include <iomanip>
#include <ostream>
#include <sstream>

#include "subslip/calibration/crystal_fit.hpp"
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

// The settings every slip system of a crystal fit's phase shares (io::read_fit_file checks that
// they are one).
const crystal::SlipGroupSettings& slip_group(const io::FitFile& f) {
  const crystal::PhaseDescription& d = f.crystal.phase;
  return d.custom_systems.empty() ? d.family_settings.front() : d.custom_settings;
}

std::string unit_of(const io::FitFile& f, const calibration::FitResult& r, std::size_t j) {
  if (r.names[j] == "initial_mu") return std::string(model::kDimensionless);
  const auto* info = law::find_law_parameter(r.names[j]);
  return io::law_unit_name(info->unit, f.kind == io::FitKind::crystal, f.units);
}

}  // namespace

calibration::FitResult fit_of(const io::FitFile& f) {
  return f.kind == io::FitKind::crystal ? calibration::fit(f.crystal) : calibration::fit(f.problem);
}

double initial_crss(const io::FitFile& f, const calibration::FitResult& r) {
  const crystal::SlipGroupSettings& group = slip_group(f);
  double mu = group.initial_mu > 0.0 ? group.initial_mu : r.law.friction.mu_s;
  for (std::size_t j = 0; j < r.names.size(); ++j)
    if (r.names[j] == "initial_mu") mu = r.estimate[j];
  return mu * group.tau0;
}

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
        << r.standard_error[j] << std::setw(29) << interval.str() << "  " << unit_of(f, r, j)
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
  if (f.kind == io::FitKind::crystal) {
    // What the curves determine: the products of tau0 with the friction coefficients, tau0 being
    // fixed (docs/calibration.md, "Single-crystal curves").
    const bool from_mu_s = !(slip_group(f).initial_mu > 0.0);
    out << "\ninitial CRSS (" << (from_mu_s ? "mu_s" : "initial_mu")
        << " tau0 at the estimate): " << std::setprecision(6) << initial_crss(f, r) << " "
        << f.units.stress << "\n";
  }
}

void write_fit_json(std::ostream& out, const io::FitFile& f, const calibration::FitResult& r) {
  auto by_name = [&](auto value) {
    std::string s = "{";
    for (std::size_t j = 0; j < r.names.size(); ++j)
      s += std::string(j ? ", " : "") + json_string(r.names[j]) + ": " + value(j);
    return s + "}";
  };
  const bool crystal = f.kind == io::FitKind::crystal;
  out << "{\n  \"file\": " << json_string(f.file) << ",\n";
  out << "  \"kind\": " << json_string(crystal ? "crystal" : "contact") << ",\n";
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
  out << "  \"unit\": " << by_name([&](std::size_t j) { return json_string(unit_of(f, r, j)); })
      << ",\n";
  out << "  \"correlation\": " << by_name([&](std::size_t i) {
    std::vector<double> row;
    for (std::size_t k = 0; k < r.names.size(); ++k)
      row.push_back(r.correlation(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(k)));
    return json_array(row);
  }) << ",\n";
  out << "  \"warnings\": [";
  for (std::size_t k = 0; k < r.warnings.size(); ++k)
    out << (k ? ", " : "") << json_string(r.warnings[k]);
  out << "],\n";
  if (crystal) {
    out << "  \"initial_crss\": {\"value\": " << json_number(initial_crss(f, r))
        << ", \"unit\": " << json_string(f.units.stress) << "},\n";
    out << "  \"stress_unit\": " << json_string(f.units.stress) << ",\n";
  } else {
    out << "  \"length_unit\": " << json_string(f.units.length) << ",\n";
  }
  out << "  \"time_unit\": " << json_string(f.units.time) << ",\n";
  out << "  \"curves\": [";
  if (crystal) {
    const auto& curves = f.crystal.curves;
    for (std::size_t c = 0; c < curves.size(); ++c) {
      const Eigen::Vector3d& e = f.euler_degrees[c];
      out << (c ? ",\n" : "\n") << "    {\"name\": " << json_string(curves[c].name)
          << ", \"orientation\": " << json_array({e[0], e[1], e[2]})
          << ", \"strain_rate\": " << json_number(curves[c].strain_rate)
          << ", \"strain\": " << json_array(curves[c].strain)
          << ", \"data\": " << json_array(curves[c].stress)
          << ", \"fit\": " << json_array(r.fitted[c]) << "}";
    }
  } else {
    const auto& curves = f.problem.curves;
    for (std::size_t c = 0; c < curves.size(); ++c) {
      out << (c ? ",\n" : "\n") << "    {\"name\": " << json_string(curves[c].name)
          << ", \"speed\": " << json_number(curves[c].speed)
          << ", \"slip\": " << json_array(curves[c].slip)
          << ", \"data\": " << json_array(curves[c].ratio)
          << ", \"fit\": " << json_array(r.fitted[c]) << "}";
    }
  }
  out << "\n  ]\n}\n";
}

}  // namespace subslip::cli
