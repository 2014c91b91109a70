// Checkpoints and `subslip run --restart`: the aggregate continued from a checkpoint gives the
// uninterrupted run bit for bit; the checkpoint store survives a kill while it writes; a real
// run killed part-way (SIGKILL) and restarted (even twice) writes a file whose every dataset
// equals the uninterrupted run's; and --restart refuses what it cannot continue, with a clear
// message and exit code 2.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "child_process.hpp"
#include "grain_recorder.hpp"
#include "scene_text.hpp"
#include "scratch_dir.hpp"
#include "subslip/crystal/flow_point_batch.hpp"
#include "subslip/crystal/phase_builder.hpp"
#include "subslip/io/checkpoint.hpp"
#include "subslip/io/crystal_output.hpp"
#include "subslip/io/crystal_scene.hpp"
#include "subslip/io/h5_writer.hpp"
#include "subslip/io/restart.hpp"
#include "subslip/io/result_file.hpp"
#include "subslip/io/result_protocol.hpp"

namespace fs = std::filesystem;
using namespace subslip;
using namespace subslip::io;
using subslip::testing::read_text;
using subslip::testing::run_subslip;

namespace {

fs::path scratch_dir() {
  return subslip::testing::scratch_dir("restart");
}

// Copper-like FCC: tension along z under mixed control with a lateral stress ramped to 5 MPa,
// then shear with graded increments while that stress is ramped back to 0: segments, free
// components of L and both stress ramps cross the checkpoints.
std::string crystal_scene(int grains, int increments, const std::string& extra = "") {
  return R"(scene: crystal
title: "restart test"
units: {stress: MPa, time: s}
phase:
  families: [fcc_111_110]
  elasticity: {type: cubic, C11: 168400, C12: 121400, C44: 75400}
  tau0: 10.0
  law:
    friction: {mu_s: 1.6, mu_k: 14.8, kappa: 20.0, xi: 0.01}
    subloading: {function: cot, u_tilde: 200}
    overstress: {form: exponential, eta_v: 1.0e-3, n: 16, r_hat: 1.6}
orientations:
  random: {count: )" +
         std::to_string(grains) + R"(, seed: 5}
loading:
  - L: [[x, 0, 0], [0, x, 0], [0, 0, 1.0e-3]]
    stress: [[5, x, x], [x, 0, x], [x, x, x]]
    duration: 10
    increments: )" +
         std::to_string(increments) + R"(
    output_every: 3
  - L: [[x, 1.0e-3, 0], [0, x, 0], [0, 0, 0]]
    stress: [[0, x, x], [x, 0, x], [x, x, x]]
    duration: 5
    increments: )" +
         std::to_string(increments / 2) + R"(
    growth: 1.05
)" + extra;
}

CrystalScene scene_of(const std::string& text) {
  return parse_crystal_scene(YamlDocument::from_string(text, "restart_test.yaml"));
}

struct Stop {};  // thrown out of the run to interrupt it

bool same_bits(double a, double b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

void expect_same_snapshot(const subslip::testing::GrainSnapshot& a,
                          const subslip::testing::GrainSnapshot& b) {
  EXPECT_TRUE(same_bits(a.macro.time, b.macro.time));
  EXPECT_EQ(a.macro.segment, b.macro.segment);
  for (int i = 0; i < 9; ++i) {
    EXPECT_TRUE(same_bits(a.macro.stress.data()[i], b.macro.stress.data()[i]));
    EXPECT_TRUE(
        same_bits(a.macro.deformation_gradient.data()[i], b.macro.deformation_gradient.data()[i]));
    EXPECT_TRUE(
        same_bits(a.macro.velocity_gradient.data()[i], b.macro.velocity_gradient.data()[i]));
  }
  auto same = [](const std::vector<double>& x, const std::vector<double>& y) {
    if (x.size() != y.size()) return false;
    for (std::size_t i = 0; i < x.size(); ++i)
      if (!same_bits(x[i], y[i])) return false;
    return true;
  };
  EXPECT_TRUE(same(a.stress, b.stress));
  EXPECT_TRUE(same(a.orientation, b.orientation));
  EXPECT_TRUE(same(a.slip, b.slip));
  EXPECT_TRUE(same(a.rate, b.rate));
  EXPECT_TRUE(same(a.crss, b.crss));
  EXPECT_TRUE(same(a.r_s, b.r_s));
}

// Runs the case uninterrupted, then again interrupted after increment `stop_after` (counting
// over all segments), and continues a fresh aggregate from the checkpoint taken there.
void check_resume_is_bitwise(const CrystalCase& c, long stop_after) {
  subslip::testing::GrainRecorder whole;
  const auto a = crystal::build_taylor_aggregate(c.phase, c.orientations);
  const auto full = a->run(c.segments, c.options, whole.observer());

  subslip::testing::GrainRecorder first, second;
  const auto b = crystal::build_taylor_aggregate(c.phase, c.orientations);
  crystal::AggregateCheckpoint saved;
  long done = 0;
  crystal::RunControl stop;
  stop.after_increment = [&](const crystal::RunPosition&, const crystal::MacroState&) {
    if (++done < stop_after) return;
    saved = b->checkpoint();
    throw Stop{};
  };
  EXPECT_THROW(b->run(c.segments, c.options, first.observer(), stop), Stop);
  ASSERT_EQ(saved.stats.increments, stop_after);

  const auto resumed_aggregate = crystal::build_taylor_aggregate(c.phase, c.orientations);
  crystal::RunControl resume;
  resume.resume = &saved;
  const auto stats = resumed_aggregate->run(c.segments, c.options, second.observer(), resume);

  // The outputs before the stop plus those after the restart are the uninterrupted run's.
  ASSERT_EQ(first.snaps.size() + second.snaps.size(), whole.snaps.size());
  for (std::size_t i = 0; i < whole.snaps.size(); ++i) {
    SCOPED_TRACE("output " + std::to_string(i));
    const auto& got =
        i < first.snaps.size() ? first.snaps[i] : second.snaps[i - first.snaps.size()];
    expect_same_snapshot(whole.snaps[i], got);
  }
  EXPECT_EQ(stats.increments, full.increments);
  EXPECT_EQ(stats.substeps, full.substeps);
  EXPECT_EQ(stats.grain_solves, full.grain_solves);
  EXPECT_EQ(stats.newton_iterations, full.newton_iterations);
  EXPECT_EQ(stats.cutbacks, full.cutbacks);
  EXPECT_EQ(stats.rejected, full.rejected);
  EXPECT_EQ(stats.mixed_iterations, full.mixed_iterations);
}

}  // namespace

TEST(Restart, AggregateContinuesBitwiseFromACheckpoint) {
  // (The trend predictor: its trend is part of the checkpoint.)
  const CrystalScene scene =
      scene_of(crystal_scene(6, 20, "integrator: {method: implicit, predictor: trend}\n"));
  const CrystalCase& c = scene.cases.at(0);
  ASSERT_EQ(c.options.predictor, crystal::MixedPredictor::trend);
  // Inside the first segment between outputs, at its end, and inside the graded second one.
  for (long stop : {7L, 20L, 26L}) {
    SCOPED_TRACE("stopped after increment " + std::to_string(stop));
    check_resume_is_bitwise(c, stop);
  }
}

// A segment by dot_F with a first Piola-Kirchhoff target, then one by L with Cauchy targets: the
// free dot_F, its path and the P ramp's start continue from the checkpoint as L's do.
TEST(Restart, DotFAndFirstPiolaRunContinuesBitwiseFromACheckpoint) {
  std::string text = crystal_scene(4, 20, "integrator: {method: implicit, predictor: trend}\n");
  const std::string l_first =
      "  - L: [[x, 0, 0], [0, x, 0], [0, 0, 1.0e-3]]\n"
      "    stress: [[5, x, x], [x, 0, x], [x, x, x]]\n";
  ASSERT_NE(text.find(l_first), std::string::npos);
  text.replace(text.find(l_first), l_first.size(),
               "  - dot_F: [[x, 0, 0], [0, x, 0], [0, 0, 1.0e-3]]\n"
               "    P: [[5, x, x], [x, 0, x], [x, x, x]]\n");
  const CrystalScene scene = scene_of(text);
  const CrystalCase& c = scene.cases.at(0);
  ASSERT_EQ(c.segments.at(0).rate_control, crystal::RateControl::deformation_rate);
  ASSERT_EQ(c.segments.at(0).stress_measure, crystal::StressMeasure::first_piola);
  for (long stop : {7L, 20L, 26L}) {
    SCOPED_TRACE("stopped after increment " + std::to_string(stop));
    check_resume_is_bitwise(c, stop);
  }
}

TEST(Restart, AdaptiveRunContinuesBitwiseFromACheckpoint) {
  // Backward Euler's estimate (order 1) and the extrapolated integrator (order 3).
  for (int order : {1, 3}) {
    SCOPED_TRACE("order " + std::to_string(order));
    const CrystalScene scene =
        scene_of(crystal_scene(4, 10,
                               "integrator: {method: implicit, predictor: trend, tolerance: "
                               "1.0e-3, order: " +
                                   std::to_string(order) + "}\n"));
    const CrystalCase& c = scene.cases.at(0);
    ASSERT_GT(c.options.tolerance, 0.0);
    ASSERT_EQ(c.options.order, order);
    // The step size the next increment tries is part of the state.
    for (long stop : {3L, 9L}) {
      SCOPED_TRACE("stopped after increment " + std::to_string(stop));
      check_resume_is_bitwise(c, stop);
    }
  }
}

// Output at chosen times: the split fixed increments and the adaptive steps shortened to the
// points resume bit for bit, between points and right after one.
TEST(Restart, RunWithOutputPointsContinuesBitwiseFromACheckpoint) {
  for (const std::string& integrator :
       std::vector<std::string>{"integrator: {method: implicit, predictor: trend}\n",
                                "integrator: {method: implicit, tolerance: 1.0e-3}\n"}) {
    SCOPED_TRACE(integrator.find("tolerance") == std::string::npos ? "fixed" : "adaptive");
    std::string text = crystal_scene(2, 10, integrator + "output: {at: {time: {every: 0.7}}}\n");
    text.erase(text.find("    output_every: 3\n"), 19);  // output.at chooses the rows
    const CrystalScene scene = scene_of(text);
    const CrystalCase& c = scene.cases.at(0);
    ASSERT_TRUE(c.segments[0].output_at_times);
    for (long stop : {3L, 14L}) {
      SCOPED_TRACE("stopped after increment " + std::to_string(stop));
      check_resume_is_bitwise(c, stop);
    }
  }
}

TEST(Restart, RestoreRefusesAnotherAggregate) {
  const CrystalScene scene = scene_of(crystal_scene(3, 4));
  const CrystalCase& c = scene.cases.at(0);
  const auto a = crystal::build_taylor_aggregate(c.phase, c.orientations);
  a->run(c.segments, c.options, [](const crystal::MacroState&, const crystal::GrainFields&) {});
  crystal::AggregateCheckpoint saved = a->checkpoint();
  EXPECT_EQ(saved.values_per_grain, 15 + 6 * 12);
  EXPECT_EQ(saved.grains.size(), 3u * static_cast<std::size_t>(saved.values_per_grain));
  const CrystalScene other = scene_of(crystal_scene(4, 4));
  const auto b = crystal::build_taylor_aggregate(other.cases[0].phase, other.cases[0].orientations);
  EXPECT_THROW(b->restore(saved), std::invalid_argument);
}

// ---- the checkpoint store

namespace {

// A checkpoint whose every number is derived from `k`, so that a torn one is recognisable.
crystal::AggregateCheckpoint numbered_checkpoint(long k, std::size_t grains, int per_grain) {
  crystal::AggregateCheckpoint c;
  const double x = static_cast<double>(k);
  c.position = {static_cast<int>(k % 3), k, 0.5 * x, 0.25 * x};
  c.macro.time = x;
  c.macro.segment = static_cast<int>(k % 3);
  c.macro.velocity_gradient.setConstant(x + 0.1);
  c.macro.deformation_gradient.setConstant(x + 0.2);
  c.macro.strain.setConstant(x + 0.3);
  c.macro.stress.setConstant(x + 0.4);
  c.segment_start_stress.setConstant(x + 0.5);
  c.free_velocity_gradient = Eigen::VectorXd::Constant(2, x + 0.6);
  c.free_velocity_gradient_trend = Eigen::VectorXd::Constant(2, x + 0.8);
  c.free_velocity_gradient_path = Eigen::VectorXd::Constant(2, x + 0.9);
  c.free_strain_correction = Eigen::VectorXd::Constant(2, x + 1.1);
  c.stats.increments = k;
  c.stats.substeps = k + 1;
  c.stats.grain_steps = k + 2;
  c.stats.grain_solves = k + 3;
  c.stats.newton_iterations = k + 4;
  c.stats.cutbacks = k + 5;
  c.stats.rejected = k + 6;
  c.stats.mixed_iterations = k + 7;
  c.stats.wall_seconds = x + 0.7;
  c.values_per_grain = per_grain;
  c.grains.assign(grains * static_cast<std::size_t>(per_grain), x);
  return c;
}

void expect_numbered(const StoredCheckpoint& s, std::size_t grains, int per_grain) {
  const long k = s.state.stats.increments;
  const auto expected = numbered_checkpoint(k, grains, per_grain);
  const double x = static_cast<double>(k);
  EXPECT_EQ(s.state.position.increment, k);
  EXPECT_EQ(s.state.position.segment, static_cast<int>(k % 3));
  EXPECT_EQ(s.state.position.segment_time, 0.5 * x);
  EXPECT_EQ(s.state.position.next_step, 0.25 * x);
  EXPECT_EQ(s.state.macro.time, x);
  EXPECT_EQ(s.state.macro.stress, expected.macro.stress);
  EXPECT_EQ(s.state.macro.deformation_gradient, expected.macro.deformation_gradient);
  EXPECT_EQ(s.state.segment_start_stress, expected.segment_start_stress);
  EXPECT_EQ(s.state.free_velocity_gradient, expected.free_velocity_gradient);
  EXPECT_EQ(s.state.free_velocity_gradient_trend, expected.free_velocity_gradient_trend);
  EXPECT_EQ(s.state.free_velocity_gradient_path, expected.free_velocity_gradient_path);
  EXPECT_EQ(s.state.free_strain_correction, expected.free_strain_correction);
  EXPECT_EQ(s.state.stats.mixed_iterations, k + 7);
  EXPECT_EQ(s.state.stats.wall_seconds, x + 0.7);
  EXPECT_EQ(s.state.grains, expected.grains);
  EXPECT_EQ(s.rows, static_cast<std::size_t>(10 * k));
  EXPECT_EQ(s.last_output.time, x - 0.5);
}

}  // namespace

TEST(Checkpoint, StoreKeepsTheLatestCompleteSlot) {
  const fs::path dir = scratch_dir();
  h5::File file = h5::File::create(dir / "c.h5", false);
  const std::size_t capacity = 5 * 63 + 17;  // larger than the checkpoints: the rest is unused
  CheckpointStore::create(file.root(), capacity);
  CheckpointStore store(file.root());
  EXPECT_FALSE(store.latest(0));
  crystal::MacroState last;
  for (long k = 1; k <= 3; ++k) {
    last.time = static_cast<double>(k) - 0.5;
    store.write(0, numbered_checkpoint(k, 5, 63), static_cast<std::size_t>(10 * k), last);
    const auto latest = store.latest(0);
    ASSERT_TRUE(latest);
    EXPECT_EQ(latest->sequence, k);
    expect_numbered(*latest, 5, 63);
    EXPECT_FALSE(store.latest(1));  // another case's checkpoint is not this case's
  }
  // Slots alternate: 1 and 3 in a, 2 in b. A slot torn by a kill (sequence -1, data half
  // written) is ignored: the other one is the latest.
  const h5::Group a = file.root().open_group("checkpoint").open_group("a");
  const long long torn[1] = {-1};
  a.open_dataset("sequence").write(torn);
  a.open_dataset("grains").write(std::vector<double>(capacity, 123.0));
  const auto latest = store.latest(0);
  ASSERT_TRUE(latest);
  EXPECT_EQ(latest->sequence, 2);
  expect_numbered(*latest, 5, 63);
  // The next case (fewer grains, other slip count) writes over the older slot and reads back
  // its own shape; a store opened afresh (a restart) continues the numbering.
  last.time = 3.5;
  CheckpointStore(file.root()).write(1, numbered_checkpoint(4, 3, 19), 40, last);
  const auto next = CheckpointStore(file.root()).latest(1);
  ASSERT_TRUE(next);
  EXPECT_EQ(next->sequence, 3);
  expect_numbered(*next, 3, 19);
  EXPECT_FALSE(store.latest(0));
  fs::remove_all(dir);
}

// A child writes checkpoints in a loop and is killed at random moments: the latest complete
// checkpoint is always one whole checkpoint, never a mix of two.
TEST(Checkpoint, KillWhileWritingLeavesAWholeCheckpoint) {
  const fs::path dir = scratch_dir();
  const unsigned seed = subslip::testing::kill_seed();
  SCOPED_TRACE("SUBSLIP_KILL_SEED=" + std::to_string(seed));
  std::mt19937 rng(seed);
  const std::size_t grains = 2000;  // 1 MB a checkpoint: a write takes a while
  const int per_grain = 63;
  int checked = 0;
  for (int trial = 0; trial < 6; ++trial) {
    const fs::path path = dir / ("k" + std::to_string(trial) + ".h5");
    // The kill moments count from the store's layout (the child says when over a pipe): on a
    // loaded machine (sanitizers, parallel builds) 50 ms after the fork can come before it.
    int ready[2];
    ASSERT_EQ(::pipe(ready), 0);
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      ::close(ready[0]);
      // As a run writes it: the restart file next to its result.
      h5::File file = create_restart_file(path, "0123456789abcdef", grains * per_grain);
      if (::write(ready[1], "r", 1) != 1) ::_exit(1);
      CheckpointStore store(file.root());
      crystal::MacroState last;
      for (long k = 1;; ++k) {
        last.time = static_cast<double>(k) - 0.5;
        store.write(0, numbered_checkpoint(k, grains, per_grain), static_cast<std::size_t>(10 * k),
                    last);
      }
    }
    ::close(ready[1]);
    char byte = 0;
    ASSERT_EQ(::read(ready[0], &byte, 1), 1);  // the store is laid out and flushed
    ::close(ready[0]);
    std::uniform_real_distribution<double> when(0.05, 0.4);
    std::this_thread::sleep_for(std::chrono::duration<double>(when(rng)));
    ::kill(child, SIGKILL);
    int status = 0;
    ASSERT_EQ(::waitpid(child, &status, 0), child);
    const h5::File file = h5::File::open_read(path);
    const auto latest = CheckpointStore(file.root()).latest(0);
    if (!latest) continue;  // killed before the first checkpoint was complete
    ++checked;
    expect_numbered(*latest, grains, per_grain);
    EXPECT_EQ(latest->sequence, latest->state.stats.increments);
  }
  EXPECT_GT(checked, 0);
  fs::remove_all(dir);
}

// ---- the command

namespace {

std::string log_of(const fs::path& dir) {
  return read_text(dir / "run.log");
}

// A kill can land after the run marked its file completed (while it closes and prints its
// summary): then there is nothing to restart.
bool killed_unfinished(int code, const fs::path& file) {
  return code != 0 && h5::File::open_read(file).root().attribute_int("completed") == 0;
}

int restart(const fs::path& dir, const std::string& file, std::vector<std::string> more = {}) {
  std::vector<std::string> args{"run", "--restart", file, "-q"};
  args.insert(args.end(), more.begin(), more.end());
  return run_subslip(dir, args, dir / "run.log");
}

}  // namespace

// A real run killed part-way, restarted, killed again, restarted again: every
// dataset equals the uninterrupted run's, and the file says it completed.
TEST(Restart, KilledCrystalRunContinuesBitwise) {
  const fs::path dir = scratch_dir();
  std::ofstream(dir / "scene.yaml")
      << crystal_scene(16, 60,
                       "output:\n  grains: [stress, orientation, slip, r_s]\n"
                       "  checkpoint_every: 4\nsweep:\n  \"phase.tau0\": [10, 12]\n");
  subslip::testing::RunTiming ref;
  ASSERT_EQ(subslip::testing::run_subslip_timed(dir, {"run", "scene.yaml", "-o", "ref.h5", "-q"},
                                                dir / "run.log", dir / "ref.h5", ref),
            0)
      << log_of(dir);
  const unsigned seed = subslip::testing::kill_seed();
  SCOPED_TRACE("SUBSLIP_KILL_SEED=" + std::to_string(seed));
  std::mt19937 rng(seed);
  // Kills after the file is in place (its layout complete): before, there is nothing to
  // restart (H5Output.RunKilledAtARandomMomentKeepsEveryCountedRow covers those moments).
  const double computing = ref.total - ref.until_file;
  std::uniform_real_distribution<double> when(0.1 * computing, 0.8 * computing);
  const int first = subslip::testing::run_and_kill_after_file(
      dir, {"run", "scene.yaml", "-o", "out.h5", "-q"}, dir / "run.log", dir / "out.h5", when(rng));
  ASSERT_TRUE(first == 128 + SIGKILL || first == 0) << log_of(dir);
  if (killed_unfinished(first, dir / "out.h5")) {
    // The checkpoints are in the restart file next to the result, of the same run (unless the
    // kill came after every case had ended: no run needs them then, and the finish drops them
    // before the finished file replaces the working one).
    if (!every_case_ended(dir / "out.h5")) {
      std::string run_id;
      EXPECT_TRUE(is_restart_file(dir / "out.restart.h5", &run_id));
      EXPECT_EQ(run_id, h5::File::open_read(dir / "out.h5").root().attribute_string("run_id"));
    }
    // Kill the restarted run too (early in it), then let a second restart finish.
    const int second = subslip::testing::run_and_kill(dir, {"run", "--restart", "out.h5", "-q"},
                                                      dir / "run.log", 0.3 * when(rng));
    ASSERT_TRUE(second == 128 + SIGKILL || second == 0) << log_of(dir);
    if (killed_unfinished(second, dir / "out.h5")) {
      ASSERT_EQ(restart(dir, "out.h5"), 0) << log_of(dir);
    }
  }
  const h5::File out = h5::File::open_read(dir / "out.h5");
  EXPECT_EQ(out.root().attribute_int("completed"), 1);
  const h5::CaseProgress progress = h5::CaseProgress::open(out.root());
  for (std::size_t k = 0; k < progress.size(); ++k)
    EXPECT_EQ(progress.state(k), h5::CaseState::completed);
  // No checkpoint in the finished result, and its restart file is gone.
  EXPECT_FALSE(out.root().has("checkpoint"));
  EXPECT_FALSE(out.root().open_group("cases").open_group("tau0=10").has("checkpoint"));
  EXPECT_FALSE(fs::exists(dir / "out.restart.h5"));
  subslip::testing::expect_same_datasets(dir / "ref.h5", dir / "out.h5");
  fs::remove_all(dir);
}

// SIGTERM (a batch scheduler's time limit) stops a crystal run after the increment in progress,
// with a checkpoint there (the scene's own are too rare to come), and exit status 128 + 15; the
// restart continues from that checkpoint and ends as the uninterrupted run.
TEST(Restart, SigtermStopsWithACheckpointThatTheRestartContinues) {
  const fs::path dir = scratch_dir();
  std::ofstream(dir / "scene.yaml")
      << crystal_scene(16, 300,
                       "integrator: {method: implicit, predictor: trend}\n"
                       "output:\n  checkpoint_every: 100000\n");
  subslip::testing::RunTiming ref;
  ASSERT_EQ(subslip::testing::run_subslip_timed(dir, {"run", "scene.yaml", "-o", "ref.h5", "-q"},
                                                dir / "run.log", dir / "ref.h5", ref),
            0)
      << log_of(dir);
  const unsigned seed = subslip::testing::kill_seed();
  SCOPED_TRACE("SUBSLIP_KILL_SEED=" + std::to_string(seed));
  std::mt19937 rng(seed);
  const double computing = ref.total - ref.until_file;
  std::uniform_real_distribution<double> when(0.2 * computing, 0.7 * computing);
  const int code = subslip::testing::run_and_kill_after_file(
      dir, {"run", "scene.yaml", "-o", "out.h5", "-q"}, dir / "run.log", dir / "out.h5", when(rng),
      SIGTERM);
  ASSERT_TRUE(code == 128 + SIGTERM || code == 0) << log_of(dir);
  if (code == 128 + SIGTERM) {
    const std::string log = log_of(dir);
    EXPECT_NE(log.find("subslip: stopped by SIGTERM: case 'base' stopped after increment "),
              std::string::npos)
        << log;
    EXPECT_NE(log.find("continue with: subslip run --restart out.h5"), std::string::npos) << log;
    EXPECT_EQ(h5::File::open_read(dir / "out.h5").root().attribute_int("completed"), 0);
    crystal::RunPosition stopped_at;
    long increments_before = 0;
    {
      const h5::File restart_file = h5::File::open_read(dir / "out.restart.h5");
      const auto stop = CheckpointStore(restart_file.root()).latest(0);
      ASSERT_TRUE(stop.has_value());
      EXPECT_GT(stop->state.stats.increments, 0);
      stopped_at = stop->state.position;
      increments_before = stop->state.stats.increments;
    }
    // The restart says where the case continues, and its summary counts what it computed.
    ASSERT_EQ(run_subslip(dir, {"run", "--restart", "out.h5"}, dir / "run.log"), 0) << log_of(dir);
    const std::string resumed = log_of(dir);
    EXPECT_NE(resumed.find("case 'base': continues from its checkpoint after increment " +
                           std::to_string(stopped_at.increment) + " of loading[" +
                           std::to_string(stopped_at.segment) + "]"),
              std::string::npos)
        << resumed;
    EXPECT_NE(
        resumed.find(" with the " + std::to_string(increments_before) + " before the restart)"),
        std::string::npos)
        << resumed;
  } else {
    GTEST_LOG_(INFO) << "the run ended before the signal";
  }
  EXPECT_EQ(h5::File::open_read(dir / "out.h5").root().attribute_int("completed"), 1);
  subslip::testing::expect_same_datasets(dir / "ref.h5", dir / "out.h5");
  fs::remove_all(dir);
}

// A run stopped before its first flush can leave the grains' weights and initial orientations
// off the disk while the case's layout is there (a 2-rank run killed early and restarted
// serially had every one at the fill value). The restart writes them again: here a stopped
// run's are overwritten with the fill value before it is restarted, and the finished file
// equals the uninterrupted run's.
TEST(Restart, RestartWritesTheGrainsWeightsAndOrientationsAgain) {
  const fs::path dir = scratch_dir();
  std::ofstream(dir / "scene.yaml") << crystal_scene(16, 300,
                                                     "output:\n  grains: [stress, orientation]\n"
                                                     "  checkpoint_every: 100000\n");
  ASSERT_EQ(run_subslip(dir, {"run", "scene.yaml", "-o", "ref.h5", "-q"}, dir / "run.log"), 0)
      << log_of(dir);
  // Stopped at once (after the increment in progress), with a checkpoint there.
  const int code =
      subslip::testing::run_and_kill_after_file(dir, {"run", "scene.yaml", "-o", "out.h5", "-q"},
                                                dir / "run.log", dir / "out.h5", 0.0, SIGTERM);
  ASSERT_EQ(code, 128 + SIGTERM) << log_of(dir);
  {
    const h5::File out = h5::File::open_write(dir / "out.h5");
    const h5::Group grains = out.root().open_group("cases").open_group("base").open_group("grains");
    grains.open_dataset("weight").write_rows(0, std::vector<double>(16, 0.0));
    grains.open_dataset("initial_orientation").write_rows(0, std::vector<double>(64, 0.0));
  }
  ASSERT_EQ(restart(dir, "out.h5"), 0) << log_of(dir);
  subslip::testing::expect_same_datasets(dir / "ref.h5", dir / "out.h5");
  fs::remove_all(dir);
}

// Contact cases take milliseconds: an unfinished one is run again from its start.
TEST(Restart, KilledContactRunRerunsUnfinishedCases) {
  const fs::path dir = scratch_dir();
  std::ofstream(dir / "scene.yaml") << subslip::testing::contact_scene_start() + R"(loading:
  - slide: {speed: 1, direction: [1, 0], distance: 2.0}
    increments: 4000
    growth: 1.001
sweep:
  "loading[0].slide.speed": [1, 2, 5, 10, 20, 50, 100, 200]
  "law.overstress.n": [8, 16, 32]
)";
  subslip::testing::RunTiming ref;
  ASSERT_EQ(subslip::testing::run_subslip_timed(
                dir, {"run", "scene.yaml", "-o", "ref.h5", "-q", "-j", "1"}, dir / "run.log",
                dir / "ref.h5", ref),
            0)
      << log_of(dir);
  const unsigned seed = subslip::testing::kill_seed();
  SCOPED_TRACE("SUBSLIP_KILL_SEED=" + std::to_string(seed));
  std::mt19937 rng(seed);
  const double computing = ref.total - ref.until_file;
  std::uniform_real_distribution<double> when(0.2 * computing, 0.8 * computing);
  const int first = subslip::testing::run_and_kill_after_file(
      dir, {"run", "scene.yaml", "-o", "out.h5", "-q", "-j", "1"}, dir / "run.log", dir / "out.h5",
      when(rng));
  ASSERT_TRUE(first == 128 + SIGKILL || first == 0) << log_of(dir);
  if (killed_unfinished(first, dir / "out.h5")) {
    ASSERT_EQ(restart(dir, "out.h5", {"-j", "2"}), 0) << log_of(dir);
  }
  EXPECT_EQ(h5::File::open_read(dir / "out.h5").root().attribute_int("completed"), 1);
  subslip::testing::expect_same_datasets(dir / "ref.h5", dir / "out.h5");
  fs::remove_all(dir);
}

namespace {

// A crystal run that completed, turned back into an interrupted one (as a kill after its last
// checkpoint would leave it): completed = 0 and its case marked running.
void mark_interrupted(const fs::path& file) {
  h5::File f = h5::File::open_write(file);
  h5::mark_running(f);
  f.root().set_attribute("finished", 0);
  h5::CaseProgress progress = h5::CaseProgress::open(f.root());
  progress.set_state(0, h5::CaseState::running);
}

void expect_refused(const fs::path& dir, const std::vector<std::string>& args,
                    const std::string& message) {
  EXPECT_EQ(run_subslip(dir, args, dir / "run.log"), 2) << log_of(dir);
  const std::string log = log_of(dir);
  EXPECT_NE(log.find(message), std::string::npos) << log;
  EXPECT_NE(log.find("subslip: error: "), std::string::npos) << log;
}

}  // namespace

TEST(Restart, RefusesWhatItCannotContinue) {
  const fs::path dir = scratch_dir();
  const std::string scene = crystal_scene(2, 6, "output:\n  checkpoint_every: 2\n");
  std::ofstream(dir / "scene.yaml") << scene;
  ASSERT_EQ(run_subslip(dir, {"run", "scene.yaml", "-o", "done.h5", "-q"}, dir / "run.log"), 0);

  expect_refused(dir, {"run", "--restart", "done.h5"},
                 "done.h5: completed: cannot restart: the run completed");
  expect_refused(dir, {"run", "--restart", "missing.h5"},
                 "missing.h5: cannot restart: no such file");
  std::ofstream(dir / "text.h5") << "not hdf5\n";
  expect_refused(dir, {"run", "--restart", "text.h5"},
                 "text.h5: cannot restart: not a readable HDF5 file");
  {
    h5::File other = h5::File::create(dir / "other.h5", false);
    other.root().set_attribute("creator", "another program");
  }
  expect_refused(dir, {"run", "--restart", "other.h5"},
                 "other.h5: format: cannot restart: not a subslip result file");

  // An interrupted file: a changed scene file, another program version, -o or --force.
  fs::copy_file(dir / "done.h5", dir / "cut.h5");
  mark_interrupted(dir / "cut.h5");
  std::ofstream(dir / "changed.yaml") << scene << "# an edit\n";
  expect_refused(dir, {"run", "changed.yaml", "--restart", "cut.h5"},
                 "cut.h5: scene: cannot restart: the scene file given differs");
  expect_refused(dir, {"run", "--restart", "cut.h5", "-o", "x.h5"}, "drop -o and --force");
  fs::copy_file(dir / "cut.h5", dir / "old.h5");
  h5::File::open_write(dir / "old.h5").root().set_attribute("program_version", "0.0.1");
  expect_refused(dir, {"run", "--restart", "old.h5"},
                 "old.h5: program_version: cannot restart: written by subslip 0.0.1");
  // A file begun by code that rounds differently (another build, or other SIMD kernels) is
  // continued, with a warning that the result is not bit for bit an uninterrupted run's.
  const std::string other_build = std::string(SUBSLIP_BUILD) == "native" ? "portable" : "native";
  const std::string other_kernels =
      std::string(crystal::detail::flow_batch_isa_name()) == "avx512" ? "avx2" : "avx512";
  for (const auto& [name, value] : {std::pair<std::string, std::string>{"build", other_build},
                                    {"simd_kernels", other_kernels}}) {
    SCOPED_TRACE(name);
    fs::remove(dir / "elsewhere.h5");
    fs::copy_file(dir / "cut.h5", dir / "elsewhere.h5");
    {
      const h5::File file = h5::File::open_write(dir / "elsewhere.h5");
      ASSERT_TRUE(file.root().has_attribute(name));
      file.root().set_attribute(name, value);
    }
    EXPECT_EQ(run_subslip(dir, {"run", "--restart", "elsewhere.h5"}, dir / "run.log"), 0);
    EXPECT_NE(log_of(dir).find("warning: elsewhere.h5 was begun with build "), std::string::npos)
        << log_of(dir);
    EXPECT_NE(log_of(dir).find(value), std::string::npos) << log_of(dir);
    EXPECT_NE(log_of(dir).find("not bit for bit"), std::string::npos) << log_of(dir);
  }
  // The file's own build and kernels: no warning.
  fs::remove(dir / "elsewhere.h5");
  fs::copy_file(dir / "cut.h5", dir / "elsewhere.h5");
  EXPECT_EQ(run_subslip(dir, {"run", "--restart", "elsewhere.h5"}, dir / "run.log"), 0);
  EXPECT_EQ(log_of(dir).find("warning"), std::string::npos) << log_of(dir);
  // The same scene file is accepted; the case is recomputed (from its start: a finished case
  // keeps no checkpoint) into the same values.
  EXPECT_EQ(restart(dir, "cut.h5"), 0) << log_of(dir);
  EXPECT_EQ(run_subslip(dir, {"run", "scene.yaml", "--restart", "cut.h5"}, dir / "run.log"), 2);
  subslip::testing::expect_same_datasets(dir / "done.h5", dir / "cut.h5");
  fs::remove_all(dir);
}

// A scene made of a base scene and --set settings records both (/scene_bases, scene_set), and
// --restart continues it from them, not from the files on the disk: the base may be gone or
// changed since. A restart given other settings is refused.
TEST(Restart, ContinuesAComposedSceneFromItsStoredSources) {
  const fs::path dir = scratch_dir();
  std::ofstream(dir / "base.yaml") << crystal_scene(2, 6, "output:\n  checkpoint_every: 2\n");
  std::ofstream(dir / "scene.yaml") << "base: base.yaml\ntitle: \"composed\"\n";
  const std::vector<std::string> set = {"--set", "phase.tau0=12", "--set",
                                        "loading[1].increments=5"};
  std::vector<std::string> args = {"run", "scene.yaml", "-o", "done.h5", "-q"};
  args.insert(args.end(), set.begin(), set.end());
  ASSERT_EQ(run_subslip(dir, args, dir / "run.log"), 0) << log_of(dir);
  {
    const h5::File f = h5::File::open_read(dir / "done.h5");
    const h5::Group root = f.root();
    EXPECT_EQ(root.open_dataset("scene").read_string(), read_text(dir / "scene.yaml"));
    const h5::Dataset base = root.open_group("scene_bases").open_dataset("1");
    EXPECT_EQ(base.read_string(), read_text(dir / "base.yaml"));
    EXPECT_EQ(base.attribute_string("file"), "base.yaml");  // as named, beside scene.yaml
    EXPECT_FALSE(root.open_group("scene_bases").has("2"));
    EXPECT_EQ(root.attribute_strings("scene_set"),
              (std::vector<std::string>{"phase.tau0=12", "loading[1].increments=5"}));
    EXPECT_EQ(root.attribute_string("title"), "composed");
    for (double tau0 : root.open_group("cases/base").attribute_doubles("tau0"))
      EXPECT_EQ(tau0, 12.0);
  }
  fs::copy_file(dir / "done.h5", dir / "cut.h5");
  mark_interrupted(dir / "cut.h5");
  std::ofstream(dir / "base.yaml") << "an edit that is no scene\n";
  expect_refused(dir, {"run", "--restart", "cut.h5", "--set", "phase.tau0=13"},
                 "cut.h5: --set: a restart continues the run with the settings it started with "
                 "(phase.tau0=12, loading[1].increments=5); drop --set");
  std::vector<std::string> same = {"run", "--restart", "cut.h5", "-q"};
  same.insert(same.end(), set.begin(), set.end());
  EXPECT_EQ(run_subslip(dir, same, dir / "run.log"), 0) << log_of(dir);
  subslip::testing::expect_same_datasets(dir / "done.h5", dir / "cut.h5");
  fs::remove_all(dir);
}

// What lies at a result path says what to do with it: an interrupted run is continued with
// --restart (a new run there is refused, pointing at it); a restart file no run can continue
// (its run finished, or its result file is gone) is named as such by `post`, by a refused
// restart and by a refused new run, which --force lets replace it.
TEST(Restart, InterruptedAndLeftOverFilesSayWhatToDo) {
  const fs::path dir = scratch_dir();
  std::ofstream(dir / "scene.yaml") << crystal_scene(2, 6, "output:\n  checkpoint_every: 2\n");
  ASSERT_EQ(run_subslip(dir, {"run", "scene.yaml", "-o", "done.h5", "-q", "--keep-restart"},
                        dir / "run.log"),
            0)
      << log_of(dir);
  ASSERT_TRUE(fs::exists(dir / "done.restart.h5"));
  expect_refused(dir, {"run", "--restart", "done.h5"},
                 "done.restart.h5 beside it holds that run's last checkpoints, which no run "
                 "continues: delete it");
  ASSERT_EQ(run_subslip(dir, {"post", "done.h5"}, dir / "run.log"), 0) << log_of(dir);
  EXPECT_NE(log_of(dir).find("finished:    yes"), std::string::npos) << log_of(dir);
  EXPECT_NE(log_of(dir).find("done.restart.h5 (left over from this finished run"),
            std::string::npos)
      << log_of(dir);

  fs::copy_file(dir / "done.h5", dir / "cut.h5");
  mark_interrupted(dir / "cut.h5");
  expect_refused(dir, {"run", "scene.yaml", "-o", "cut.h5"}, "cut.h5: holds an interrupted run (");
  EXPECT_NE(log_of(dir).find("continue it with: subslip run --restart cut.h5"), std::string::npos)
      << log_of(dir);
  ASSERT_EQ(run_subslip(dir, {"post", "cut.h5"}, dir / "run.log"), 0) << log_of(dir);
  EXPECT_NE(log_of(dir).find("finished:    NO: a working file"), std::string::npos) << log_of(dir);
  // The restart finds no checkpoint of the case (a finished run's are dropped) and says so.
  ASSERT_EQ(run_subslip(dir, {"run", "--restart", "cut.h5"}, dir / "run.log"), 0) << log_of(dir);
  EXPECT_NE(log_of(dir).find("case 'base': runs again from its start: "), std::string::npos)
      << log_of(dir);

  // With the result gone, a new run names the left-over file (it never deletes one unasked).
  fs::remove(dir / "done.h5");
  expect_refused(dir, {"run", "scene.yaml", "-o", "done.h5"},
                 "done.restart.h5: already exists, left over from a run of done.h5 whose result "
                 "file is gone: no run continues from it; delete it, or use --force");
  ASSERT_EQ(run_subslip(dir, {"run", "scene.yaml", "-o", "done.h5", "--force"}, dir / "run.log"), 0)
      << log_of(dir);
  EXPECT_FALSE(fs::exists(dir / "done.restart.h5"));
  subslip::testing::expect_same_datasets(dir / "cut.h5", dir / "done.h5");
  fs::remove_all(dir);
}

// The orientations come from a file the scene names: a restart after the file changed would mix
// two sets of grains, so it is refused.
TEST(Restart, RefusesChangedOrientations) {
  const fs::path dir = scratch_dir();
  std::string scene = crystal_scene(2, 6, "output:\n  checkpoint_every: 2\n");
  scene.replace(scene.find("random: {count: 2, seed: 5}"),
                std::string("random: {count: 2, seed: 5}").size(), "file: grains.txt");
  std::ofstream(dir / "scene.yaml") << scene;
  const std::string header = "# subslip-orientations convention=bunge-euler-deg passive P=-1\n";
  std::ofstream(dir / "grains.txt") << header << "10 20 30\n40 50 60\n";
  ASSERT_EQ(run_subslip(dir, {"run", "scene.yaml", "-o", "out.h5", "-q"}, dir / "run.log"), 0)
      << log_of(dir);
  mark_interrupted(dir / "out.h5");
  std::ofstream(dir / "grains.txt") << header << "10 20 30\n40 50 61\n";
  expect_refused(dir, {"run", "--restart", "out.h5"}, "the orientations differ");
  std::ofstream(dir / "grains.txt") << header << "10 20 30\n40 50 60\n";
  EXPECT_EQ(restart(dir, "out.h5"), 0) << log_of(dir);
  fs::remove_all(dir);
}

// The restart file next to an interrupted result must be that run's: a restart file of another
// run (its run_id) or another file at that path is refused, naming it and what to do.
TEST(Restart, RefusesARestartFileOfAnotherRun) {
  const fs::path dir = scratch_dir();
  std::ofstream(dir / "scene.yaml") << crystal_scene(2, 6, "output:\n  checkpoint_every: 2\n");
  ASSERT_EQ(run_subslip(dir, {"run", "scene.yaml", "-o", "a.h5", "-q", "--keep-restart"},
                        dir / "run.log"),
            0)
      << log_of(dir);
  ASSERT_EQ(run_subslip(dir, {"run", "scene.yaml", "-o", "b.h5", "-q"}, dir / "run.log"), 0)
      << log_of(dir);
  mark_interrupted(dir / "b.h5");
  fs::copy_file(dir / "a.restart.h5", dir / "b.restart.h5");
  expect_refused(dir, {"run", "--restart", "b.h5"},
                 "b.restart.h5: run_id: cannot restart b.h5: the restart file belongs to another "
                 "run; remove it");
  std::ofstream(dir / "b.restart.h5", std::ios::trunc) << "not a restart file\n";
  expect_refused(dir, {"run", "--restart", "b.h5"}, "it is not a subslip restart file");
  fs::remove(dir / "b.restart.h5");
  EXPECT_EQ(restart(dir, "b.h5"), 0) << log_of(dir);
  subslip::testing::expect_same_datasets(dir / "a.h5", dir / "b.h5");
  fs::remove_all(dir);
}
