#include "subslip/driver/crystal_run.hpp"

#include <array>
#include <chrono>
#include <cmath>
#include <sstream>
#include <string>

#include "packing.hpp"
#include "subslip/crystal/measures.hpp"
#include "subslip/crystal/phase_builder.hpp"
#include "subslip/driver/checkpoint_policy.hpp"
#include "subslip/driver/team_crystal_sink.hpp"

namespace subslip::driver {

using crystal::Mat3;

// ---------------------------------------------------------------- summary helpers

std::pair<int, int> loading_component(const std::vector<crystal::LoadSegment>& segments) {
  std::pair<int, int> best{2, 2};
  double largest = 0.0;
  for (const auto& s : segments) {
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) {
        const double v = s.free(i, j) ? 0.0 : std::abs(crystal::prescribed_rate(s)(i, j));
        if (v > largest) {
          largest = v;
          best = {i, j};
        }
      }
    }
  }
  return best;
}

namespace {

CrystalSummary summarise(const model::CrystalCase& c, const crystal::MacroState& last,
                         const crystal::AggregateStats& stats) {
  CrystalSummary s;
  s.final_state = last;
  s.axis = loading_component(c.segments);
  s.final_von_mises_stress = crystal::von_mises_stress(last.stress);
  s.final_von_mises_strain = crystal::von_mises_strain(last.strain);
  s.stats = stats;
  if (stats.wall_seconds > 0.0)
    s.grain_steps_per_second = static_cast<double>(stats.grain_steps) / stats.wall_seconds;
  if (stats.grain_solves > 0) {
    s.newton_per_grain_solve =
        static_cast<double>(stats.newton_iterations) / static_cast<double>(stats.grain_solves);
  }
  return s;
}

std::string case_failure(const model::CrystalCase& c, const std::string& why) {
  return "case '" + c.name + "': " + why;
}

// The result of a case an earlier session ended, from what its sink stored. The derived
// numbers are recomputed, as when the case ended.
CrystalCaseResult stored_result(const model::CrystalCase& c, const StoredCrystalCase& stored) {
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

double loading_time(const model::CrystalCase& c) {
  double t = 0.0;
  for (const auto& s : c.segments) t += s.duration;
  return t;
}

// Whether case `c` writes checkpoints: its policy says so and the sink can hold them (a store
// too small for it comes from a run that had none for it).
bool writes_checkpoints(const CheckpointPolicy& policy, const model::CrystalCase& c,
                        const CrystalSink& sink) {
  const std::size_t capacity = sink.checkpoint_capacity();
  return policy.enabled() && capacity > 0 && capacity >= checkpoint_values(c);
}

// Ends the running case in the sink: completed, or failed for `failure` (the rows it reached
// stay). The summary is of the last state written.
CrystalCaseResult end_case(const model::CrystalCase& c, CrystalSink& sink,
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

std::string stopped_at(const model::CrystalCase& c, const crystal::RunPosition& at,
                       const crystal::MacroState& m, bool checkpointed) {
  std::ostringstream msg;
  msg << "case '" << c.name << "' stopped after increment " << at.increment << " of loading["
      << at.segment << "]"
      << " (time " << m.time << ")"
      << (checkpointed ? ", with a checkpoint there" : ", without a checkpoint (none enabled)");
  return msg.str();
}

// What an interrupted case continues from: its latest checkpoint, or (none) its start.
EarlierWork earlier_work(const std::optional<ResumePoint>& resume, bool checkpoints) {
  EarlierWork w;
  if (resume) {
    w.kind = EarlierWork::Kind::checkpoint;
    w.position = resume->state.position;
    w.time = resume->state.macro.time;
    w.stats = resume->state.stats;
  } else {
    w.why = checkpoints ? "the run stopped before the case's first checkpoint"
                        : "the case writes no checkpoints";
  }
  return w;
}

// Runs case `index` into the sink; `resuming`: an interrupted case, continued from the sink's
// latest checkpoint of it (or from the start when it has none).
CrystalCaseResult run_case(const model::CrystalScene& scene, CrystalSink& sink,
                           const CrystalRunOptions& options, std::size_t index, bool resuming) {
  const model::CrystalCase& c = scene.cases[index];
  std::optional<ResumePoint> resume;
  if (resuming) resume = sink.latest_checkpoint(index);
  const CheckpointPolicy policy = checkpoint_policy(c, options.checkpoint_every);
  const bool checkpoints = writes_checkpoints(policy, c, sink);
  if (resuming && options.on_earlier_work)
    options.on_earlier_work(index, earlier_work(resume, checkpoints));
  sink.begin_case(index, resume ? &*resume : nullptr);
  // The summary and the checkpoints name the last state written, which a resumed case has
  // from its checkpoint until it writes the next.
  crystal::MacroState last_output = resume ? resume->last_output : crystal::MacroState{};
  CheckpointClock clock(policy);
  const parallel::Team& team = *options.team;
  const parallel::Block block = parallel::block_of(c.grain_count(), team.rank(), team.size());
  if (c.orientation_block && c.orientation_block->offset != block.offset)
    throw std::logic_error("run_case: the orientations held are another rank's block");
  const auto aggregate = crystal::build_taylor_aggregate(c.phase, c.orientations, team,
                                                         c.orientation_block ? &block : nullptr);
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

// A case an earlier session ended, to on_earlier_work.
void report_ended(const CrystalRunOptions& options, std::size_t index,
                  const CrystalCaseResult& stored) {
  if (!options.on_earlier_work) return;
  EarlierWork w;
  w.kind = EarlierWork::Kind::ended;
  w.stats = stored.summary.stats;
  options.on_earlier_work(index, w);
}

// ---------------------------------------------------------------- whole cases over ranks

// The sink of a case one rank runs alone: its output states, packed for the root, and how it
// ended. It holds no checkpoints (the case is rerun from its start after a kill).
class RecordingSink final : public CrystalSink {
 public:
  Packed states;  // count, grains, slip systems, then per state its macro state and fields
  std::size_t count = 0;
  int grains = 0, slips = 0;
  std::optional<CrystalSummary> summary;
  std::string why;  // of a failure

  CaseStatus status(std::size_t) const override { return CaseStatus::pending; }
  StoredCrystalCase stored_case(std::size_t) const override { return {}; }
  std::optional<ResumePoint> latest_checkpoint(std::size_t) const override { return std::nullopt; }
  std::size_t checkpoint_capacity() const override { return 0; }
  void begin_case(std::size_t, const ResumePoint*) override {}
  void write_state(const crystal::MacroState& state, const GrainBlock& block) override {
    const FieldArrays fields(block.fields);
    grains = fields.grain_count();
    slips = fields.slip_count();
    states.put(state);
    states.values.insert(states.values.end(), fields.values().begin(), fields.values().end());
    ++count;
  }
  void write_checkpoint(const CheckpointBlock&, const crystal::MacroState&) override {}
  void complete_case(const CrystalSummary& s) override { summary = s; }
  void fail_case(const CrystalSummary& s, const std::string& reason) override {
    summary = s;
    why = reason;
  }
  void end_run() override {}

  // What the root receives: the header, then the states.
  std::vector<double> message() const {
    Packed head;
    head.put_integer(static_cast<std::int64_t>(count));
    head.put_integer(grains);
    head.put_integer(slips);
    head.values.insert(head.values.end(), states.values.begin(), states.values.end());
    return head.values;
  }
};

// Case `index` on this rank alone (the serial team), recorded; `error`: an exception other
// than a step failure, which stops every rank when the case's turn to be written comes.
struct CaseAlone {
  RecordingSink record;
  std::string error;
};

void run_alone(const model::CrystalScene& scene, std::size_t index, CaseAlone& out) {
  CrystalRunOptions alone;  // the serial team, no checkpoints, no callbacks
  alone.checkpoint_every = 0;
  try {
    run_case(scene, out.record, alone, index, false);
  } catch (const std::exception& e) {
    out.error = e.what();
  }
}

// The root writes a case another rank (or itself) recorded.
void replay(CrystalSink& sink, std::size_t index, const std::vector<double>& message,
            const CrystalSummary& summary, const std::string& why) {
  sink.begin_case(index, nullptr);
  Unpacked in(message);
  const auto count = static_cast<std::size_t>(in.integer());
  const auto grains = static_cast<int>(in.integer());
  const auto slips = static_cast<int>(in.integer());
  FieldArrays fields(grains, slips);
  const GrainRange all{0, static_cast<std::size_t>(grains), static_cast<std::size_t>(grains)};
  for (std::size_t k = 0; k < count; ++k) {
    crystal::MacroState state;
    in.get(state);
    const auto values = in.take(fields.values().size());
    std::copy(values.begin(), values.end(), fields.values().begin());
    sink.write_state(state, GrainBlock{all, fields});
  }
  if (why.empty()) {
    sink.complete_case(summary);
  } else {
    sink.fail_case(summary, why);
  }
}

// Case `index`, recorded by rank `owner` (`mine` there): its result on every rank, its states
// written by the root.
CrystalCaseResult write_case_of(const model::CrystalScene& scene, const parallel::Team& team,
                                CrystalSink* root_sink, std::size_t index, int owner,
                                const CaseAlone* mine) {
  Packed head;
  std::string why, error;
  if (mine != nullptr) {
    head.put(mine->record.summary.value_or(CrystalSummary{}));
    why = mine->record.why;
    error = mine->error;
  }
  team.broadcast(head.values, owner);
  team.broadcast(why, owner);
  team.broadcast(error, owner);
  const model::CrystalCase& c = scene.cases[index];
  if (!error.empty()) parallel::stop_every_rank(team, case_failure(c, error), owner);
  CrystalCaseResult result{c.name, {}, why.empty() ? "" : case_failure(c, why)};
  Unpacked(head.values).get(result.summary);
  std::vector<double> states;
  if (mine != nullptr) {
    if (owner != 0) team.send(mine->record.message(), 0);
    if (team.is_root()) states = mine->record.message();
  } else if (team.is_root()) {
    states = team.receive(owner);
  }
  parallel::on_root(team, [&] { replay(*root_sink, index, states, result.summary, why); });
  return result;
}

std::vector<CrystalCaseResult> run_cases_over_ranks(const model::CrystalScene& scene,
                                                    const parallel::Team& team,
                                                    CrystalSink* root_sink,
                                                    const CrystalRunOptions& options) {
  TeamCrystalSink shared(team, root_sink);  // the root's answers, on every rank
  const std::size_t n = scene.cases.size();
  std::vector<CaseStatus> status(n);
  for (std::size_t k = 0; k < n; ++k) status[k] = shared.status(k);
  std::vector<CrystalCaseResult> results;
  const auto ranks = static_cast<std::size_t>(team.size());
  for (std::size_t first = 0; first < n; first += ranks) {
    const std::size_t mine_index = first + static_cast<std::size_t>(team.rank());
    std::optional<CaseAlone> mine;
    if (mine_index < n && !ended(status[mine_index])) {
      mine.emplace();
      run_alone(scene, mine_index, *mine);
    }
    std::array<double, 1> stop{options.stop_requested && options.stop_requested() ? 1.0 : 0.0};
    team.max(stop);
    const std::size_t last = std::min(n, first + ranks);
    for (std::size_t k = first; k < last; ++k) {
      if (ended(status[k])) {
        results.push_back(stored_result(scene.cases[k], shared.stored_case(k)));
        report_ended(options, k, results.back());
      } else {
        if (status[k] == CaseStatus::interrupted && options.on_earlier_work) {
          EarlierWork w;
          w.why = "a case a rank runs whole writes no checkpoints";
          options.on_earlier_work(k, w);
        }
        const int owner = static_cast<int>(k - first);
        results.push_back(write_case_of(scene, team, root_sink, k, owner,
                                        owner == team.rank() ? &*mine : nullptr));
      }
      if (options.on_progress) options.on_progress(k, 1.0, ended(status[k]));
      if (options.on_case_done) options.on_case_done(k, scene.cases[k], results.back());
    }
    if (stop[0] > 0.0 && last < n) {
      throw RunStopped("stopped after case '" + scene.cases[last - 1].name + "' (" +
                           std::to_string(last) + " of " + std::to_string(n) +
                           " cases written; --restart runs the others)",
                       false);
    }
  }
  shared.end_run();
  return results;
}

}  // namespace

bool shares_grains(const model::CrystalScene& scene, const parallel::Team& team) {
  return team.size() > 1 && scene.cases.size() < static_cast<std::size_t>(team.size());
}

std::vector<CrystalCaseResult> run_crystal_scene_on_team(const model::CrystalScene& scene,
                                                         const parallel::Team& team,
                                                         CrystalSink* root_sink,
                                                         const CrystalRunOptions& options,
                                                         bool own_sinks) {
  if (team.size() == 1) return run_crystal_scene(scene, *root_sink, options);
  if (!shares_grains(scene, team)) return run_cases_over_ranks(scene, team, root_sink, options);
  CrystalRunOptions over_ranks = options;
  over_ranks.team = &team;
  if (own_sinks) {
    CollectiveCrystalSink together(team, *root_sink);
    return run_crystal_scene(scene, together, over_ranks);
  }
  TeamCrystalSink shared(team, root_sink);
  return run_crystal_scene(scene, shared, over_ranks);
}

std::vector<CrystalCaseResult> run_crystal_scene(const model::CrystalScene& scene,
                                                 CrystalSink& sink,
                                                 const CrystalRunOptions& options) {
  std::vector<CrystalCaseResult> results;
  for (std::size_t k = 0; k < scene.cases.size(); ++k) {
    const CaseStatus status = sink.status(k);
    if (ended(status)) {
      results.push_back(stored_result(scene.cases[k], sink.stored_case(k)));
      report_ended(options, k, results.back());
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
