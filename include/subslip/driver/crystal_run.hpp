// How a crystal scene runs: its cases one after the other (the grains of a case in parallel
// inside the Taylor aggregate), each from its start or, in a restart, from its latest
// checkpoint; checkpoints when the policy says; every output state handed to the sink as it is
// computed. No file is touched here: the sink (driver/crystal_sink.hpp) does that.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "subslip/crystal/aggregate.hpp"
#include "subslip/driver/crystal_sink.hpp"
#include "subslip/model/crystal_case.hpp"
#include "subslip/parallel/team.hpp"

namespace subslip::driver {

// The component (i, j) of L that drives a case: the largest prescribed |L_ij| over its
// segments (the tension axis, the shear component, ...). The summary reports strain and stress
// along it.
std::pair<int, int> loading_component(const std::vector<crystal::LoadSegment>& segments);

// What a restart finds of case `index` from the sessions before it (a run continued with
// --restart), reported before the case is run or skipped.
struct EarlierWork {
  enum class Kind {
    ended,       // the case ended (completed or failed) in an earlier session: it is not run
    checkpoint,  // the case continues from its latest checkpoint
    from_start,  // the case was interrupted without a checkpoint it can continue from: it runs
                 // again from its start (`why`)
  };
  Kind kind = Kind::from_start;
  crystal::RunPosition position;  // checkpoint: where it continues
  double time = 0.0;              // checkpoint: the loading time there
  crystal::AggregateStats stats;  // the counters of the sessions before (none for from_start)
  std::string why;                // from_start: why there is no checkpoint to continue from
};

struct CrystalRunOptions {
  // The ranks that share each case's grains (MPI; each holds its parallel::block_of them). With
  // more than one, the sink must be a TeamCrystalSink (driver/team_crystal_sink.hpp) on every
  // rank, and every rank calls run_crystal_scene.
  const parallel::Team* team = &parallel::serial_team();
  // --checkpoint-every: overrides every case's checkpoint_policy (driver/checkpoint_policy.hpp).
  std::optional<long> checkpoint_every;
  // Called as each case ends or is found ended by an earlier session.
  std::function<void(std::size_t index, const model::CrystalCase&, const CrystalCaseResult&)>
      on_case_done;
  // How far case `index` is: the fraction of its loading time done. `resumed` marks the point a
  // restart continues from (work done before this session), and completed cases it skips.
  std::function<void(std::size_t index, double fraction, bool resumed)> on_progress;
  // Called for every case a restart finds begun or ended by an earlier session (on every rank).
  std::function<void(std::size_t index, const EarlierWork&)> on_earlier_work;
  // Asked after every increment (on every rank; the ranks stop together when any asks): true
  // stops the run there, after a checkpoint when the case writes them, with RunStopped (a
  // signal from a batch scheduler, Ctrl-C). None: the run is never stopped.
  std::function<bool()> stop_requested;
  // Called with every state the aggregate reports, after the sink has it (tests, progress).
  std::function<void(std::size_t index, const crystal::MacroState&, const crystal::GrainFields&)>
      on_state;
};

// Runs `scene` over the ranks of `team`; every rank calls it, `root_sink` being the result
// file's sink on the root and null elsewhere. A scene of at least as many cases as ranks (a
// sweep) gives each rank whole cases, round by round (rank r of N runs cases r, N + r, ...
// with its threads), and the root writes each round's cases in case order as they come: a
// kill loses at most the round in progress, whose cases --restart runs again from their start
// (such cases write no checkpoints). Fewer cases than ranks: every case's grains are shared
// among the ranks, with checkpoints as in a serial run: their blocks reach the root's sink
// (TeamCrystalSink), or, with `own_sinks`, every rank passes its own sink in `root_sink` and
// the ranks write one file together (CollectiveCrystalSink: parallel HDF5). The results are
// the same on every rank, and equal the serial run's.
std::vector<CrystalCaseResult> run_crystal_scene_on_team(const model::CrystalScene& scene,
                                                         const parallel::Team& team,
                                                         CrystalSink* root_sink,
                                                         const CrystalRunOptions& options = {},
                                                         bool own_sinks = false);

// Whether run_crystal_scene_on_team shares the grains of each case among the ranks of `team`
// (fewer cases than ranks), rather than giving each rank whole cases.
bool shares_grains(const model::CrystalScene& scene, const parallel::Team& team);

// The run stopped on request (CrystalRunOptions::stop_requested) after an increment of the
// running case; `checkpointed`: a checkpoint of that increment was written, from which
// --restart continues (else from the case's last checkpoint, or its start).
struct RunStopped : std::runtime_error {
  RunStopped(const std::string& what, bool saved) : std::runtime_error(what), checkpointed(saved) {}
  bool checkpointed;
};

// Runs every case of `scene` in order into `sink`: cases the sink reports ended are kept (their
// stored results returned), an interrupted one continues from the sink's latest checkpoint of
// it, the others start. A case that fails numerically (crystal::CrystalStepFailure) is ended
// with fail_case and gets a result with `failure` set; the other cases still run. Other errors
// (the sink's) are thrown.
std::vector<CrystalCaseResult> run_crystal_scene(const model::CrystalScene& scene,
                                                 CrystalSink& sink,
                                                 const CrystalRunOptions& options = {});

}  // namespace subslip::driver
