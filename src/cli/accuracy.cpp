#include "accuracy.hpp"
#include "validators.hpp"

#include <omp.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>

#include "subslip/driver/crystal_run.hpp"
#include "subslip/io/accuracy_output.hpp"
#include "subslip/io/contact_scene.hpp"
#include "subslip/io/crystal_scene.hpp"
#include "subslip/io/input_error.hpp"
#include "subslip/io/scene_compose.hpp"
#include "subslip/io/text_layout.hpp"
#include "subslip/io/yaml_checked.hpp"
#include "subslip/study/work_precision.hpp"

namespace subslip::cli {

namespace {

namespace fs = std::filesystem;
using study::Integrator;

fs::path output_dir(const AccuracyArgs& a) {
  if (!a.output.empty()) return a.output;
  return fs::path("results") / ("accuracy_" + fs::path(a.scene).stem().string());
}

Integrator parse_integrator(const std::string& name) {
  for (Integrator i : study::kAllIntegrators)
    if (study::to_string(i) == name) return i;
  throw InputError("--integrators", 0, "", "unknown integrator '" + name + "'");
}

std::vector<std::string> integrator_names() {
  std::vector<std::string> names;
  for (Integrator i : study::kAllIntegrators) names.emplace_back(study::to_string(i));
  return names;
}

study::StudyOptions study_options(const AccuracyArgs& a) {
  study::StudyOptions o;
  if (a.reference_tolerance > 0.0) {
    static constexpr Integrator kOfOrder[] = {
        Integrator::implicit_adaptive, Integrator::extrapolated_2, Integrator::extrapolated_3,
        Integrator::extrapolated_4};
    o.reference = {kOfOrder[a.reference_order - 1], a.reference_tolerance};
  } else {
    const double finest = *std::max_element(a.implicit.begin(), a.implicit.end());
    o.reference = {Integrator::implicit,
                   a.reference_factor > 0.0 ? a.reference_factor : 16.0 * finest};
  }
  o.reference_at_run_times = a.reference_at_run_times;
  o.cvode_check_rtol = a.cvode_check_rtol;
  o.cvode_check_seconds = a.cvode_check_seconds;
  o.repeat = a.repeat;
  o.repeat_budget_seconds = a.repeat_budget;
  o.max_run_seconds = a.max_run_seconds;
  for (const auto& name : a.integrators) {
    study::Ladder l;
    l.integrator = parse_integrator(name);
    switch (l.integrator) {
      case Integrator::forward_euler:
        // Without --fe: from the scene's increments up by x4 until the run-time budget.
        l.values = a.forward_euler.empty() ? std::vector<double>{1.0} : a.forward_euler;
        l.extend_until_budget = a.forward_euler.empty();
        l.uniform = a.fe_uniform;
        break;
      case Integrator::implicit:
        l.values = a.implicit;
        break;
      case Integrator::implicit_adaptive:
        l.values = a.adaptive;
        break;
      case Integrator::extrapolated_2:
      case Integrator::extrapolated_3:
      case Integrator::extrapolated_4:
        l.values = a.extrapolated;
        break;
      case Integrator::cvode:
        l.values = a.cvode;
        l.atol_scale = a.cvode_atol;
        break;
    }
    o.ladders.push_back(l);
  }
  if (!a.quiet) {
    // Indented under the case; long lines (the reference, failures) wrapped to 80 columns.
    o.progress = [](std::string_view line) {
      const std::string indented = "  " + std::string(line);
      for (const auto& l : io::text::wrap_words(indented, io::text::kTextColumns, "    "))
        std::printf("%s\n", l.c_str());
      std::fflush(stdout);
    };
  }
  return o;
}

bool selected(const AccuracyArgs& a, const std::string& name) {
  return a.cases.empty() || std::find(a.cases.begin(), a.cases.end(), name) != a.cases.end();
}

template <class Case>
void check_case_names(const AccuracyArgs& a, const std::vector<Case>& cases) {
  for (const auto& wanted : a.cases) {
    const bool known =
        std::any_of(cases.begin(), cases.end(), [&](const Case& c) { return c.name == wanted; });
    if (known) continue;
    std::string list;
    for (const auto& c : cases) list += (list.empty() ? "" : ", ") + c.name;
    throw InputError(a.scene, 0, "--case", "no case '" + wanted + "' (cases: " + list + ")");
  }
}

void announce(const AccuracyArgs& a, const std::string& name, const study::Problem& p) {
  if (a.quiet) return;
  const std::string line = "case " + name + ": " + p.quantity() + ", " +
                           std::to_string(p.base_increments()) + " increments in the scene";
  for (const auto& l : io::text::wrap_words(line, io::text::kTextColumns, "  "))
    std::printf("%s\n", l.c_str());
  std::fflush(stdout);
}

// One case to study: its name, the unit of its measured quantity, and the problem.
struct StudyCase {
  std::string name;
  std::string unit;
  std::unique_ptr<study::Problem> problem;
};

// Parses the scene (every input error before anything is computed or written) into the cases
// to study, and fills the report's scene fields.
std::vector<StudyCase> contact_cases(const AccuracyArgs& a, const io::YamlDocument& doc,
                                     io::AccuracyReport& rep) {
  const io::ContactScene scene = io::parse_contact_scene(doc);
  check_case_names(a, scene.cases);
  rep.title = scene.title;
  rep.units = scene.units.entries();
  std::vector<StudyCase> out;
  for (const auto& c : scene.cases) {
    if (!selected(a, c.name)) continue;
    out.push_back(
        {c.name, "1", std::make_unique<study::ContactProblem>(c.model, c.segments, c.integrator)});
  }
  return out;
}

study::CrystalProblem::Measure crystal_measure(const std::string& name) {
  using Measure = study::CrystalProblem::Measure;
  if (name == "stress") return Measure::stress;
  if (name == "resolved") return Measure::resolved;
  return Measure::state;
}

std::vector<StudyCase> crystal_cases(const AccuracyArgs& a, const io::YamlDocument& doc,
                                     io::AccuracyReport& rep) {
  const io::CrystalScene scene = io::parse_crystal_scene(doc);
  check_case_names(a, scene.cases);
  rep.title = scene.title;
  rep.units = io::crystal_units(scene.units);
  std::vector<StudyCase> out;
  for (const auto& c : scene.cases) {
    if (!selected(a, c.name)) continue;
    out.push_back({c.name, scene.units.stress,
                   std::make_unique<study::CrystalProblem>(
                       c.phase, c.orientations, c.segments, c.options,
                       driver::loading_component(c.segments), crystal_measure(a.measure),
                       a.reference_at_run_times ? study::CrystalProblem::TimeAxis::segment
                                                : study::CrystalProblem::TimeAxis::absolute)});
  }
  return out;
}

fs::path plot_script() {
  if (const char* env = std::getenv("SUBSLIP_PLOT_SCRIPT")) return env;
  return fs::path(SUBSLIP_SOURCE_DIR) / "scripts" / "plot_accuracy.py";
}

// Runs scripts/plot_accuracy.py on the study directory; a missing Python or matplotlib is
// reported with the command that makes the plot later (the tables are written either way).
void plot(const fs::path& dir, bool quiet) {
  const fs::path python = "/usr/bin/python3";
  const fs::path script = plot_script();
  const std::string later = python.string() + " " + script.string() + " " + dir.string();
  if (!fs::exists(python) || !fs::exists(script)) {
    std::fprintf(stderr, "subslip: no plot: %s not found; with Python 3 and matplotlib run: %s\n",
                 fs::exists(python) ? script.c_str() : python.c_str(), later.c_str());
    return;
  }
  std::fflush(stdout);
  const pid_t child = ::fork();
  if (child == 0) {
    std::vector<std::string> args{python.string(), script.string(), dir.string()};
    if (quiet) args.emplace_back("--quiet");
    std::vector<char*> argv;
    for (auto& s : args) argv.push_back(s.data());
    argv.push_back(nullptr);
    ::execv(argv[0], argv.data());
    std::_Exit(127);
  }
  int status = 0;
  if (child < 0 || ::waitpid(child, &status, 0) < 0 || !WIFEXITED(status) ||
      WEXITSTATUS(status) != 0) {
    std::fprintf(stderr, "subslip: the plot was not made (see above); to retry: %s\n",
                 later.c_str());
  }
}

}  // namespace

void add_accuracy_command(CLI::App& app, AccuracyArgs& a) {
  CLI::App* cmd = app.add_subcommand(
      "accuracy", "Work-precision study: error against run time of every integrator on a scene");
  cmd->add_option("scene", a.scene, "Scene file (contact or crystal)")->required();
  cmd->add_option("-o,--output", a.output,
                  "Directory for accuracy.{csv,md,h5} and the plots (default: "
                  "results/accuracy_<scene stem>)");
  cmd->add_flag("-f,--force", a.force, "Overwrite the study files in the directory");
  cmd->add_flag("-q,--quiet", a.quiet, "Print nothing but errors");
  cmd->add_option("--case", a.cases, "Study only these cases of a swept scene");
  cmd->add_option("--integrators", a.integrators, "Integrators to study")
      ->check(CLI::IsMember(integrator_names()))
      ->capture_default_str();
  cmd->add_option("--fe", a.forward_euler,
                  "Forward Euler increment factors (relative to the scene); default: 1, 4, 16, "
                  "... until --max-run-seconds")
      ->check(cli::positive());
  cmd->add_flag("--fe-uniform", a.fe_uniform,
                "Forward Euler with uniform increments (as many as the graded ones): where "
                "stability bounds its step everywhere, grading only wastes steps");
  cmd->add_option("--implicit", a.implicit, "Implicit (fixed-step) increment factors")
      ->check(cli::positive())
      ->capture_default_str();
  cmd->add_option("--adaptive", a.adaptive, "Adaptive implicit tolerances")
      ->check(cli::above_and_at_most(0.0, 1.0))
      ->capture_default_str();
  cmd->add_option("--extrapolated", a.extrapolated,
                  "Tolerances of the extrapolated implicit integrators (orders 2, 3 and 4)")
      ->check(cli::above_and_at_most(0.0, 1.0))
      ->capture_default_str();
  cmd->add_option("--cvode", a.cvode, "CVODE relative tolerances")
      ->check(cli::above_and_at_most(0.0, 1.0))
      ->capture_default_str();
  cmd->add_option("--cvode-atol", a.cvode_atol,
                  "CVODE absolute tolerance, relative to each component's scale (never looser "
                  "than the rtol)")
      ->check(cli::above_and_at_most(0.0, 1.0))
      ->capture_default_str();
  auto* factor = cmd->add_option("--reference-factor", a.reference_factor,
                                 "Increment factor of the implicit reference, extrapolated with "
                                 "half of it (default: 16 x the largest --implicit factor)")
                     ->check(cli::positive());
  auto* tolerance = cmd->add_option("--reference-tolerance", a.reference_tolerance,
                                    "Instead: an adaptive implicit reference at this tolerance")
                        ->check(cli::above_and_at_most(0.0, 1.0))
                        ->excludes(factor);
  cmd->add_option("--reference-order", a.reference_order,
                  "Order of the adaptive reference: 1 backward Euler's estimate, 2 .. 4 "
                  "extrapolated (whose estimate is on what the state determines)")
      ->check(CLI::Range(1, 4))
      ->needs(tolerance)
      ->capture_default_str();
  cmd->add_flag("--reference-at-run-times", a.reference_at_run_times,
                "Crystal: compare every run with the adaptive reference recomputed with its "
                "steps ending at exactly that run's times (no interpolation; each point costs a "
                "reference and its 10x looser companion more)")
      ->needs(tolerance);
  cmd->add_option("--measure", a.measure,
                  "Crystal: what the error is measured on besides the loading component: "
                  "'state', every grain's r, ln(CRSS) and r_s of each system; 'resolved', "
                  "every grain's resolved shear of each system over its yield scale, the CRSS "
                  "or a compressed pressure-sensitive plane's mu f_n (what the extrapolated "
                  "estimate bounds); 'stress', every grain's stress (where the "
                  "split of slip among systems, and so each CRSS, is not determined)")
      ->check(CLI::IsMember({"state", "stress", "resolved"}))
      ->capture_default_str();
  cmd->add_option("--cvode-check-rtol", a.cvode_check_rtol,
                  "rtol of the CVODE run that cross-checks the reference")
      ->check(cli::above_and_at_most(0.0, 1.0))
      ->capture_default_str();
  cmd->add_option("--cvode-check-seconds", a.cvode_check_seconds,
                  "Stop the CVODE cross-check of the reference after this long")
      ->check(cli::positive())
      ->capture_default_str();
  cmd->add_option("--repeat", a.repeat, "Timed runs per point (median)")
      ->check(cli::between(1, 1000))
      ->capture_default_str();
  cmd->add_option("--repeat-budget", a.repeat_budget,
                  "Seconds of repeated runs per point: slow points get fewer repeats")
      ->check(cli::non_negative())
      ->capture_default_str();
  cmd->add_option("--max-run-seconds", a.max_run_seconds,
                  "Skip ladder points expected to run longer than this, and stop runs that do")
      ->check(cli::positive())
      ->capture_default_str();
  cmd->add_option("-j,--threads", a.threads, "OpenMP threads for the grains of a crystal")
      ->check(cli::positive())
      ->capture_default_str();
  cmd->add_flag("--no-plot", a.no_plot, "Do not run scripts/plot_accuracy.py");
}

int run_accuracy(const AccuracyArgs& a) {
  const io::YamlDocument document = io::compose_scene(io::YamlDocument::from_file(a.scene));
  const std::string kind = io::scene_kind(document, {"contact", "crystal"});
  io::AccuracyReport report;
  report.scene_file = a.scene;
  report.scene_text = document.text();
  report.scene_kind = kind;
  report.cvode_check_rtol = a.cvode_check_rtol;
  report.cvode_atol = a.cvode_atol;
  report.threads = a.threads;
  const auto cases =
      kind == "contact" ? contact_cases(a, document, report) : crystal_cases(a, document, report);
  const fs::path dir = output_dir(a);
  io::check_accuracy_output(dir, a.force);
  omp_set_num_threads(a.threads);
  const auto options = study_options(a);
  try {
    for (const auto& c : cases) {
      announce(a, c.name, *c.problem);
      report.cases.push_back({c.name, c.unit, study::run_study(*c.problem, options)});
    }
  } catch (const study::ReferenceFailure& e) {
    std::fprintf(stderr, "subslip: error: %s: %s\n", a.scene.c_str(), e.what());
    return 3;  // a numerical failure
  }
  io::write_accuracy_report(dir, report);
  if (!a.quiet) std::printf("study: %s/accuracy.{csv,md,h5}\n", dir.c_str());
  if (!a.no_plot) plot(dir, a.quiet);
  return 0;
}

}  // namespace subslip::cli
