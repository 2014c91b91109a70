// subslip command line.
//
// Subcommands register in main(); scene kinds dispatch in run_scene() on the scene's `scene:`
// key. Exit codes: 0 success, 1 other failure (HDF5, internal), 2 bad input (scene file,
// command line, output path), 3 numerical failure (a contact or crystal step that cannot be
// completed).
#include <CLI/CLI.hpp>

#include "accuracy.hpp"
#include "bench.hpp"
#include "fit.hpp"
#include "post.hpp"
#include "run_scene.hpp"
#include "validators.hpp"

#include <array>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <stdexcept>
#include <string>

#include "subslip/crystal/flow_point_batch.hpp"
#include "subslip/crystal/texture.hpp"
#include "subslip/io/h5_writer.hpp"
#include "subslip/io/input_error.hpp"
#include "subslip/io/orientation_file.hpp"
#include "subslip/parallel/team.hpp"

namespace fs = std::filesystem;
using namespace subslip;

using cli::exit_code_of;
using cli::RunArgs;
using cli::StoppedBySignal;

namespace {

void add_run_command(CLI::App& app, RunArgs& a) {
  CLI::App* run = app.add_subcommand("run", "Run a scene file and write its results to HDF5");
  run->add_option("scene", a.scene,
                  "Scene file (YAML, see docs/scenes.md); with --restart optional (then it must "
                  "be the scene the run started with)");
  run->add_option("--set", a.settings,
                  "PATH=VALUE: the value at PATH (a key path as in a sweep, "
                  "loading[0].increments) set over the scene's, checked as the scene's own; "
                  "repeatable, applied in order; recorded in the result file")
      ->allow_extra_args(false);
  run->add_option("-o,--output", a.output, "Result file (default: results/<scene stem>.h5)");
  run->add_flag("-f,--force", a.force, "Overwrite an existing result file");
  run->add_flag("-q,--quiet", a.quiet, "Print nothing but errors");
  run->add_flag("-v,--verbose", a.verbose,
                "When writing the result file fails, print HDF5's error stack as well");
  run->add_option("-j,--threads", a.threads,
                  "Threads: for sweep cases (contact) or for the grains of a case (crystal); "
                  "default: OpenMP's")
      ->check(cli::non_negative());
  run->add_option("--flush-interval", a.flush_interval,
                  "Write rows to the result file at most every SECONDS; 0 = after every output "
                  "step, unless writing costs over ~5 % of the computation (then every few ms)")
      ->check(cli::non_negative())
      ->capture_default_str();
  run->add_option("--restart", a.restart,
                  "Continue the killed run that wrote FILE (scene read from its /scene): "
                  "completed cases are kept, an interrupted crystal case continues from its last "
                  "checkpoint; the result equals an uninterrupted run bit for bit (a warning says "
                  "where this build or its SIMD kernels round differently from the file's)");
  run->add_option("--checkpoint-every", a.checkpoint_every,
                  "Crystal runs: write a checkpoint every N increments (0: never); default: "
                  "output.checkpoint_every of the scene, else about once a minute")
      ->check(cli::non_negative());
  run->add_flag("--keep-restart", a.keep_restart,
                "Crystal runs: keep the restart file (checkpoints, <result stem>.restart.h5) "
                "when the run finishes; default: it is deleted");
  run->add_flag("--gather-output", a.gather_output,
                "Under MPI: rank 0 writes every rank's grains (gathered to it) instead of all "
                "ranks writing the file together through MPI-IO; for file systems without "
                "MPI-IO support (NFS). Needs the whole output state of a case on rank 0");
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
                     ->check(cli::positive());
  auto* component = cmd->add_option("--component", a.component,
                                    "A texture component: cube, goss, brass, copper or s");
  random->excludes(component);
  cmd->add_option("--count", a.count, "Orientations of the component")
      ->check(cli::positive())
      ->needs(component);
  cmd->add_option("--spread", a.spread, "RMS misorientation to the ideal component [deg]")
      ->check(cli::between(0.0, 180.0))
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

// Several input errors: one "subslip: error:" line each, as a single one has.
int report(const std::exception& e, int code) {
  const auto* several = dynamic_cast<const InputErrors*>(&e);
  if (several == nullptr) return report(e.what(), code);
  for (const InputError& one : several->all) report(one.what(), code);
  if (several->stopped) report(InputErrors::limit_line(several->all.size()).c_str(), code);
  return code;
}

// What the run stopped on, reported once (by the root) with its exit status. Over MPI ranks, a
// failure every rank meets alike (bad input, a failed grain: the ranks agree on it, or the
// root's, shared by parallel::on_root) ends each rank with the same status; any other failure
// on a rank stops them all (MPI_Abort), since the others would wait for it forever.
int stop_on(const std::exception& e, const parallel::Team& team) {
  const std::exception_ptr failure = std::current_exception();
  const int code = exit_code_of(failure);
  // A stop on request is no error: said once, by the root.
  if (dynamic_cast<const StoppedBySignal*>(&e) != nullptr) {
    if (team.is_root()) std::fprintf(stderr, "subslip: %s\n", e.what());
    return code;
  }
  if (team.size() == 1) return report(e, code);
  const bool shared = code != 1 || dynamic_cast<const parallel::StoppedByRoot*>(&e) != nullptr ||
                      (team.is_root() && parallel::root_failure_shared());
  if (team.is_root()) report(e, code);
  if (shared) return code;
  if (!team.is_root())
    std::fprintf(stderr, "subslip: error on MPI rank %d: %s\n", team.rank(), e.what());
  team.abort(code);
  return code;  // (not reached)
}

// Every rank takes the same grain kernels (the widest every rank has), so that a run's results
// do not depend on how its grains are spread over machines whose instruction sets differ:
// results of different kernels differ by round-off.
void agree_on_flow_batches(const parallel::Team& team) {
  std::array<std::int64_t, 1> level{crystal::detail::flow_batch_level()};
  team.min(level);
  crystal::detail::limit_flow_batches(static_cast<int>(level[0]));
}

}  // namespace

int main(int argc, char** argv) {
  // Before anything else: MPI may take its own arguments. Without mpirun this is one rank.
  const parallel::Session session(argc, argv);
  const parallel::Team& team = session.team();
  agree_on_flow_batches(team);
  CLI::App app{"subslip: subloading-overstress friction on contacts and crystal slip systems"};
  app.require_subcommand(1);
  app.set_version_flag(
      "--version",
      std::string(SUBSLIP_VERSION) + " (" + SUBSLIP_BUILD +
          " build; crystal flow points in SIMD batches: " + crystal::detail::flow_batch_isa_name() +
          "; grain step of 12, 24 and 48 systems: " + crystal::detail::grain_step_isa_name() + ")");
  RunArgs run_args;
  add_run_command(app, run_args);
  OrientationArgs orientation_args;
  add_orientations_command(app, orientation_args);
  cli::BenchArgs bench_args;
  cli::add_bench_command(app, bench_args);
  cli::AccuracyArgs accuracy_args;
  cli::add_accuracy_command(app, accuracy_args);
  cli::PostArgs post_args;
  cli::add_post_command(app, post_args);
  cli::FitArgs fit_args;
  cli::add_fit_command(app, fit_args);
  // Further subcommands (post, accuracy) register here, each with its own argument struct and
  // a branch below.
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (!team.is_root()) return 2;
    if (e.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) return app.exit(e);
    // Usage errors are input errors, reported like every other error (one line, exit 2).
    std::fprintf(stderr, "subslip: error: %s (subslip --help lists the options)\n", e.what());
    return 2;
  }
  try {
    if (app.got_subcommand("run")) return cli::run_scene(run_args, team);
    // The other commands are one process's work: over MPI ranks the root does it.
    if (!team.is_root()) return 0;
    if (app.got_subcommand("orientations")) return run_orientations(orientation_args);
    if (app.got_subcommand("bench")) return cli::run_bench(bench_args);
    if (app.got_subcommand("accuracy")) return cli::run_accuracy(accuracy_args);
    if (app.got_subcommand("post")) return cli::run_post(post_args);
    if (app.got_subcommand("fit")) return cli::run_fit(fit_args);
  } catch (const std::exception& e) {
    return stop_on(e, team);
  }
  return 0;
}
