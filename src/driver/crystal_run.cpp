#include "subslip/driver/crystal_run.hpp"

#include <array>
#include <chrono>
#include <cmath>
#include <sstream>
#include <string>

#include "subslip/crystal/phase_builder.hpp"
#include "subslip/driver/checkpoint_policy.hpp"

namespace subslip::driver {

using crystal::Mat3;

// ---------------------------------------------------------------- summary helpers

std::pair<int, int> loading_component(const std::vector<crystal::LoadSegment>& segments) {
  std::pair<int, int> best{2, 2};
  double largest = 0.0;
  for (const auto& s : segments) {
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) {
        const double v = s.free(i, j) ? 0.0 : std::abs(s.velocity_gradient(i, j));
        if (v > largest) {
          largest = v;
          best = {i, j};
        }
      }
    }
  }
  return best;
}

double von_mises_stress(const Eigen::Matrix3d& stress) {
  const Mat3 sym = 0.5 * (stress + stress.transpose());
  const Mat3 dev = sym - sym.trace() / 3.0 * Mat3::Identity();
  return std::sqrt(1.5 * dev.squaredNorm());
}

double von_mises_strain(const Eigen::Matrix3d& strain) {
  const Mat3 sym = 0.5 * (strain + strain.transpose());
  const Mat3 dev = sym - sym.trace() / 3.0 * Mat3::Identity();
  return std::sqrt(2.0 / 3.0 * dev.squaredNorm());
}

namespace {

CrystalSummary summarise(const io::CrystalCase& c, const crystal::MacroState& last,
                         const crystal::AggregateStats& stats) {
  CrystalSummary s;
  s.final_state = last;
  s.axis = loading_component(c.segments);
  s.final_von_mises_stress = von_mises_stress(last.stress);
  s.final_von_mises_strain = von_mises_strain(last.strain);
  s.stats = stats;
  if (stats.wall_seconds > 0.0)
    s.grain_steps_per_second = static_cast<double>(stats.grain_steps) / stats.wall_seconds;
  if (stats.grain_solves > 0) {
    s.newton_per_grain_solve =
        static_cast<double>(stats.newton_iterations) / static_cast<double>(stats.grain_solves);
  }
  return s;
}

std::string case_failure(const io::CrystalCase& c, const std::string& why) {
  return "case '" + c.name + "': " + why;
}

// The result of a case an earlier session ended, from what its sink stored. The derived
// numbers are recomputed, as when the case ended.
CrystalCaseResult stored_result(const io::CrystalCase& c, const StoredCrystalCase& stored) {
  CrystalCaseResult r{c.name, summarise(c, stored.final_state, stored.stats), {}};
  if (!stored.failure.empty()) r.failure = case_failure(c, stored.failure);
  return r;
}

// Decides after each increment whether a checkpoint is due.
class CheckpointClock {
 public:
  explicit CheckpointClock(const CheckpointPolicy& p) : policy_(p) {}
  bool due() {
    ++increments_;
    const auto now = std::chrono::steady_clock::now();
    const bool by_count = policy_.every_increments > 0 && increments_ >= policy_.every_increments;
    const bool by_time =
        policy_.every_seconds > 0.0 &&
        std::chrono::duration<double>(now - last_).count() >= policy_.every_seconds;
    if (!by_count && !by_time) return false;
    increments_ = 0;
    last_ = now;
    return true;
  }

 private:
  CheckpointPolicy policy_;
  long increments_ = 0;
  std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
};

double loading_time(const io::CrystalCase& c) {
  double t = 0.0;
  for (const auto& s : c.segments) t += s.duration;
  return t;
}

// Whether case `c` writes checkpoints: its policy says so and the sink can hold them (a store
// too small for it comes from a run that had none for it).
bool writes_checkpoints(const CheckpointPolicy& policy, const io::CrystalCase& c,
                        const CrystalSink& sink) {
  const std::size_t capacity = sink.checkpoint_capacity();
  return policy.enabled() && capacity > 0 && capacity >= checkpoint_values(c);
}

// Ends the running case in the sink: completed, or failed for `failure` (the rows it reached
// stay). The summary is of the last state written.
CrystalCaseResult end_case(const io::CrystalCase& c, CrystalSink& sink,
                           const crystal::MacroState& last_output,
                           const crystal::AggregateStats& stats,
                           const std::optional<std::string>& failure) {
  CrystalCaseResult result{c.name, summarise(c, last_output, stats), {}};
  if (!failure) {
    sink.complete_case(result.summary);
    return result;
  }
  result.failure = case_failure(c, *failure);
  sink.fail_case(result.summary, *failure);
  return result;
}

std::string stopped_at(const io::CrystalCase& c, const crystal::RunPosition& at,
                       const crystal::MacroState& m, bool checkpointed) {
  std::ostringstream msg;
  msg << "case '" << c.name << "' stopped after increment " << at.increment << " of loading["
      << at.segment << "]"
      << " (time " << m.time << ")"
      << (checkpointed ? ", with a checkpoint there" : ", without a checkpoint (none enabled)");
  return msg.str();
}

// Runs case `index` into the sink; `resuming`: an interrupted case, continued from the sink's
// latest checkpoint of it (or from the start when it has none).
CrystalCaseResult run_case(const io::CrystalScene& scene, CrystalSink& sink,
                           const CrystalRunOptions& options, std::size_t index, bool resuming) {
  const io::CrystalCase& c = scene.cases[index];
  std::optional<ResumePoint> resume;
  if (resuming) resume = sink.latest_checkpoint(index);
  const CheckpointPolicy policy = checkpoint_policy(c, options.checkpoint_every);
  const bool checkpoints = writes_checkpoints(policy, c, sink);
  sink.begin_case(index, resume ? &*resume : nullptr);
  // The summary and the checkpoints name the last state written, which a resumed case has
  // from its checkpoint until it writes the next.
  crystal::MacroState last_output = resume ? resume->last_output : crystal::MacroState{};
  CheckpointClock clock(policy);
  const parallel::Team& team = *options.team;
  const auto aggregate = crystal::build_taylor_aggregate(c.phase, c.orientations, team);
  const parallel::Block block = parallel::block_of(c.orientations.size(), team.rank(), team.size());
  const GrainRange grains{block.offset, block.count, block.total};
  // After an increment, whether a checkpoint is due (the root's clock decides for every rank:
  // wall times differ) and whether to stop (any rank's request stops all), in one reduction.
  const auto after_increment = [&] {
    std::array<double, 2> wanted{checkpoints && team.is_root() && clock.due() ? 1.0 : 0.0,
                                 options.stop_requested && options.stop_requested() ? 1.0 : 0.0};
    team.max(wanted);
    return std::pair<bool, bool>{wanted[0] > 0.0, wanted[1] > 0.0};
  };
  const double duration = loading_time(c);
  const auto& on_progress = options.on_progress;
  if (on_progress && resume) on_progress(index, resume->state.macro.time / duration, true);
  crystal::RunControl control;
  if (resume) control.resume = &resume->state;
  control.after_increment = [&](const crystal::RunPosition& at, const crystal::MacroState& m) {
    if (on_progress) on_progress(index, m.time / duration, false);
    const auto [due, stop] = after_increment();
    if (checkpoints && (due || stop)) {
      const crystal::AggregateCheckpoint state = aggregate->checkpoint();
      sink.write_checkpoint(CheckpointBlock{grains, state}, last_output);
    }
    if (stop) throw RunStopped(stopped_at(c, at, m, checkpoints), checkpoints);
  };
  const auto observe = [&](const crystal::MacroState& m, const crystal::GrainFields& g) {
    last_output = m;
    sink.write_state(m, GrainBlock{grains, g});
    if (options.on_state) options.on_state(index, m, g);
  };
  crystal::AggregateStats stats;  // none when the case fails
  std::optional<std::string> failure;
  try {
    stats = aggregate->run(c.segments, c.options, observe, control);
  } catch (const crystal::CrystalStepFailure& e) {
    failure = e.what();
  }
  return end_case(c, sink, last_output, stats, failure);
}

bool ended(CaseStatus s) {
  return s == CaseStatus::completed || s == CaseStatus::failed;
}

}  // namespace

std::vector<CrystalCaseResult> run_crystal_scene(const io::CrystalScene& scene, CrystalSink& sink,
                                                 const CrystalRunOptions& options) {
  std::vector<CrystalCaseResult> results;
  for (std::size_t k = 0; k < scene.cases.size(); ++k) {
    const CaseStatus status = sink.status(k);
    if (ended(status)) {
      results.push_back(stored_result(scene.cases[k], sink.stored_case(k)));
      if (options.on_progress) options.on_progress(k, 1.0, true);
    } else {
      results.push_back(run_case(scene, sink, options, k, status == CaseStatus::interrupted));
    }
    if (options.on_case_done) options.on_case_done(k, scene.cases[k], results.back());
  }
  sink.end_run();
  return results;
}

}  // namespace subslip::driver
