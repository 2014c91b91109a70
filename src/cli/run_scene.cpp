// `subslip run` (run_scene.hpp): the scene's kinds, the result file, tables and progress.
#include <omp.h>

#include <signal.h>
#include <unistd.h>
#include "progress.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "run_scene.hpp"
#include "subslip/contact/contact_point.hpp"
#include "subslip/crystal/aggregate.hpp"
#include "subslip/crystal/flow_point_batch.hpp"
#include "subslip/crystal/texture.hpp"
#include "subslip/driver/checkpoint_policy.hpp"
#include "subslip/driver/contact_run.hpp"
#include "subslip/driver/crystal_run.hpp"
#include "subslip/driver/orientation_sharing.hpp"
#include "subslip/driver/sink_error.hpp"
#include "subslip/history/contact_history.hpp"
#include "subslip/io/contact_output.hpp"
#include "subslip/io/contact_scene.hpp"
#include "subslip/io/crystal_output.hpp"
#include "subslip/io/crystal_scene.hpp"
#include "subslip/io/h5_writer.hpp"
#include "subslip/io/input_error.hpp"
#include "subslip/io/orientation_file.hpp"
#include "subslip/io/restart.hpp"
#include "subslip/io/result_file.hpp"
#include "subslip/io/run_output.hpp"
#include "subslip/io/scene_common.hpp"
#include "subslip/io/scene_compose.hpp"
#include "subslip/io/scene_warnings.hpp"
#include "subslip/io/sweep.hpp"
#include "subslip/io/text_layout.hpp"
#include "subslip/io/yaml_checked.hpp"
#include "subslip/parallel/team.hpp"

namespace fs = std::filesystem;
namespace text = subslip::io::text;

namespace subslip::cli {

int exit_code_of(const std::exception_ptr& failure) {
  try {
    std::rethrow_exception(failure);
  } catch (const InputError&) {
    return 2;
  } catch (const io::h5::OutputPathError&) {
    return 2;
  } catch (const history::StepFailure&) {
    return 3;
  } catch (const crystal::CrystalStepFailure&) {
    return 3;
  } catch (const parallel::StoppedByRoot& e) {
    return e.exit_code;
  } catch (const StoppedBySignal& e) {
    return e.exit_code;
  } catch (...) {
    return 1;
  }
}

namespace {

fs::path output_path(const RunArgs& a) {
  if (!a.restart.empty()) return a.restart;
  if (!a.output.empty()) return a.output;
  return fs::path("results") / (fs::path(a.scene).stem().string() + ".h5");
}

// The checks of the output, then the file: `size` is what the run will write and need.
io::RunOutput open_output(const RunArgs& a, const io::YamlDocument& document,
                          const std::vector<std::string>& case_names,
                          const io::RestartInfo* restart, const std::vector<fs::path>& inputs,
                          const io::RunSize& size, bool checkpoints = false) {
  const io::OutputRequest request{output_path(a), !a.restart.empty(), a.force, a.keep_restart};
  return io::open_output(request, document, case_names, restart, inputs, size, checkpoints);
}

// The names of the cases' groups, as the result file lists them.
template <class Case>
std::vector<std::string> names_of(const std::vector<Case>& cases) {
  std::vector<std::string> names;
  for (const auto& c : cases) names.push_back(io::case_group_name(c.name));
  return names;
}

void print_warnings(const RunArgs& a, const std::vector<std::string>& warnings) {
  if (a.warnings != nullptr) {
    a.warnings->insert(a.warnings->end(), warnings.begin(), warnings.end());
    return;
  }
  if (a.quiet) return;
  for (const auto& w : warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
}

// The scene file (none for a scene given as text) and its base scenes, for a contact run.
std::vector<fs::path> input_files(const RunArgs& a, const model::SceneMakeup& makeup) {
  std::vector<fs::path> files;
  if (a.scene_text.empty()) files.emplace_back(a.scene);
  for (const auto& base : makeup.bases) files.emplace_back(base.first);
  return files;
}

// The progress goes to stderr (stdout keeps the results, redirected or not): a bar when stderr
// is a terminal.
cli::ProgressMode progress_mode(const RunArgs& a) {
  return cli::progress_mode(a.quiet, ::isatty(STDERR_FILENO) == 1);
}

std::string scene_label(const RunArgs& a, const std::string& scene_file) {
  return a.restart.empty() ? a.scene : scene_file + " (restart of " + a.restart + ")";
}

// `line` on stdout, wrapped into lines of at most 80 columns (continued lines indented).
void print_wrapped(const std::string& line, const char* indent = "  ") {
  for (const auto& l : text::wrap_words(line, text::kTextColumns, indent))
    std::printf("%s\n", l.c_str());
}

// "subslip: SCENE: N cases - TITLE", the title on a line of its own when both do not fit.
void print_scene_intro(const RunArgs& a, const std::string& file, std::size_t cases,
                       const std::string& title) {
  const std::string head = "subslip: " + scene_label(a, file) + ": " + std::to_string(cases) +
                           (cases == 1 ? " case" : " cases");
  if (title.empty() || text::display_width(head + " - " + title) <= text::kTextColumns) {
    print_wrapped(title.empty() ? head : head + " - " + title);
    return;
  }
  print_wrapped(head);
  print_wrapped("  " + title);
}

// The widest case name, for the name column of a table.
template <class Case>
int longest_name(const std::vector<Case>& cases) {
  int widest = 0;
  for (const auto& c : cases) widest = std::max(widest, text::display_width(c.name));
  return widest;
}

// A failed case: a line under its row (the whole message is in the result file and, for the
// first failure, in the error that ends the run).
void print_failure(const std::string& failure) {
  if (failure.empty()) return;
  std::printf("%s\n", text::fit_end("  FAILED: " + failure, text::kTextColumns).c_str());
}

// Compact headers (explained by kContactLegend) so that the table fits 80 columns.
text::Table contact_table(const io::ContactScene& scene) {
  text::Table t({{"case", 0, true},
                 {"peak", 7},
                 {"slip@peak[" + scene.units.length + "]", 7},
                 {"bottom", 7},
                 {"steady", 7},
                 {"incr", 6},
                 {"newton", 6},
                 {"cuts", 5},
                 {"wall[s]", 7}});
  t.fit_column(0, longest_name(scene.cases));
  return t;
}

constexpr const char* kContactLegend =
    "(f_t/f_n: peak, bottom = the minimum after it, steady = analytical at the last speed; incr: "
    "increments; newton: iterations per increment; cuts: cutbacks)";

void print_contact_table(const io::ContactScene& scene,
                         const std::vector<driver::ContactCaseResult>& results) {
  const text::Table t = contact_table(scene);
  std::printf("%s\n", t.header().c_str());
  for (const auto& r : results) {
    const auto& s = r.summary;
    const double increments = static_cast<double>(s.stats.increments);
    const double newton = static_cast<double>(s.stats.iterations) / std::max(1.0, increments);
    std::printf("%s\n",
                t.row({r.name, t.number(1, s.peak_ratio, 5), t.number(2, s.slip_at_peak),
                       t.number(3, s.bottom_ratio, 5), t.number(4, s.steady_ratio_analytical, 5),
                       t.number(5, increments, 7), t.number(6, newton, 3),
                       t.number(7, static_cast<double>(s.stats.cutbacks), 7),
                       t.number(8, s.stats.wall_seconds, 3)})
                    .c_str());
    print_failure(r.failure);
  }
  print_wrapped(kContactLegend, " ");
}

// The counters of the run summary that every case has, whatever its driver.
template <class CaseResult>
void add_case_counters(cli::RunTotals& t, const CaseResult& r) {
  const auto& st = r.summary.stats;
  ++t.cases;
  t.failed += r.failure.empty() ? 0 : 1;
  t.increments += st.increments;
  t.cutbacks += st.cutbacks;
  t.rejected += st.rejected;
  t.compute_seconds += st.wall_seconds;
}

cli::RunTotals contact_totals(const std::vector<driver::ContactCaseResult>& results) {
  cli::RunTotals t;
  for (const auto& r : results) {
    add_case_counters(t, r);
    t.solves += r.summary.stats.increments;
    t.newton_iterations += r.summary.stats.iterations;
  }
  return t;
}

// A contact scene over the ranks of `team` (a serial run is a team of one): every rank parses
// the scene and computes its share of the cases; the root checks and writes the file, prints.
int run_contact(const RunArgs& a, const io::YamlDocument& document, const io::RestartInfo* restart,
                const parallel::Team& team) {
  // Every input and output check comes before the first step is computed.
  const auto session = std::chrono::steady_clock::now();
  const io::ContactScene scene = io::parse_contact_scene(document);
  std::optional<io::RunOutput> output;  // the root's
  const bool speaks = team.is_root() && !a.quiet;
  parallel::on_root(
      team,
      [&] {
        output.emplace(open_output(a, document, names_of(scene.cases), restart,
                                   input_files(a, scene.makeup), io::estimate_contact_run(scene)));
        print_warnings(a, io::contact_scene_warnings(scene));
      },
      exit_code_of);
  if (speaks) {
    print_scene_intro(a, scene.file, scene.cases.size(), scene.title);
    std::fflush(stdout);
  }
  std::vector<double> work;
  for (const auto& c : scene.cases)
    work.push_back(static_cast<double>(io::output_count(c.segments)));
  cli::ProgressReporter progress(team.is_root() ? progress_mode(a) : cli::ProgressMode::none,
                                 stderr, work);
  driver::ContactRunOptions options;
  options.threads = a.threads;
  options.on_case_done = [&](std::size_t k, const io::ContactCase& c,
                             const driver::ContactCaseResult&) { progress.update(k, c.name, 1.0); };
  std::vector<driver::ContactCaseResult> results;
  if (!team.is_root()) {
    parallel::on_root(team, [] {});
    results = driver::run_contact_scene_on_team(scene, team, nullptr, options);
  } else {
    results = output->write([&] {
      std::optional<io::ContactResultSink> sink;
      parallel::on_root(team, [&] {
        io::ContactSinkOptions to_file;
        to_file.flush_interval = std::chrono::duration<double>(a.flush_interval);
        to_file.restart = output->restart();
        sink.emplace(scene, output->file, to_file);
        if (!output->restart()) output->header_written();
      });
      return driver::run_contact_scene_on_team(scene, team, &*sink, options);
    });
  }
  progress.clear();
  if (speaks) {
    print_contact_table(scene, results);
    const double wall =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - session).count();
    std::printf("%s\n", cli::summary_text(contact_totals(results), wall, output->path).c_str());
  }
  for (const auto& r : results) {
    if (!r.failure.empty()) throw history::StepFailure(r.failure);
  }
  return 0;
}

// ---- crystal scenes

std::string component_label(std::pair<int, int> ij) {
  return std::to_string(ij.first + 1) + std::to_string(ij.second + 1);
}

// Compact headers (explained by crystal_legend) so that the table fits 80 columns; strain and
// stress along the loading component.
text::Table crystal_table(const io::CrystalScene& scene) {
  const std::string ij = component_label(driver::loading_component(scene.cases.front().segments));
  const std::string stress_unit = "[" + scene.units.stress + "]";
  text::Table t({{"case", 0, true},
                 {"strain_" + ij, 9},
                 {"stress" + stress_unit, 10},
                 {"mises" + stress_unit, 10},
                 {"gsteps/s", 8},
                 {"newton", 6},
                 {"cuts", 5},
                 {"wall[s]", 7}});
  t.fit_column(0, longest_name(scene.cases));
  return t;
}

// `restarted`: the run continued work of an earlier session, which the case rows count too.
std::string crystal_legend(const io::CrystalScene& scene, bool restarted) {
  const std::string ij = component_label(driver::loading_component(scene.cases.front().segments));
  return "(final values, strain and stress along " + ij +
         "; mises: von Mises; gsteps/s: grain-steps per second; newton: iterations per grain "
         "solve; cuts: cutbacks" +
         (restarted ? "; rows count every session of the run, the summary this one" : "") + ")";
}

void print_crystal_row(const text::Table& t, const driver::CrystalCaseResult& r) {
  const auto& s = r.summary;
  const auto [i, j] = s.axis;
  std::printf(
      "%s\n",
      t.row({r.name, t.number(1, s.final_state.strain(i, j)),
             t.number(2, s.final_state.stress(i, j)), t.number(3, s.final_von_mises_stress),
             t.number(4, s.grain_steps_per_second, 3), t.number(5, s.newton_per_grain_solve, 3),
             t.number(6, static_cast<double>(s.stats.cutbacks), 7),
             t.number(7, s.stats.wall_seconds, 3)})
          .c_str());
  print_failure(r.failure);
  std::fflush(stdout);
}

// `output`: how the ranks' results reach the file, when there are several ranks.
void print_crystal_intro(const RunArgs& a, const io::CrystalScene& scene, int ranks,
                         const char* output) {
  const io::CrystalCase& first = scene.cases.front();
  print_scene_intro(a, scene.file, scene.cases.size(), scene.title);
  const std::string over_ranks =
      ranks > 1 ? " in each of " + std::to_string(ranks) + " MPI ranks" : "";
  std::printf("  %zu grain%s, %zu slip systems, %d thread%s%s\n", first.grain_count(),
              first.grain_count() == 1 ? "" : "s", crystal::described_systems(first.phase).size(),
              omp_get_max_threads(), omp_get_max_threads() == 1 ? "" : "s", over_ranks.c_str());
  if (ranks > 1) std::printf("  output: %s\n", output);
  std::fflush(stdout);
}

cli::RunTotals crystal_totals(const std::vector<driver::CrystalCaseResult>& results) {
  cli::RunTotals t;
  for (const auto& r : results) {
    add_case_counters(t, r);
    t.grain_steps += r.summary.stats.grain_steps;
    t.solves += r.summary.stats.grain_solves;
    t.newton_iterations += r.summary.stats.newton_iterations;
  }
  return t;
}

// "12.2", "0.001": a time as printf's %g with six digits writes it.
std::string shortest_number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

// The counters of the work an earlier session did (a restart), and its line: where an
// interrupted case continues, or that it starts again and why.
void add_earlier_work(cli::RunTotals& before, const driver::EarlierWork& w) {
  if (w.kind == driver::EarlierWork::Kind::ended) ++before.cases;
  before.increments += w.stats.increments;
  before.grain_steps += w.stats.grain_steps;
  before.solves += w.stats.grain_solves;
  before.newton_iterations += w.stats.newton_iterations;
  before.cutbacks += w.stats.cutbacks;
  before.rejected += w.stats.rejected;
  before.compute_seconds += w.stats.wall_seconds;
}

std::string earlier_work_line(const io::CrystalCase& c, const driver::EarlierWork& w,
                              const std::string& time_unit) {
  const std::string name = "case '" + c.name + "': ";
  switch (w.kind) {
    case driver::EarlierWork::Kind::checkpoint:
      return name + "continues from its checkpoint after increment " +
             std::to_string(w.position.increment) + " of loading[" +
             std::to_string(w.position.segment) + "] (time " + shortest_number(w.time) + " " +
             (time_unit.empty() ? "s" : time_unit) + ")";
    case driver::EarlierWork::Kind::from_start:
      return name + "runs again from its start: " + w.why;
    case driver::EarlierWork::Kind::ended:
      break;
  }
  return "";
}

// The work of a crystal case for the progress bar: grains x increments.
std::vector<double> crystal_work(const io::CrystalScene& scene) {
  std::vector<double> work;
  for (const auto& c : scene.cases) {
    double increments = 0.0;
    for (const auto& s : c.segments) increments += s.increments;
    work.push_back(increments * static_cast<double>(c.grain_count()));
  }
  return work;
}

// The scene file (none for a scene given as text), its base scenes and the orientation files
// it reads.
std::vector<fs::path> input_files(const RunArgs& a, const io::CrystalScene& scene) {
  std::vector<fs::path> files = input_files(a, scene.makeup);
  for (const auto& c : scene.cases)
    if (c.orientation_source.kind == "file") files.emplace_back(c.orientation_source.description);
  return files;
}

// SIGTERM (a batch scheduler's time limit: Slurm sends it to every task), SIGINT (Ctrl-C) and
// SIGUSR1 (which Open MPI's mpirun passes on to every rank, where it would end a job on SIGTERM)
// stop a crystal run after the increment in progress, with a checkpoint there, so that
// --restart continues from it. A second signal ends the process at once.
volatile std::sig_atomic_t g_stop_signal = 0;

extern "C" void request_stop(int signal) {
  if (g_stop_signal != 0) {
    ::signal(signal, SIG_DFL);
    ::raise(signal);
    return;
  }
  g_stop_signal = signal;
}

// The handlers for the lifetime of a crystal run (the default disposition before and after).
class StopSignals {
 public:
  StopSignals() {
    struct sigaction act {};
    act.sa_handler = request_stop;
    sigemptyset(&act.sa_mask);
    for (std::size_t k = 0; k < kSignals.size(); ++k) ::sigaction(kSignals[k], &act, &old_[k]);
  }
  ~StopSignals() {
    for (std::size_t k = 0; k < kSignals.size(); ++k) ::sigaction(kSignals[k], &old_[k], nullptr);
  }
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;
  static bool received() { return g_stop_signal != 0; }
  // The signal received here (SIGTERM for a rank that stopped because another did).
  static int signal() { return g_stop_signal != 0 ? static_cast<int>(g_stop_signal) : SIGTERM; }

 private:
  static constexpr std::array<int, 3> kSignals{SIGTERM, SIGINT, SIGUSR1};
  std::array<struct sigaction, 3> old_{};
};

std::string signal_name(int signal) {
  switch (signal) {
    case SIGTERM:
      return "SIGTERM";
    case SIGINT:
      return "SIGINT";
    case SIGUSR1:
      return "SIGUSR1";
    default:
      return "signal " + std::to_string(signal);
  }
}

// A crystal run over the ranks of `team` (MPI; a serial run is a team of one): every rank
// parses the scene and computes its block of each case's grains; the root alone checks and
// writes the result file (the ranks' blocks reach it through a driver::TeamCrystalSink) and
// prints.
int run_crystal(const RunArgs& a, const io::YamlDocument& document, const io::RestartInfo* restart,
                const parallel::Team& team) {
  // Every input and output check comes before the first step is computed.
  const auto session = std::chrono::steady_clock::now();
  // From here a stop signal waits for the end of an increment, also one that comes while the
  // file is laid out. Every rank has its handlers before the root creates the file (the
  // reduction waits for all): a signal that finds the file can stop no rank the hard way.
  std::optional<StopSignals> signals;
  if (a.stop_on_signals) signals.emplace();
  if (team.size() > 1) {
    std::array<double, 1> handlers_ready{0.0};
    team.max(handlers_ready);
  }
  // Ranks that will write the file together keep only their blocks of the orientations.
  driver::OrientationSharing sharing;
  if (team.size() > 1 && io::h5::parallel_hdf5() && !a.gather_output)
    sharing = {&team, exit_code_of};
  io::CrystalScene scene = io::describe_crystal_scene(document);
  driver::read_orientations(scene, sharing);
  const std::optional<long> checkpoint_every =
      a.checkpoint_every >= 0 ? std::optional<long>(a.checkpoint_every) : std::nullopt;
  bool checkpoints = true, any_checkpoints = false;
  for (const auto& c : scene.cases) {
    const bool on = driver::checkpoint_policy(c, checkpoint_every).enabled();
    checkpoints = checkpoints && on;
    any_checkpoints = any_checkpoints || on;
  }
  std::optional<io::RunOutput> output;  // the root's
  parallel::on_root(
      team,
      [&] {
        output.emplace(
            open_output(a, document, names_of(scene.cases), restart, input_files(a, scene),
                        io::estimate_crystal_run(scene, checkpoint_every), any_checkpoints));
        print_warnings(a, io::crystal_scene_warnings(scene, checkpoints));
      },
      exit_code_of);
  // Crystal cases run one after the other; the threads go to the grains of a case.
  if (a.threads > 0) omp_set_num_threads(a.threads);
  const bool speaks = team.is_root() && !a.quiet;
  const text::Table table = crystal_table(scene);
  // The ranks share each case's grains and write them into the file together (parallel HDF5).
  const bool collective =
      driver::shares_grains(scene, team) && io::h5::parallel_hdf5() && !a.gather_output;
  if (speaks) {
    print_crystal_intro(a, scene, team.size(),
                        collective ? "every rank writes its grains (parallel HDF5, MPI-IO)"
                        : driver::shares_grains(scene, team)
                            ? "rank 0 writes the grains gathered from every rank"
                            : "rank 0 writes the cases of every rank");
    std::printf("%s\n", table.header().c_str());
  }
  cli::ProgressReporter progress(team.is_root() ? progress_mode(a) : cli::ProgressMode::none,
                                 stderr, crystal_work(scene));
  driver::CrystalRunOptions options;
  options.checkpoint_every = checkpoint_every;
  options.stop_requested = [] { return StopSignals::received(); };
  options.on_case_done = [&](std::size_t, const io::CrystalCase&,
                             const driver::CrystalCaseResult& r) {
    progress.clear();
    if (speaks) print_crystal_row(table, r);
  };
  options.on_progress = [&](std::size_t k, double fraction, bool resumed) {
    if (resumed) progress.set_done_before(k, fraction);
    progress.update(k, scene.cases[k].name, fraction);
  };
  cli::RunTotals before;  // what earlier sessions computed (a restart)
  options.on_earlier_work = [&](std::size_t k, const driver::EarlierWork& w) {
    add_earlier_work(before, w);
    const std::string line = earlier_work_line(scene.cases[k], w, scene.units.time);
    if (!speaks || line.empty()) return;
    progress.clear();
    print_wrapped(line);
  };
  const auto run = [&](driver::CrystalSink* root_sink) {
    return driver::run_crystal_scene_on_team(scene, team, root_sink, options);
  };
  // The sink of the result file `path`: a new one, or one that continues (`restart`).
  const auto sink_options = [&](const fs::path& path, bool restart) {
    io::CrystalSinkOptions to_file;
    to_file.flush_interval = std::chrono::duration<double>(a.flush_interval);
    to_file.restart = restart;
    to_file.restart_file = io::restart_file_for(path);
    to_file.checkpoint_capacity = driver::checkpoint_capacity(scene, checkpoint_every);
    to_file.computed_with = {{"simd_kernels", crystal::detail::flow_batch_isa_name()}};
    return to_file;
  };
  const auto run_collectively = [&] {
    // The root lays the file out (a restart: reopens it and its restart file) alone, as a
    // serial run does, and closes it; then every rank opens it for its writes.
    std::string path;
    parallel::on_root(
        team,
        [&] {
          io::CrystalResultSink layout(scene, output->file,
                                       sink_options(output->path, output->restart()));
          if (!output->restart()) output->header_written();
          layout.end_run();
          output->file.close();
          path = output->path.string();
        },
        exit_code_of);
    team.broadcast(path, 0);
    io::CrystalSinkOptions to_file = sink_options(path, true);  // (continues the layout)
    to_file.mpi = io::h5::MpiAccess{team.mpi_communicator(), team.rank()};
    to_file.ranks = team.size();
    std::optional<driver::SinkWriteError> failure;
    std::vector<driver::CrystalCaseResult> results;
    {
      // (the sink's objects are closed before the file: MPI-IO files close only without)
      io::h5::File file = io::h5::File::open_write(path, &*to_file.mpi);
      std::optional<io::CrystalResultSink> sink(std::in_place, scene, file, to_file);
      try {
        results = driver::run_crystal_scene_on_team(scene, team, &*sink, options, true);
        sink.reset();
        file.close();
      } catch (const driver::SinkWriteError& e) {  // (every rank: CollectiveCrystalSink)
        sink.reset();
        file.close_quietly();
        failure = e;
      }
    }
    io::RunOutput::finish_collective_run(team.is_root() ? &*output : nullptr, team, failure,
                                         exit_code_of);
    return results;
  };
  // The root runs into its file (RunOutput::write finishes it), the other ranks into nothing.
  const auto run_on_ranks = [&] {
    if (collective) return run_collectively();
    if (!team.is_root()) {
      parallel::on_root(team, [] {});
      return run(nullptr);
    }
    return output->write([&] {
      std::optional<io::CrystalResultSink> sink;
      parallel::on_root(team, [&] {
        sink.emplace(scene, output->file, sink_options(output->path, output->restart()));
        if (!output->restart()) output->header_written();
      });
      return run(&*sink);
    });
  };
  std::vector<driver::CrystalCaseResult> results;
  try {
    results = run_on_ranks();
  } catch (const driver::RunStopped& e) {
    progress.clear();
    const std::string file = team.is_root() ? output->path.string() : "FILE";
    throw StoppedBySignal("stopped by " + signal_name(StopSignals::signal()) + ": " + e.what() +
                              "; continue with: subslip run --restart " + file,
                          StopSignals::signal());
  }
  progress.clear();
  if (speaks) {
    print_wrapped(crystal_legend(scene, before.cases > 0 || before.increments > 0), " ");
    const double wall =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - session).count();
    std::printf("%s\n",
                cli::summary_text(crystal_totals(results), before, wall, output->path).c_str());
  }
  for (const auto& r : results) {
    if (!r.failure.empty()) throw crystal::CrystalStepFailure(r.failure);
  }
  return 0;
}

// The bases and settings of the root's restart file, on every rank (each composes the scene).
void broadcast(const parallel::Team& team, model::SceneMakeup& makeup) {
  const auto share_count = [&](std::size_t& n) {
    std::string text = std::to_string(n);
    team.broadcast(text, 0);
    n = std::stoul(text);
  };
  std::size_t bases = makeup.bases.size();
  share_count(bases);
  makeup.bases.resize(bases);
  for (auto& [file, text] : makeup.bases) {
    team.broadcast(file, 0);
    team.broadcast(text, 0);
  }
  std::size_t settings = makeup.settings.size();
  share_count(settings);
  makeup.settings.resize(settings);
  for (std::string& setting : makeup.settings) team.broadcast(setting, 0);
}

// A restart continues the run as it was set: settings given again must be the same.
void check_restart_settings(const RunArgs& a, const io::RestartInfo& restart) {
  if (a.settings.empty() || a.settings == restart.makeup.settings) return;
  std::string stored;
  for (const auto& s : restart.makeup.settings) stored += (stored.empty() ? "" : ", ") + s;
  throw InputError(a.restart, 0, "--set",
                   "a restart continues the run with the settings it started with (" +
                       (stored.empty() ? std::string("none") : stored) + "); drop --set");
}

// The scene the interrupted run read, from what its file stores (/scene, its bases, settings):
// the base files on the disk are not read again.
io::YamlDocument stored_scene(const io::RestartInfo& restart) {
  io::SceneSources sources{{restart.scene_file, restart.scene_text}, {}, restart.makeup.settings};
  for (const auto& [file, text] : restart.makeup.bases) sources.bases.push_back({file, text});
  return io::YamlDocument::compose(sources);
}

}  // namespace

// The dispatch on `scene:`. A new scene kind adds its name to the list and a branch here.
// With --restart the scene is the one stored in the file (/scene, with its bases and settings);
// a scene file named as well must have the same text.
// Run over MPI ranks, every rank runs this: the scene file is read by each; a restart file is
// inspected by the root, which shares the scene it holds.
int run_scene(const RunArgs& a, const parallel::Team& team) {
  io::h5::print_error_stacks(a.verbose);
  std::optional<io::YamlDocument> given;
  if (!a.scene_text.empty())
    given.emplace(io::YamlDocument::from_string(a.scene_text, a.scene));
  else if (!a.scene.empty())
    given.emplace(io::YamlDocument::from_file(a.scene));
  std::optional<io::RestartInfo> restart;
  if (!a.restart.empty()) {
    if (!a.output.empty() || a.force)
      throw InputError(a.restart, 0, "--restart", "continues FILE in place: drop -o and --force");
    parallel::on_root(
        team,
        [&] {
          restart = io::inspect_for_restart(
              a.restart, given ? std::optional<std::string>(given->text()) : std::nullopt);
        },
        exit_code_of);
    if (!restart) restart.emplace();
    if (team.is_root()) {
      const std::string rounding = io::restart_rounding_warning(
          a.restart, *restart, SUBSLIP_BUILD, crystal::detail::flow_batch_isa_name());
      if (!rounding.empty()) print_warnings(a, {rounding});
    }
    for (std::string* text : {&restart->scene_kind, &restart->scene_file, &restart->scene_text})
      team.broadcast(*text, 0);
    broadcast(team, restart->makeup);
    check_restart_settings(a, *restart);
  } else if (!given) {
    throw InputError("run", 0, "", "give a scene file (or --restart FILE)");
  }
  const io::YamlDocument document =
      restart ? stored_scene(*restart) : io::compose_scene(*given, a.settings);
  const io::RestartInfo* info = restart ? &*restart : nullptr;
  const std::string kind = io::scene_kind(document, {"contact", "crystal"});
  if (restart && kind != restart->scene_kind)
    throw InputError(a.restart, 0, "scene_kind",
                     "cannot restart: /scene is not a " + kind + " scene");
  if (kind == "contact") return run_contact(a, document, info, team);
  if (kind == "crystal") return run_crystal(a, document, info, team);
  throw InputError(document.file(), 0, "scene", "no runner for scene kind '" + kind + "'");
}

}  // namespace subslip::cli
