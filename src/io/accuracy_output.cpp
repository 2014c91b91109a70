#include "subslip/io/accuracy_output.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <system_error>

#include "subslip/io/h5_writer.hpp"
#include "subslip/io/result_protocol.hpp"

namespace subslip::io {

namespace fs = std::filesystem;
using study::Integrator;
using study::PointResult;
using study::StudyResult;

namespace {

constexpr const char* kCsv = "accuracy.csv";
constexpr const char* kReferenceCsv = "accuracy_reference.csv";
constexpr const char* kMarkdown = "accuracy.md";
constexpr const char* kHdf5 = "accuracy.h5";

std::string format_or_blank(const char* fmt, double x) {
  if (std::isnan(x)) return "";
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, x);
  return buf;
}

// A CSV field: quoted when it holds a comma, a quote or a line break (RFC 4180).
std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string out = "\"";
  for (char c : s) {
    if (c == '"') out += '"';
    out += c;
  }
  return out + "\"";
}

// The increments a fixed-step point prescribes (the factor times the scene's); 0 otherwise.
long planned_increments(const StudyResult& study, const PointResult& p) {
  if (!study::is_fixed_step(p.setting.integrator)) return 0;
  return std::lround(static_cast<double>(study.base_increments) * p.setting.value);
}

// ok, failed (the integrator gave up: a result), stopped (over the run-time budget: none).
// What the setting is: increment factor (graded as the scene, or uniform), tolerance, rtol.
std::string kind_of(const PointResult& p) {
  std::string kind(study::setting_kind(p.setting.integrator));
  if (study::is_fixed_step(p.setting.integrator) && p.setting.uniform) kind += " (uniform)";
  return kind;
}

std::string status_of(const PointResult& p) {
  if (p.ok) return "ok";
  return p.over_budget ? "stopped" : "failed";
}

// Max error over the tolerance asked for (adaptive, CVODE: rtol); NaN for fixed steps.
double error_to_tolerance(const PointResult& p) {
  if (study::is_fixed_step(p.setting.integrator) || !p.ok) return study::kNaN;
  return p.error.max_error / p.setting.value;
}

std::string count_or_blank(const PointResult& p, long value) {
  return p.ok ? std::to_string(value) : "";
}

std::ofstream open_text(const fs::path& path) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw h5::OutputPathError(path.string() + ": cannot be written");
  return out;
}

void write_csv(const fs::path& path, const AccuracyReport& report) {
  std::ofstream out = open_text(path);
  out << "case,integrator,setting_kind,setting,increments,steps,rejected,newton_iterations,"
         "cutbacks,max_error,max_error_time,max_error_on,reference_error,end_error,error_to_"
         "tolerance,median_time_s,repeats,"
         "status,failure\n";
  for (const auto& c : report.cases) {
    for (const auto& p : c.result.points) {
      const long inc = planned_increments(c.result, p);
      out << csv_field(c.name) << ',' << study::to_string(p.setting.integrator) << ',' << kind_of(p)
          << ',' << format_or_blank("%.6g", p.setting.value) << ','
          << (inc > 0 ? std::to_string(inc) : "") << ',' << count_or_blank(p, p.counters.steps)
          << ',' << count_or_blank(p, p.counters.rejected) << ','
          << count_or_blank(p, p.counters.newton_iterations) << ','
          << count_or_blank(p, p.counters.cutbacks) << ','
          << format_or_blank("%.6e", p.error.max_error) << ','
          << format_or_blank("%.6e", p.error.max_error_time) << ',' << csv_field(p.max_error_on)
          << ',' << format_or_blank("%.6e", p.reference_error) << ','
          << format_or_blank("%.6e", p.error.end_error) << ','
          << format_or_blank("%.6e", error_to_tolerance(p)) << ','
          << format_or_blank("%.6e", p.median_seconds) << ',' << p.repeats << ',' << status_of(p)
          << ',' << csv_field(p.failure) << '\n';
    }
  }
}

void write_reference_csv(const fs::path& path, const AccuracyReport& report) {
  std::ofstream out = open_text(path);
  out << "case,title,quantity,quantity_unit,error_scale,reference_integrator,reference_setting,"
         "extrapolated,reference_steps,reference_time_s,check_setting,self_convergence,cvode_rtol,"
         "cvode_difference,interpolation_error,measured\n";
  for (const auto& c : report.cases) {
    const auto& r = c.result.reference;
    out << csv_field(c.name) << ',' << csv_field(report.title) << ','
        << csv_field(c.result.quantity) << ',' << csv_field(c.quantity_unit) << ','
        << format_or_blank("%.9g", r.scale) << ',' << study::to_string(r.setting.integrator) << ','
        << format_or_blank("%.6g", r.setting.value) << ',' << (r.extrapolated ? 1 : 0) << ','
        << r.run.counters.steps << ',' << format_or_blank("%.6e", r.run.seconds) << ','
        << format_or_blank("%.6g", r.check.value) << ','
        << format_or_blank("%.6e", r.self_convergence) << ','
        << (r.cvode ? format_or_blank("%.3g", report.cvode_check_rtol) : "") << ','
        << format_or_blank("%.6e", r.cvode_difference) << ','
        << format_or_blank("%.6e", r.interpolation_error) << ',' << csv_field(c.result.measured)
        << '\n';
  }
}

// ---- Markdown

std::string md_setting_of(const study::Setting& s) {
  if (study::is_fixed_step(s.integrator))
    return format_or_blank("x%g", s.value) + (s.uniform ? " uniform" : "");
  return std::string(study::setting_kind(s.integrator)) + " " + format_or_blank("%.0e", s.value);
}

std::string md_setting(const PointResult& p) {
  return md_setting_of(p.setting);
}

std::string describe_reference_setting(const study::ReferenceResult& r) {
  std::string text =
      std::string(study::to_string(r.setting.integrator)) + " " + md_setting_of(r.setting);
  if (r.extrapolated) {
    text += ", Richardson-extrapolated with " + md_setting_of(r.check);
  }
  return text;
}

// The companion of the self-convergence estimate.
std::string describe_check(const study::ReferenceResult& r) {
  if (r.extrapolated) {
    return "the same extrapolation from " + md_setting_of(r.check) + " and " +
           md_setting_of({r.check.integrator, 0.5 * r.check.value});
  }
  return md_setting_of(r.check);
}

std::string md_number(double x, const char* fmt = "%.2e") {
  return std::isnan(x) ? "-" : format_or_blank(fmt, x);
}

void write_points_table(std::ostream& out, const StudyResult& study) {
  out << "| integrator | setting | increments | steps | rejected | Newton iterations | cutbacks | "
         "max error | at t | on | its reference's error | end error | median time [s] | runs |\n"
         "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& p : study.points) {
    const long inc = planned_increments(study, p);
    out << "| " << study::to_string(p.setting.integrator) << " | " << md_setting(p) << " | "
        << (inc > 0 ? std::to_string(inc) : "-") << " | ";
    if (p.ok) {
      out << p.counters.steps << " | " << p.counters.rejected << " | "
          << p.counters.newton_iterations << " | " << p.counters.cutbacks << " | "
          << md_number(p.error.max_error) << " | " << md_number(p.error.max_error_time, "%.3g")
          << " | " << (p.max_error_on.empty() ? "-" : p.max_error_on) << " | "
          << md_number(p.reference_error) << " | " << md_number(p.error.end_error) << " | ";
    } else {
      out << "- | - | - | - | " << status_of(p)
          << " (last point t = " << md_number(p.reached_time, "%.3g") << ") | - | - | - | - | ";
    }
    out << md_number(p.median_seconds, "%.3g") << " | " << p.repeats << " |\n";
  }
}

// The fastest of subslip's implicit integrators (fixed, adaptive or extrapolated) at an error
// level; NaN when none reaches it.
double best_implicit_time(const StudyResult& study, double level) {
  double best = study::kNaN;
  for (Integrator i :
       {Integrator::implicit, Integrator::implicit_adaptive, Integrator::extrapolated_2,
        Integrator::extrapolated_3, Integrator::extrapolated_4}) {
    const double t = study::cheapest_time(study, i, level);
    if (!std::isnan(t) && !(t >= best)) best = t;
  }
  return best;
}

void write_time_to_error_table(std::ostream& out, const StudyResult& study) {
  const auto integrators = study::measured_integrators(study);
  const auto levels = error_levels(study);
  if (integrators.empty() || levels.empty()) return;
  out << "\nTime [s] of the cheapest measured run whose max error is at most the level, and the "
         "speed-up of the fastest implicit integrator (fixed, adaptive or extrapolated) over "
         "forward Euler and "
         "over CVODE at that level:\n\n| max error <= |";
  for (Integrator i : integrators) out << ' ' << study::to_string(i) << " |";
  out << " implicit vs forward_euler | implicit vs cvode |\n|---|";
  for (std::size_t k = 0; k < integrators.size() + 2; ++k) out << "---|";
  out << '\n';
  for (double level : levels) {
    out << "| " << format_or_blank("%.0e", level) << " |";
    for (Integrator i : integrators) {
      out << ' ' << md_number(study::cheapest_time(study, i, level), "%.3g") << " |";
    }
    const double best = best_implicit_time(study, level);
    const double fe = study::cheapest_time(study, Integrator::forward_euler, level);
    const double cv = study::cheapest_time(study, Integrator::cvode, level);
    out << ' ' << md_number(fe / best, "%.3g") << " | " << md_number(cv / best, "%.3g") << " |\n";
  }
}

std::string ladder_name(const study::LadderSummary& s) {
  return std::string(study::to_string(s.integrator)) + (s.uniform ? " (uniform)" : "");
}

void write_ladder_table(std::ostream& out, const StudyResult& study) {
  const auto ladders = study::ladder_summaries(study);
  if (ladders.empty()) return;
  out << "\nPer integrator, over its points above the reference's resolution: the observed order "
         "(-slope of log max error over log steps), how the max error follows the tolerance "
         "(slope of log max error over log tolerance: 1 means proportional) and the max error "
         "over the tolerance asked for:\n\n"
         "| integrator | points | observed order | error ~ tolerance^ | max error / tolerance |\n"
         "|---|---|---|---|---|\n";
  for (const auto& s : ladders) {
    out << "| " << ladder_name(s) << " | " << s.points << " | " << md_number(s.order, "%.2f")
        << " | " << md_number(s.exponent, "%.2f") << " | "
        << (std::isnan(s.least_ratio)
                ? std::string("-")
                : md_number(s.least_ratio, "%.2g") + " ... " + md_number(s.greatest_ratio, "%.2g"))
        << " |\n";
  }
}

void write_markdown(const fs::path& path, const AccuracyReport& report) {
  std::ofstream out = open_text(path);
  out << "# Work-precision study: " << report.scene_file << "\n\n";
  if (!report.title.empty()) out << report.title << "\n\n";
  out << "subslip " << SUBSLIP_VERSION << ", " << report.threads << " thread"
      << (report.threads == 1 ? "" : "s") << ". Errors are |value - reference| / scale at every "
      << "step of a run (max) and at the end; times are wall-clock medians of repeated runs "
         "that report only the scene's output points. Fixed-step settings multiply the scene's "
         "increments; CVODE runs at rtol with absolute tolerances min(rtol, "
      << format_or_blank("%.0e", report.cvode_atol) << ") x each component's scale.\n";
  for (const auto& c : report.cases) {
    const StudyResult& s = c.result;
    const auto& r = s.reference;
    out << "\n## Case `" << c.name << "`: " << s.quantity << " [" << c.quantity_unit << "]\n\n"
        << "Scale: " << s.scale_description << " = " << format_or_blank("%.6g", r.scale) << " ["
        << c.quantity_unit << "].\n\nReference: " << describe_reference_setting(r) << " ("
        << r.run.counters.steps << " steps, " << format_or_blank("%.3g", r.run.seconds)
        << " s). Self-convergence (against " << describe_check(r)
        << "): " << md_number(r.self_convergence) << "; CVODE at rtol "
        << format_or_blank("%.0e", report.cvode_check_rtol) << ": "
        << (r.cvode ? (r.cvode->ok ? "differs by " + md_number(r.cvode_difference)
                                   : "failed (" + r.cvode->failure + ")")
                    : std::string("not available"))
        << "; interpolation error bound " << md_number(r.interpolation_error) << ".\n\n";
    write_points_table(out, s);
    write_ladder_table(out, s);
    write_time_to_error_table(out, s);
    for (const auto& note : s.notes) out << "\n- " << note;
    if (!s.notes.empty()) out << '\n';
  }
}

// ---- HDF5

// A [n] dataset of variable-length UTF-8 strings with `unit` and `description` attributes.
void write_strings(const h5::Group& group, const std::string& name,
                   const std::vector<std::string>& values, const std::string& description) {
  const h5::Dataset dataset = group.write_strings(name, values, description);
  dataset.set_attribute("unit", "label");
}

void write_column(const h5::Group& group, const std::string& name,
                  const std::vector<double>& values, const std::string& unit,
                  const std::string& description) {
  const std::size_t shape[] = {values.size()};
  group.write_array(name, shape, values, unit, description);
}

void write_table(const h5::Group& group, const StudyResult& s, const std::string& time_unit) {
  std::vector<std::string> integrator, kind, status, failure, max_error_on;
  std::vector<double> setting, increments, steps, rejected, newton, cutbacks, max_error,
      max_error_time, reference_error, end_error, to_tolerance, seconds, repeats, reached;
  const double nan = study::kNaN;
  for (const auto& p : s.points) {
    integrator.emplace_back(study::to_string(p.setting.integrator));
    kind.push_back(kind_of(p));
    status.push_back(status_of(p));
    failure.push_back(p.failure);
    setting.push_back(p.setting.value);
    const long inc = planned_increments(s, p);
    increments.push_back(inc > 0 ? static_cast<double>(inc) : nan);
    steps.push_back(p.ok ? static_cast<double>(p.counters.steps) : nan);
    rejected.push_back(p.ok ? static_cast<double>(p.counters.rejected) : nan);
    newton.push_back(p.ok ? static_cast<double>(p.counters.newton_iterations) : nan);
    cutbacks.push_back(p.ok ? static_cast<double>(p.counters.cutbacks) : nan);
    max_error.push_back(p.error.max_error);
    max_error_time.push_back(p.error.max_error_time);
    max_error_on.push_back(p.max_error_on);
    reference_error.push_back(p.reference_error);
    end_error.push_back(p.error.end_error);
    to_tolerance.push_back(error_to_tolerance(p));
    seconds.push_back(p.median_seconds);
    repeats.push_back(p.repeats);
    reached.push_back(p.reached_time);
  }
  write_strings(group, "integrator", integrator,
                "forward_euler, implicit (fixed increments), implicit_adaptive, extrapolated_2, "
                "extrapolated_3, extrapolated_4 (adaptive, extrapolated to that order), cvode");
  write_strings(group, "setting_kind", kind, "what `setting` is for this row");
  write_column(group, "setting", setting, "1",
               "increment factor (relative to the scene's increments) or tolerance / rtol");
  write_column(group, "increments", increments, "1",
               "prescribed increments (fixed step; NaN for adaptive)");
  write_column(group, "steps", steps, "1", "steps taken (NaN: failed)");
  write_column(group, "rejected", rejected, "1", "adaptive steps refused by the error estimate");
  write_column(group, "newton_iterations", newton, "1", "Newton / nonlinear iterations, summed");
  write_column(group, "cutbacks", cutbacks, "1",
               "halvings after failed updates (CVODE: error-test and convergence failures)");
  write_column(group, "max_error", max_error, "1",
               "max over the output points and measured quantities of |value - reference| / "
               "their scale");
  write_column(group, "max_error_time", max_error_time, time_unit, "where the max error is");
  write_strings(group, "max_error_on", max_error_on, "on which measured quantity it is");
  write_column(group, "reference_error", reference_error, "1",
               "the resolution of the run's own reference (--reference-at-run-times; else NaN)");
  write_column(group, "end_error", end_error, "1", "|value - reference| / error_scale at the end");
  write_column(group, "error_to_tolerance", to_tolerance, "1",
               "max_error / the tolerance (adaptive) or rtol (CVODE) asked for; NaN: fixed step");
  write_column(group, "median_time", seconds, "s", "median wall time of the repeated runs");
  write_column(group, "repeats", repeats, "1", "timed runs");
  write_column(group, "reached_time", reached, time_unit, "the last output time reached");
  write_strings(group, "status", status,
                "ok | failed (the integrator gave up) | stopped (over the run-time budget)");
  write_strings(group, "failure", failure, "the integrator's message when failed");
}

// One row per integrator ladder (study::ladder_summaries).
void write_ladders(const h5::Group& group, const StudyResult& s) {
  std::vector<std::string> name;
  std::vector<double> points, order, exponent, least, greatest;
  for (const auto& l : study::ladder_summaries(s)) {
    name.push_back(ladder_name(l));
    points.push_back(l.points);
    order.push_back(l.order);
    exponent.push_back(l.exponent);
    least.push_back(l.least_ratio);
    greatest.push_back(l.greatest_ratio);
  }
  group.set_attribute("description",
                      "per integrator, fitted over its points above 10 x the reference's "
                      "resolution (self_convergence, interpolation_error)");
  write_strings(group, "integrator", name, "the ladder (forward Euler's uniform one apart)");
  write_column(group, "points", points, "1", "points fitted");
  write_column(group, "observed_order", order, "1",
               "-d log(max_error) / d log(steps); NaN: fewer than two points");
  write_column(group, "tolerance_exponent", exponent, "1",
               "d log(max_error) / d log(tolerance); 1: the error follows the tolerance; NaN: "
               "fixed step");
  write_column(group, "least_error_to_tolerance", least, "1", "min of max_error / tolerance");
  write_column(group, "greatest_error_to_tolerance", greatest, "1", "max of max_error / tolerance");
}

void write_path(const h5::Group& parent, const std::string& name, const study::Trajectory& path,
                const std::string& time_unit, const std::string& unit,
                const std::string& description) {
  const h5::Group g = parent.create_group(name);
  g.set_attribute("description", description);
  write_column(g, "time", path.time, time_unit, "time");
  write_column(g, "value", path.headline(), unit, "the measured quantity (channel 0)");
  std::vector<double> segment(path.segment.begin(), path.segment.end());
  write_column(g, "segment", segment, "index", "loading segment, -1 for the initial state");
}

std::string unit_named(const AccuracyReport& report, const std::string& name) {
  for (const auto& [n, u] : report.units)
    if (n == name) return u;
  return "";
}

void write_case(const h5::Group& cases, const AccuracyReport& report, const AccuracyCase& c) {
  const h5::Group g = cases.create_group(c.name);
  const StudyResult& s = c.result;
  const auto& r = s.reference;
  g.set_attribute("quantity", s.quantity);
  g.set_attribute("quantity.unit", c.quantity_unit);
  g.set_attribute("error_scale", r.scale);
  g.set_attribute("error_scale.unit", c.quantity_unit);
  g.set_attribute("error_scale_description", s.scale_description);
  g.set_attribute("base_increments", static_cast<long long>(s.base_increments));
  g.set_attribute("reference_integrator", study::to_string(r.setting.integrator));
  g.set_attribute("reference_setting", r.setting.value);
  g.set_attribute("reference_setting_kind", study::setting_kind(r.setting.integrator));
  g.set_attribute("reference_check_setting", r.check.value);
  g.set_attribute("reference_extrapolated", r.extrapolated ? 1 : 0);
  g.set_attribute("reference_steps", static_cast<long long>(r.run.counters.steps));
  g.set_attribute("reference_seconds", r.run.seconds);
  g.set_attribute("reference_self_convergence", r.self_convergence);
  g.set_attribute("reference_interpolation_error", r.interpolation_error);
  g.set_attribute("cvode_check_rtol", report.cvode_check_rtol);
  g.set_attribute("reference_cvode_difference", r.cvode_difference);
  std::string notes;
  for (const auto& n : s.notes) notes += (notes.empty() ? "" : "\n") + n;
  g.set_attribute("notes", notes);
  const std::string time_unit = unit_named(report, "time");
  write_table(g.create_group("table"), s, time_unit);
  write_ladders(g.create_group("ladders"), s);
  write_path(g, "reference", r.path, time_unit, c.quantity_unit, "the reference run, every step");
  if (r.cvode && r.cvode->ok) {
    write_path(g, "cvode_check", r.cvode_path, time_unit, c.quantity_unit,
               "CVODE at cvode_check_rtol, every CVODE step and the scene's increments");
  }
}

void write_hdf5_file(const fs::path& path, const AccuracyReport& report) {
  h5::File file = h5::File::create(path, true);
  h5::ResultHeader header;
  header.scene_kind = report.scene_kind;
  header.scene_file = report.scene_file;
  header.scene_text = report.scene_text;
  header.title = report.title;
  header.units = report.units;
  header.units.emplace_back("run_time", "s");
  h5::write_result_header(file, header);
  const h5::Group root = file.root();
  root.set_attribute("content", "work-precision study (subslip accuracy)");
  root.set_attribute("threads", report.threads);
  root.set_attribute("cvode_atol_scale", report.cvode_atol);
  const h5::Group cases = root.create_group("cases");
  std::vector<std::string> names;
  for (const auto& c : report.cases) names.push_back(c.name);
  cases.set_attribute("names", names);
  for (const auto& c : report.cases) write_case(cases, report, c);
  h5::mark_completed(file);
  file.close();
}

// A failed write (a full disk) names the file and the reason, and leaves no broken file.
void write_hdf5(const fs::path& path, const AccuracyReport& report) {
  try {
    write_hdf5_file(path, report);
  } catch (const h5::Error& e) {
    std::error_code ec;
    fs::remove(path, ec);
    throw std::runtime_error(path.string() + ": cannot " + e.action +
                             (e.reason.empty() ? "" : ": " + e.reason) + "; the file was removed");
  }
}

}  // namespace

std::vector<fs::path> accuracy_files(const fs::path& dir) {
  return {dir / kCsv, dir / kReferenceCsv, dir / kMarkdown, dir / kHdf5};
}

void check_accuracy_output(const fs::path& dir, bool overwrite) {
  if (!overwrite) {
    for (const auto& f : accuracy_files(dir)) {
      if (fs::exists(f)) {
        throw h5::OutputPathError(f.string() + ": already exists; use --force to overwrite it");
      }
    }
  }
  // Creates the directory and proves it writable.
  h5::check_output_path(dir / kHdf5, true);
}

void write_accuracy_report(const fs::path& dir, const AccuracyReport& report) {
  write_csv(dir / kCsv, report);
  write_reference_csv(dir / kReferenceCsv, report);
  write_markdown(dir / kMarkdown, report);
  write_hdf5(dir / kHdf5, report);
}

std::vector<double> error_levels(const StudyResult& study) {
  double lo = INFINITY, hi = 0.0;
  for (const auto& p : study.points) {
    if (!p.ok || !(p.error.max_error > 0.0)) continue;
    lo = std::min(lo, p.error.max_error);
    hi = std::max(hi, p.error.max_error);
  }
  std::vector<double> levels;
  if (!(hi > 0.0)) return levels;
  // Errors above 10 % of the scale are no result worth timing.
  const int top = std::min(-1, static_cast<int>(std::ceil(std::log10(hi))));
  for (int e = top; std::pow(10.0, e) >= lo * 0.999; --e) levels.push_back(std::pow(10.0, e));
  return levels;
}

}  // namespace subslip::io
