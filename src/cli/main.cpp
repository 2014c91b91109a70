// subslip command line.
//
// Subcommands register in main(); scene kinds dispatch in run_scene() on the scene's `scene:`
// key. Exit codes: 0 success, 1 other failure (HDF5, internal), 2 bad input (scene file,
// command line, output path), 3 numerical failure (a contact step that cannot be completed).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "subslip/contact/contact_point.hpp"
#include "subslip/io/contact_output.hpp"
#include "subslip/io/contact_scene.hpp"
#include "subslip/io/h5_writer.hpp"
#include "subslip/io/input_error.hpp"
#include "subslip/io/scene_common.hpp"
#include "subslip/io/yaml_checked.hpp"

namespace fs = std::filesystem;
using namespace subslip;

namespace {

struct RunArgs {
  std::string scene;
  std::string output;  // empty: results/<scene stem>.h5
  bool force = false;
  bool quiet = false;
  int threads = 0;
  double flush_interval = 0.25;
};

fs::path output_path(const RunArgs& a) {
  if (!a.output.empty()) return a.output;
  return fs::path("results") / (fs::path(a.scene).stem().string() + ".h5");
}

std::string number(double x, const char* format) {
  if (std::isnan(x)) return "-";
  char buf[32];
  std::snprintf(buf, sizeof buf, format, x);
  return buf;
}

void print_contact_table(const io::ContactScene& scene,
                         const std::vector<io::ContactCaseResult>& results) {
  std::size_t width = 4;
  for (const auto& r : results) width = std::max(width, r.name.size());
  const int w = static_cast<int>(width);
  const std::string slip_head = "slip@peak[" + scene.units.length + "]";
  std::printf("%-*s  %9s  %14s  %9s  %9s  %9s  %9s  %8s  %8s\n", w, "case", "peak",
              slip_head.c_str(), "bottom", "steady", "increments", "newton", "cutbacks", "wall[s]");
  for (const auto& r : results) {
    const auto& s = r.summary;
    std::printf("%-*s  %9s  %14s  %9s  %9s  %9ld  %9ld  %8ld  %8s%s\n", w, r.name.c_str(),
                number(s.peak_ratio, "%.5f").c_str(), number(s.slip_at_peak, "%.4g").c_str(),
                number(s.bottom_ratio, "%.5f").c_str(),
                number(s.steady_ratio_analytical, "%.5f").c_str(), s.stats.increments,
                s.stats.iterations, s.stats.cutbacks, number(s.stats.wall_seconds, "%.3f").c_str(),
                r.failure.empty() ? "" : "  FAILED");
  }
  std::printf(
      "(peak, bottom, steady: f_t/f_n; bottom = minimum after the peak; steady = analytical "
      "steady state at the last sliding speed)\n");
}

int run_contact(const RunArgs& a, const io::YamlDocument& document) {
  // Every input and output check comes before the first step is computed.
  const io::ContactScene scene = io::parse_contact_scene(document);
  const fs::path out = output_path(a);
  io::h5::check_output_path(out, a.force);
  io::h5::File file = io::h5::File::create(out, a.force);
  if (!a.quiet) {
    std::printf("subslip: %s: %zu case%s%s%s\n", a.scene.c_str(), scene.cases.size(),
                scene.cases.size() == 1 ? "" : "s", scene.title.empty() ? "" : " - ",
                scene.title.c_str());
    std::fflush(stdout);
  }
  io::ContactRunOptions options;
  options.threads = a.threads;
  options.flush_interval = std::chrono::duration<double>(a.flush_interval);
  const auto results = io::run_contact_scene(scene, file, options);
  file.close();
  if (!a.quiet) {
    print_contact_table(scene, results);
    std::printf("results: %s\n", out.c_str());
  }
  for (const auto& r : results) {
    if (!r.failure.empty()) throw contact::StepFailure(r.failure);
  }
  return 0;
}

// The dispatch on `scene:`. A new scene kind adds its name to the list and a branch here.
int run_scene(const RunArgs& a) {
  const io::YamlDocument document = io::YamlDocument::from_file(a.scene);
  const std::string kind = io::scene_kind(document, {"contact"});
  if (kind == "contact") return run_contact(a, document);
  throw InputError(a.scene, 0, "scene", "no runner for scene kind '" + kind + "'");
}

void add_run_command(CLI::App& app, RunArgs& a) {
  CLI::App* run = app.add_subcommand("run", "Run a scene file and write its results to HDF5");
  run->add_option("scene", a.scene, "Scene file (YAML, see docs/scenes.md)")->required();
  run->add_option("-o,--output", a.output, "Result file (default: results/<scene stem>.h5)");
  run->add_flag("-f,--force", a.force, "Overwrite an existing result file");
  run->add_flag("-q,--quiet", a.quiet, "Print nothing but errors");
  run->add_option("-j,--threads", a.threads, "Threads for sweep cases (default: OpenMP's)")
      ->check(CLI::NonNegativeNumber);
  run->add_option("--flush-interval", a.flush_interval,
                  "Flush the result file at most every SECONDS while a case runs; 0 = after "
                  "every output step (slow: gzip chunks are recompressed at each flush)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
}

int report(const char* message, int code) {
  std::fprintf(stderr, "subslip: error: %s\n", message);
  return code;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"subslip: subloading-overstress friction on contacts and crystal slip systems"};
  app.require_subcommand(1);
  app.set_version_flag("--version", SUBSLIP_VERSION);
  RunArgs run_args;
  add_run_command(app, run_args);
  // Further subcommands (post, bench, accuracy, orientations) register here, each with its
  // own argument struct and a branch below.
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;  // usage errors are input errors
  }
  try {
    if (app.got_subcommand("run")) return run_scene(run_args);
  } catch (const InputError& e) {
    return report(e.what(), 2);
  } catch (const io::h5::OutputPathError& e) {
    return report(e.what(), 2);
  } catch (const contact::StepFailure& e) {
    return report(e.what(), 3);
  } catch (const std::exception& e) {
    return report(e.what(), 1);
  }
  return 0;
}
