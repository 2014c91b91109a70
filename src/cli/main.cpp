// subslip command line.
//
// Subcommands register in main(); scene kinds dispatch in run_scene() on the scene's `scene:`
// key. Exit codes: 0 success, 1 other failure (HDF5, internal), 2 bad input (scene file,
// command line, output path), 3 numerical failure (a contact or crystal step that cannot be
// completed).
#include <omp.h>

#include <CLI/CLI.hpp>

#include "bench.hpp"
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

#include "subslip/contact/contact_point.hpp"
#include "subslip/crystal/aggregate.hpp"
#include "subslip/crystal/texture.hpp"
#include "subslip/io/contact_output.hpp"
#include "subslip/io/contact_scene.hpp"
#include "subslip/io/crystal_output.hpp"
#include "subslip/io/crystal_scene.hpp"
#include "subslip/io/h5_writer.hpp"
#include "subslip/io/input_error.hpp"
#include "subslip/io/orientation_file.hpp"
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

// ---- crystal scenes

std::string component_label(std::pair<int, int> ij) {
  return std::to_string(ij.first + 1) + std::to_string(ij.second + 1);
}

void print_crystal_header(const io::CrystalScene& scene, std::size_t width) {
  const auto axis = io::loading_component(scene.cases.front().segments);
  const std::string ij = component_label(axis);
  const std::string strain = "strain_" + ij;
  const std::string stress = "stress_" + ij + "[" + scene.units.stress + "]";
  const std::string mises = "vMises[" + scene.units.stress + "]";
  std::printf("%-*s  %10s  %16s  %14s  %14s  %12s  %8s  %8s\n", static_cast<int>(width), "case",
              strain.c_str(), stress.c_str(), mises.c_str(), "grain-steps/s", "newton/solve",
              "cutbacks", "wall[s]");
}

void print_crystal_row(const io::CrystalCaseResult& r, std::size_t width) {
  const auto& s = r.summary;
  const auto [i, j] = s.axis;
  std::printf("%-*s  %10s  %16s  %14s  %14s  %12s  %8ld  %8s%s\n", static_cast<int>(width),
              r.name.c_str(), number(s.final_state.strain(i, j), "%.5f").c_str(),
              number(s.final_state.stress(i, j), "%.4g").c_str(),
              number(s.final_von_mises_stress, "%.4g").c_str(),
              number(s.grain_steps_per_second, "%.4g").c_str(),
              number(s.newton_per_grain_solve, "%.3f").c_str(), s.stats.cutbacks,
              number(s.stats.wall_seconds, "%.3f").c_str(), r.failure.empty() ? "" : "  FAILED");
  std::fflush(stdout);
}

void print_crystal_intro(const RunArgs& a, const io::CrystalScene& scene) {
  const io::CrystalCase& first = scene.cases.front();
  std::printf("subslip: %s: %zu case%s%s%s\n", a.scene.c_str(), scene.cases.size(),
              scene.cases.size() == 1 ? "" : "s", scene.title.empty() ? "" : " - ",
              scene.title.c_str());
  std::printf(
      "  %zu grain%s, %zu slip systems, %d thread%s (strain and stress along the "
      "loading component; final values)\n",
      first.orientations.size(), first.orientations.size() == 1 ? "" : "s",
      crystal::described_systems(first.phase).size(), omp_get_max_threads(),
      omp_get_max_threads() == 1 ? "" : "s");
  std::fflush(stdout);
}

int run_crystal(const RunArgs& a, const io::YamlDocument& document) {
  // Every input and output check comes before the first step is computed.
  const io::CrystalScene scene = io::parse_crystal_scene(document);
  const fs::path out = output_path(a);
  io::h5::check_output_path(out, a.force);
  io::h5::File file = io::h5::File::create(out, a.force);
  // Crystal cases run one after the other; the threads go to the grains of a case.
  if (a.threads > 0) omp_set_num_threads(a.threads);
  std::size_t width = 4;
  for (const auto& c : scene.cases) width = std::max(width, c.name.size());
  if (!a.quiet) {
    print_crystal_intro(a, scene);
    print_crystal_header(scene, width);
  }
  io::CrystalRunOptions options;
  options.flush_interval = std::chrono::duration<double>(a.flush_interval);
  options.on_case_done = [&](std::size_t, const io::CrystalCase&, const io::CrystalCaseResult& r) {
    if (!a.quiet) print_crystal_row(r, width);
  };
  const auto results = io::run_crystal_scene(scene, file, options);
  file.close();
  if (!a.quiet) std::printf("results: %s\n", out.c_str());
  for (const auto& r : results) {
    if (!r.failure.empty()) throw crystal::CrystalStepFailure(r.failure);
  }
  return 0;
}

// The dispatch on `scene:`. A new scene kind adds its name to the list and a branch here.
int run_scene(const RunArgs& a) {
  const io::YamlDocument document = io::YamlDocument::from_file(a.scene);
  const std::string kind = io::scene_kind(document, {"contact", "crystal"});
  if (kind == "contact") return run_contact(a, document);
  if (kind == "crystal") return run_crystal(a, document);
  throw InputError(a.scene, 0, "scene", "no runner for scene kind '" + kind + "'");
}

void add_run_command(CLI::App& app, RunArgs& a) {
  CLI::App* run = app.add_subcommand("run", "Run a scene file and write its results to HDF5");
  run->add_option("scene", a.scene, "Scene file (YAML, see docs/scenes.md)")->required();
  run->add_option("-o,--output", a.output, "Result file (default: results/<scene stem>.h5)");
  run->add_flag("-f,--force", a.force, "Overwrite an existing result file");
  run->add_flag("-q,--quiet", a.quiet, "Print nothing but errors");
  run->add_option("-j,--threads", a.threads,
                  "Threads: for sweep cases (contact) or for the grains of a case (crystal); "
                  "default: OpenMP's")
      ->check(CLI::NonNegativeNumber);
  run->add_option("--flush-interval", a.flush_interval,
                  "Flush the result file at most every SECONDS while a case runs; 0 = after "
                  "every output step (slow: gzip chunks are recompressed at each flush)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
}

// ---- subslip orientations

struct OrientationArgs {
  std::size_t random = 0;  // --random N
  std::string component;   // --component NAME
  std::size_t count = 1;   // with --component
  double spread = 0.0;     // degrees, with --component
  std::uint64_t seed = 1;
  std::string output;  // empty: standard output
  bool force = false;
};

void add_orientations_command(CLI::App& app, OrientationArgs& a) {
  CLI::App* cmd = app.add_subcommand(
      "orientations", "Write an orientation file (docs/orientations.md): random or a component");
  auto* random = cmd->add_option("--random", a.random, "N uniformly random orientations")
                     ->check(CLI::PositiveNumber);
  auto* component = cmd->add_option("--component", a.component,
                                    "A texture component: cube, goss, brass, copper or s");
  random->excludes(component);
  cmd->add_option("--count", a.count, "Orientations of the component")
      ->check(CLI::PositiveNumber)
      ->needs(component);
  cmd->add_option("--spread", a.spread, "RMS misorientation to the ideal component [deg]")
      ->check(CLI::Range(0.0, 180.0))
      ->needs(component);
  cmd->add_option("--seed", a.seed, "Random seed")->capture_default_str();
  cmd->add_option("-o,--output", a.output, "Output file (default: standard output)");
  cmd->add_flag("-f,--force", a.force, "Overwrite an existing file");
}

int run_orientations(const OrientationArgs& a) {
  crystal::OrientationRequest request;
  request.seed = a.seed;
  if (!a.component.empty()) {
    try {
      request.component = crystal::parse_texture_component(a.component);
    } catch (const std::invalid_argument& e) {
      throw InputError("--component", 0, "", e.what());
    }
    request.count = a.count;
    request.spread_deg = a.spread;
  } else if (a.random > 0) {
    request.count = a.random;
  } else {
    throw InputError("orientations", 0, "", "give --random N or --component NAME");
  }
  if (!a.output.empty() && fs::exists(a.output) && !a.force) {
    throw io::h5::OutputPathError(a.output + ": already exists; use --force to overwrite it");
  }
  const std::string text = io::write_orientation_file(a.output, request);
  if (a.output.empty()) {
    std::fputs(text.c_str(), stdout);
  } else {
    std::fprintf(stderr, "subslip: wrote %zu orientations (%s) to %s\n", request.count,
                 crystal::describe(request).c_str(), a.output.c_str());
  }
  return 0;
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
  OrientationArgs orientation_args;
  add_orientations_command(app, orientation_args);
  cli::BenchArgs bench_args;
  cli::add_bench_command(app, bench_args);
  // Further subcommands (post, accuracy) register here, each with its own argument struct and
  // a branch below.
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;  // usage errors are input errors
  }
  try {
    if (app.got_subcommand("run")) return run_scene(run_args);
    if (app.got_subcommand("orientations")) return run_orientations(orientation_args);
    if (app.got_subcommand("bench")) return cli::run_bench(bench_args);
  } catch (const InputError& e) {
    return report(e.what(), 2);
  } catch (const io::h5::OutputPathError& e) {
    return report(e.what(), 2);
  } catch (const contact::StepFailure& e) {
    return report(e.what(), 3);
  } catch (const crystal::CrystalStepFailure& e) {
    return report(e.what(), 3);
  } catch (const std::exception& e) {
    return report(e.what(), 1);
  }
  return 0;
}
