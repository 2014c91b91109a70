// The crystal drivers: a single crystal is an aggregate of one grain; a Taylor (iso-strain)
// polycrystal gives every grain the same velocity gradient and homogenises the stress as the
// weighted average. Loading is mixed control in the DAMASK load-case convention: every
// component of the rate (L, or dot_F) is either prescribed or free, and each free component's
// stress (Cauchy, or first Piola-Kirchhoff) is prescribed.
//
// The step is a pure function of the start state: the whole aggregate is advanced from the
// committed state; a mixed-control Newton re-runs the grains from that state with an updated
// L; a failed grain makes the whole step halve (cut back) and retry. Grains run in parallel
// (OpenMP, static schedule, inside each MPI rank when the aggregate is shared: GrainShare); the
// volume averages are exact sums (parallel/exact_sum.hpp) and every other reduction picks by
// grain index, so results are bitwise independent of the thread and rank counts.
#pragma once

#include <Eigen/Core>
#include <array>
#include <functional>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "subslip/crystal/crystal_kernel.hpp"
#include "subslip/crystal/grain_fields_table.hpp"
#include "subslip/parallel/team.hpp"

namespace subslip::crystal {

using Mask3 = Eigen::Matrix<bool, 3, 3>;

// What a segment's kinematic components prescribe. The aggregate always steps with a velocity
// gradient; under dot_F it is the one whose Cayley map over the step takes F_n to
// F_n + dot_F dt exactly (DAMASK's meaning of dot_F).
enum class RateControl {
  velocity_gradient,  // L, held over the segment
  deformation_rate,   // dot_F, held over the segment: F grows linearly in time
};

// What a segment's stress components prescribe: the Cauchy stress sigma, or the first
// Piola-Kirchhoff stress P = J sigma F^-T (not symmetric: each of its nine components is its
// own condition, so free rate components are never paired under P).
enum class StressMeasure { cauchy, first_piola };

struct LoadSegment {
  Mat3 velocity_gradient = Mat3::Zero();  // prescribed components of L [1/time]
  Mat3 deformation_rate = Mat3::Zero();   // prescribed components of dot_F [1/time]
  RateControl rate_control = RateControl::velocity_gradient;
  Mask3 free = Mask3::Constant(false);  // true: the rate component ij free, stress_ij prescribed
  StressMeasure stress_measure = StressMeasure::cauchy;
  Mat3 stress_target = Mat3::Zero();  // stress_measure reached at the segment end (free comps)
  double duration = 1.0;              // [time]
  int increments = 1;
  double growth = 1.0;  // ratio of successive increments
  int output_every = 1;
  // Output at chosen times instead (output_at_times): only at these times into the segment
  // (increasing, in (0, duration]), which the steps end on exactly: a fixed increment is split,
  // an adaptive step shortened. None: no output in this segment.
  bool output_at_times = false;
  std::vector<double> output_times;
};

// The prescribed rate tensor of a segment: L or dot_F, as its rate_control says.
inline const Mat3& prescribed_rate(const LoadSegment& seg) {
  return seg.rate_control == RateControl::velocity_gradient ? seg.velocity_gradient
                                                            : seg.deformation_rate;
}

// The increment lengths of a segment: geometric progression summing to the duration exactly.
std::vector<double> increment_lengths(double duration, int increments, double growth);

enum class CrystalMethod { implicit, forward_euler };

// Mixed control: where a step's iteration on the free components of L starts. `last`: their
// values of the last step. `trend`: those continued along their change per unit time over the
// segment's last step (a component that would change sign keeps its value; a step that fails
// from there is tried from `last`, and a failed step clears the trend): fewer grain Newton
// iterations on smooth loading paths, but a different path through holds at yield vertices of
// nearly ideal plasticity, where the free L is hardly determined (docs/benchmarks.md, "The
// free components' trend").
enum class MixedPredictor { last, trend };

struct AggregateOptions {
  CrystalMethod method = CrystalMethod::implicit;
  GrainStepOptions grain;
  // With a tolerance, the grains' steps are solved to tolerance / 100 where that is tighter
  // than grain.tolerance (integrators/inner_tolerance.hpp); false: to grain.tolerance as given
  // (a scene that names its residual_tolerance).
  bool grain_tolerance_follows_tolerance = true;
  int max_cutbacks = 20;  // halvings of one increment
  // Mixed control: |sigma_free - target| relative to the stress scale. The accepted error is a
  // strain error the next increment starts from, so a run drifts by up to increments x this
  // (relative): 1e-10 keeps a 1e5-increment run within 1e-5. A tolerance finer than the state
  // resolves (round-off, or the grains' Newton tolerance) is met as well as it can be.
  double stress_tolerance = 1e-10;
  // With a tolerance, the free stresses are brought to tolerance / 100 of the smallest CRSS
  // instead, and with order 1 (whose estimate reads the rates) to the tighter of the two
  // (src/crystal/mixed_control.cpp, free_stress_tolerance); false: stress_tolerance as given
  // (a scene that names it).
  bool stress_tolerance_follows_tolerance = true;
  int max_mixed_iterations = 25;
  MixedPredictor predictor = MixedPredictor::last;
  // Adaptive stepping (implicit only) when > 0: the local error of each step, estimated per
  // grain and slip system as dt/2 |A (gdot_end - gdot_start)| (the change of the resolved
  // shear stress rate over the step, A = P:C:P) in units of the current CRSS mu tau0, is kept
  // below `tolerance` for every grain; the step grows and shrinks with it. A segment's
  // increments then only set its first step, and every accepted step is an increment.
  double tolerance = 0.0;
  // With a tolerance: 1 is backward Euler with the estimate above; 2 .. 4 (the extrapolation's
  // kMaxExtrapolationOrder) is backward Euler extrapolated to that order
  // (integrators/extrapolation.hpp), with the estimate the difference of its two best solutions
  // (every system's resolved shear stress over its CRSS).
  int order = 1;
};

// `opt` with grain.tolerance as its run solves the grains' steps to
// (grain_tolerance_follows_tolerance).
AggregateOptions with_effective_grain_tolerance(AggregateOptions opt);

// What an observer sees at an output step.
struct MacroState {
  double time = 0.0;
  // Time into the current segment. Exact where `time` cannot resolve the steps: 1e-11 s steps
  // of a 1e-4 s segment after 1e6 s of loading all round to the same double.
  double segment_time = 0.0;
  int segment = -1;  // -1 for the initial state
  Mat3 velocity_gradient = Mat3::Zero();
  Mat3 deformation_gradient = Mat3::Identity();
  Mat3 strain = Mat3::Zero();  // log strain ln V (finite rotation) or the integral of D
  Mat3 stress = Mat3::Zero();  // volume-averaged Cauchy stress
};

struct AggregateStats {
  long increments = 0;
  long substeps = 0;
  long grain_steps = 0;        // grain updates that were committed
  long grain_solves = 0;       // grain updates attempted (mixed-control iterations included)
  long newton_iterations = 0;  // summed over grain solves
  long cutbacks = 0;
  long rejected = 0;  // adaptive steps refused by the error estimate (redone smaller)
  long mixed_iterations = 0;
  double wall_seconds = 0.0;
};

// Per-grain fields for output, filled into caller-owned arrays (row-major, one row a grain).
// The fields are those of the table (grain_fields_table.hpp), which gives each one's width as
// given here (given_width), unit and meaning; an implementation gives every field of it.
class GrainFields {
 public:
  virtual ~GrainFields() = default;
  virtual int grain_count() const = 0;
  virtual int slip_count() const = 0;
  // [grains x given_width(f, slip_count())] values of `f` into `out`: stress 11 22 33 23 13 12
  // (sample frame), orientation g row-major (v_c = g v_s), the others one per slip system.
  virtual void values(GrainField f, double* out) const = 0;
};

using MacroObserver = std::function<void(const MacroState&, const GrainFields&)>;

// Where a run stands between two increments.
struct RunPosition {
  int segment = 0;            // the segment of the last completed increment
  long increment = 0;         // increments completed in that segment
  double segment_time = 0.0;  // time completed in that segment
  double next_step = 0.0;     // adaptive stepping: the step the next increment tries (else 0)
};

// Values of one grain's state (GrainState) of a phase of N slip systems: stress 6, orientation
// 9, then mu, r_s, slip and slip rate, N each.
constexpr int state_values_per_grain(int slip_count) {
  return 15 + 4 * slip_count;
}

// Values per grain in a checkpoint (see AggregateCheckpoint): the state, then its slip-rate
// trend and the trend's change (N each), from which the next step's Newton iteration starts.
constexpr int checkpoint_values_per_grain(int slip_count) {
  return state_values_per_grain(slip_count) + 2 * slip_count;
}

// Everything a run carries from one increment to the next: continuing from a checkpoint gives
// the results of the uninterrupted run bit for bit. A plain value (the I/O layer stores it).
struct AggregateCheckpoint {
  RunPosition position;
  MacroState macro;                          // the current state (not necessarily an output)
  Mat3 segment_start_stress = Mat3::Zero();  // where the segment's stress ramp starts
  Eigen::VectorXd free_velocity_gradient;    // mixed control: the free components of L
  // Their predictor's state (MixedPredictor::trend): the change per unit time (1/s^2) of the
  // path they follow without the free-stress errors the steps accepted, that path at the last
  // step (1/s), and the strain along them that removes the last step's error to first order.
  Eigen::VectorXd free_velocity_gradient_trend;
  Eigen::VectorXd free_velocity_gradient_path;
  Eigen::VectorXd free_strain_correction;
  double trend_step = 0.0;   // the step the grains' slip-rate trend was taken over (0: none yet)
  AggregateStats stats;      // counters so far; wall_seconds over all sessions
  int values_per_grain = 0;  // checkpoint_values_per_grain(N)
  // Per grain: Cauchy stress (lattice frame, Mandel) 6, orientation g row-major 9, then mu,
  // r_s, slip, slip rate, slip-rate trend (the rate's change per unit time over the last
  // step) and the trend's change per unit time since the step before, N each.
  std::vector<double> grains;

  // The mixed-control vectors, in the order they are stored (one entry per free component).
  std::array<const Eigen::VectorXd*, 4> free_vectors() const {
    return {&free_velocity_gradient, &free_velocity_gradient_trend, &free_velocity_gradient_path,
            &free_strain_correction};
  }
  std::array<Eigen::VectorXd*, 4> free_vectors() {
    return {&free_velocity_gradient, &free_velocity_gradient_trend, &free_velocity_gradient_path,
            &free_strain_correction};
  }
};

struct RunControl {
  // Continue from this checkpoint (of a run of the same segments and options).
  const AggregateCheckpoint* resume = nullptr;
  // Called after every completed increment, after its output if it has one; it may call
  // Aggregate::checkpoint(). For progress reports and checkpoints: no I/O in the drivers.
  std::function<void(const RunPosition&, const MacroState&)> after_increment;
};

struct CrystalStepFailure : std::runtime_error {
  explicit CrystalStepFailure(const std::string& what,
                              double smallest_tolerance = std::numeric_limits<double>::quiet_NaN())
      : std::runtime_error(what), smallest_tolerance(smallest_tolerance) {}
  // As history::StepFailure::smallest_tolerance: the tolerance a noise-floor stop names, else NaN.
  double smallest_tolerance;
};

// A runtime-polymorphic handle on a Taylor aggregate of some slip count (one virtual call per
// run or output, never per slip system).
class Aggregate {
 public:
  virtual ~Aggregate() = default;
  virtual int grain_count() const = 0;
  virtual int slip_count() const = 0;
  virtual std::size_t state_bytes_per_grain() const = 0;
  // What the aggregate holds per grain while it runs: the committed and trial states, the
  // consistent tangent, the step report and the weight (what limits the grains one process
  // can hold; the checkpoint and output buffers come on top).
  virtual std::size_t memory_bytes_per_grain() const = 0;
  // Runs the segments from the initial state (observed first) or, with control.resume, from
  // that checkpoint (nothing observed until the next output increment).
  virtual AggregateStats run(const std::vector<LoadSegment>& segments, const AggregateOptions& opt,
                             const MacroObserver& observe, const RunControl& control = {}) = 0;
  // The run's state, from inside RunControl::after_increment (or after run() returned).
  virtual AggregateCheckpoint checkpoint() const = 0;
  // Sets the grains, the macro state and the counters from a checkpoint of an aggregate of the
  // same grains (throws std::invalid_argument when the sizes differ).
  virtual void restore(const AggregateCheckpoint& c) = 0;
};

// The grains of an aggregate this process computes when the aggregate is shared among the
// ranks of a team (MPI): grains [offset, offset + count) of `total`, count being the number of
// orientations given; the other ranks hold the rest. Every rank runs the same loading; the
// volume averages, the decisions (convergence, cutbacks, failure) and the counters are the
// team's, bitwise the same at any rank count (exact sums), so every rank holds the same macro
// state. Default: this process holds every grain.
struct GrainShare {
  const parallel::Team* team = &parallel::serial_team();
  std::size_t offset = 0;
  std::size_t total = 0;  // 0: the number of orientations given
};

// The Taylor aggregate for N slip systems (N = Eigen::Dynamic for unusual counts). The weights
// are relative (empty: equal); they are normalised over all grains of the team. grain_count(),
// the GrainFields and the checkpoint's grains are this rank's block.
template <int N>
std::unique_ptr<Aggregate> make_taylor_aggregate(Phase<N> phase,
                                                 const std::vector<Mat3>& orientations,
                                                 const std::vector<double>& weights,
                                                 const typename SlipTypes<N>::VecN& initial_mu,
                                                 const GrainShare& share = {});

}  // namespace subslip::crystal
