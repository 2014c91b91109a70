#include "subslip/crystal/aggregate.hpp"

#include "aggregate_extrapolation.hpp"
#include "grain_sweep.hpp"
#include "mixed_control.hpp"
#include "subslip/crystal/free_components.hpp"
#include "subslip/integrators/extrapolation.hpp"
#include "subslip/integrators/inner_tolerance.hpp"
#include "subslip/integrators/step_control.hpp"

#include <Eigen/LU>
#include <chrono>
#include <sstream>

namespace subslip::crystal {

std::vector<double> increment_lengths(double duration, int increments, double growth) {
  std::vector<double> dt(static_cast<size_t>(increments));
  double sum = 0.0, h = 1.0;
  for (auto& d : dt) {
    d = h;
    sum += h;
    h *= growth;
  }
  for (auto& d : dt) d *= duration / sum;
  return dt;
}

namespace {

using aggregate_parts::ErrorEstimate;
using aggregate_parts::log_strain;
using aggregate_parts::symmetric_part;

// The Taylor aggregate: the run loops (increments and their cutbacks, the adaptive clock and
// its extrapolated steps) over its parts: the grains (GrainSweep, src/crystal/grain_sweep.cpp;
// their checkpoint in aggregate_checkpoint.cpp), the mixed control (MixedControl,
// mixed_control.cpp) and the extrapolated step's work space (Extrapolation,
// aggregate_extrapolation.cpp).
template <int N>
class TaylorAggregate final : public Aggregate {
 public:
  using VecN = typename SlipTypes<N>::VecN;

  TaylorAggregate(Phase<N> phase, const std::vector<Mat3>& orientations,
                  const std::vector<double>& weights, const VecN& initial_mu,
                  const GrainShare& share)
      : grains_(std::move(phase), orientations, weights, initial_mu, share),
        mixed_(grains_, macro_, stats_),
        extrapolation_(orientations.size()) {}

  int grain_count() const override { return grains_.grain_count(); }
  int slip_count() const override { return grains_.slip_count(); }
  std::size_t state_bytes_per_grain() const override {
    return sizeof(double) * static_cast<size_t>(state_values_per_grain(grains_.slip_count()));
  }
  std::size_t memory_bytes_per_grain() const override {
    return 2 * sizeof(GrainState<N>) + sizeof(Tangent) + sizeof(SlipTangent<N>) + 3 * sizeof(VecN) +
           sizeof(GrainStepReport) + sizeof(double);
  }

  AggregateStats run(const std::vector<LoadSegment>& segments, const AggregateOptions& given,
                     const MacroObserver& observe, const RunControl& control) override {
    const AggregateOptions opt = with_effective_grain_tolerance(given);
    session_start_ = std::chrono::steady_clock::now();
    const AggregateCheckpoint* resume = control.resume;
    size_t first = 0;
    if (resume != nullptr) {
      restore(*resume);
      first = static_cast<size_t>(resume->position.segment);
    } else {
      stats_ = {};
      macro_ = {};
      wall_before_ = 0.0;
      observe(macro_, grains_);
    }
    // Where each segment starts in time, from the durations (not the sum of the steps, which
    // rounds): output times are that plus their time into the segment, also after a restart.
    double segment_start = 0.0;
    for (size_t k = 0; k < first; ++k) segment_start += segments[k].duration;
    for (size_t k = first; k < segments.size(); ++k) {
      run_segment(segments[k], k > 0 ? &segments[k - 1] : nullptr, static_cast<int>(k),
                  segment_start, opt, observe, control, k == first ? resume : nullptr);
      segment_start += segments[k].duration;
    }
    stats_.wall_seconds = wall_seconds();
    return stats_;
  }

  AggregateCheckpoint checkpoint() const override {
    AggregateCheckpoint c;
    c.position = cursor_.position;
    c.macro = macro_;
    c.segment_start_stress = cursor_.stress_start;
    c.free_velocity_gradient = cursor_.free;
    c.free_velocity_gradient_trend = mixed_.path().trend;
    c.free_velocity_gradient_path = mixed_.path().value;
    c.free_strain_correction = mixed_.path().correction;
    c.trend_step = grains_.trend_step();
    c.stats = stats_;
    c.stats.wall_seconds = wall_seconds();
    c.values_per_grain = checkpoint_values_per_grain(grains_.slip_count());
    c.grains.resize(grains_.committed().size() * static_cast<size_t>(c.values_per_grain));
    grains_.pack(c.grains.data());
    return c;
  }

  void restore(const AggregateCheckpoint& c) override {
    if (c.values_per_grain != checkpoint_values_per_grain(grains_.slip_count()) ||
        c.grains.size() != grains_.committed().size() * static_cast<size_t>(c.values_per_grain)) {
      throw std::invalid_argument(
          "checkpoint of a different aggregate (grains or slip systems) or of an older subslip "
          "(no slip-rate trend and its change)");
    }
    grains_.unpack(c.grains.data());
    macro_ = c.macro;
    grains_.set_trend_step(c.trend_step);
    stats_ = c.stats;
    wall_before_ = c.stats.wall_seconds;
    cursor_ = {c.position, c.segment_start_stress, c.free_velocity_gradient};
    mixed_.path() = {c.free_velocity_gradient_trend, c.free_velocity_gradient_path,
                     c.free_strain_correction, c.position.increment > 0};
  }

 private:
  using FreePath = typename aggregate_parts::MixedControl<N>::FreePath;

  // What the run loops carry between increments besides the grains, macro_ and the mixed
  // control's path of the free components: kept here so that checkpoint() can see it from
  // RunControl::after_increment.
  struct Cursor {
    RunPosition position;
    Mat3 stress_start = Mat3::Zero();
    Eigen::VectorXd free;
  };

  double wall_seconds() const {
    return wall_before_ +
           std::chrono::duration<double>(std::chrono::steady_clock::now() - session_start_).count();
  }

  // The segment's stress ramp start and free components of L: from the checkpoint, or from the
  // state the segment starts in (the free components from the elastic response to the new
  // loading: elastic_free_start).
  // A stress component the previous segment prescribed (in the same measure) ramps from that
  // prescribed value, not from the stress reached (which differs by up to the tolerance): errors
  // do not carry over from segment to segment.
  void start_segment(const LoadSegment& seg, const std::vector<FreeComponent>& fc,
                     const LoadSegment* previous, const AggregateCheckpoint* resume) {
    if (resume != nullptr) {
      cursor_.stress_start = resume->segment_start_stress;
      cursor_.free = resume->free_velocity_gradient;
      mixed_.path() = {resume->free_velocity_gradient_trend, resume->free_velocity_gradient_path,
                       resume->free_strain_correction, resume->position.increment > 0};
      return;
    }
    cursor_.stress_start = mixed_.committed_stress(seg);
    if (previous != nullptr && previous->stress_measure == seg.stress_measure)
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          if (previous->free(i, j)) cursor_.stress_start(i, j) = previous->stress_target(i, j);
    cursor_.free = mixed_.elastic_free_start(seg, fc, cursor_.stress_start);
    // The loading has just changed: no trend carries over from the last segment, and its
    // targets start from the last one's, not from the stresses reached.
    mixed_.path().trend.setZero(static_cast<int>(fc.size()));
    mixed_.path().value = cursor_.free;
    mixed_.path().correction.setZero(static_cast<int>(fc.size()));
    mixed_.path().from_step = false;
  }

  // The prescribed stresses at `progress` (0 .. 1) through a segment: ramped linearly from the
  // segment's start to its targets.
  static Mat3 stress_target_at(const LoadSegment& seg, const Mat3& stress_start, double progress) {
    return stress_start + (seg.stress_target - stress_start) * progress;
  }

  void end_increment(int index, long done, double t, double next_step, const RunControl& control) {
    cursor_.position = {index, done, t, next_step};
    if (control.after_increment) control.after_increment(cursor_.position, macro_);
  }

  void run_segment(const LoadSegment& seg, const LoadSegment* previous, int index, double t_start,
                   const AggregateOptions& opt, const MacroObserver& observe,
                   const RunControl& control, const AggregateCheckpoint* resume) {
    if (opt.tolerance > 0.0 && opt.method == CrystalMethod::implicit) {
      run_segment_adaptive(seg, previous, index, t_start, opt, observe, control, resume);
      return;
    }
    const auto fc = free_components(seg);
    start_segment(seg, fc, previous, resume);
    const Mat3 stress_start = cursor_.stress_start;
    Eigen::VectorXd& u = cursor_.free;
    const auto dts = increment_lengths(seg.duration, seg.increments, seg.growth);
    const std::vector<double> none;
    const auto steps =
        integrators::fixed_steps(dts, seg.output_at_times ? seg.output_times : none, seg.duration);
    double t_local = resume != nullptr ? resume->position.segment_time : 0.0;
    const size_t first = resume != nullptr ? static_cast<size_t>(resume->position.increment) : 0;
    for (size_t k = first; k < steps.size(); ++k) {
      const integrators::FixedStep& step = steps[k];
      advance_increment(seg, fc, stress_start, t_local, step.length, u, opt);
      t_local = step.end;  // (the running sum of the increments where none is split)
      ++stats_.increments;
      macro_.segment = index;
      const bool last = k + 1 == steps.size();
      macro_.segment_time = last ? seg.duration : t_local;
      if (seg.output_at_times) {
        if (step.output_time) {
          macro_.time = t_start + step.end;  // exactly the output time (the sum of steps rounds)
          observe(macro_, grains_);
        }
      } else if (step.increment_end &&
                 (last || step.increment % static_cast<long>(seg.output_every) == 0)) {
        observe(macro_, grains_);
      }
      end_increment(index, static_cast<long>(k + 1), t_local, 0.0, control);
    }
  }

  // One segment with adaptive steps (AggregateOptions::tolerance): the first step is the
  // segment's first increment; then the step follows the error estimate, and a step that fails
  // (a grain or the mixed control does not converge) is halved like a cutback.
  void run_segment_adaptive(const LoadSegment& seg, const LoadSegment* previous, int index,
                            double t_start, const AggregateOptions& opt,
                            const MacroObserver& observe, const RunControl& control,
                            const AggregateCheckpoint* resume) {
    const auto fc = free_components(seg);
    start_segment(seg, fc, previous, resume);
    const Mat3 stress_start = cursor_.stress_start;
    Eigen::VectorXd& u = cursor_.free;
    if (resume != nullptr && resume->position.segment_time >= seg.duration) return;
    const int estimate_order = integrators::estimate_order(opt.order);
    const integrators::StepFactorLimits growth = integrators::after_accepted_limits(opt.order);
    integrators::AdaptiveSegment clock =
        resume != nullptr
            ? integrators::AdaptiveSegment(seg.duration, resume->position.next_step, opt.tolerance,
                                           estimate_order, resume->position.segment_time,
                                           resume->position.increment, growth)
            : integrators::AdaptiveSegment(
                  seg.duration, increment_lengths(seg.duration, seg.increments, seg.growth).front(),
                  opt.tolerance, estimate_order, growth);
    if (seg.output_at_times) clock.set_stops(seg.output_times);
    const bool extrapolated = opt.order >= 2;
    for (;;) {
      const double h = clock.step();
      Eigen::VectorXd u_try = u;
      std::string why;
      bool solved = false;
      ErrorEstimate error;
      if (extrapolated) {
        solved = extrapolated_step(seg, fc, stress_start, clock, u_try, opt, why);
        if (solved) error = extrapolation_.error(grains_);
      } else {
        const double progress = clock.last() ? 1.0 : std::min(1.0, clock.end_time() / seg.duration);
        solved = mixed_.try_step(seg, fc, stress_target_at(seg, stress_start, progress), h, u_try,
                                 opt, why);
        if (solved) {
          error = grains_.local_error(h);
          step_free_stress_error_ = mixed_.free_stress_error();
        }
      }
      if (!solved || !(error.value <= opt.tolerance)) {
        solved ? ++stats_.rejected : ++stats_.cutbacks;
        if (!solved) mixed_.forget_free_trend();
        if (solved) why = describe_error(error);
        const integrators::EstimateNoise noise{
            extrapolation_.resolution(grains_.phase(), opt, step_free_stress_error_, error.scale),
            true, !extrapolated};
        if (!clock.refuse(!solved, error.value, noise)) {
          if (clock.at_noise_floor())
            why = clock.noise_floor_message() + " (" + why + ")";
          else if (clock.estimate_does_not_fall())
            why = clock.not_falling_message() + " (" + why + ")";
          else if (clock.below_time_resolution())
            why = clock.time_resolution_message() + " (last attempt: " + why + ")";
          std::ostringstream msg;
          msg << "crystal step failed at time " << macro_.time << " after " << clock.refusals()
              << " refused attempts (dt = " << h << "): " << why;
          throw CrystalStepFailure(msg.str(), clock.named_tolerance());
        }
        continue;
      }
      const bool last = clock.last();
      // (An extrapolated step combines several solves: no one step's error to correct.)
      mixed_.record_free_step(u_try,
                              extrapolated ? aggregate_parts::MixedControl<N>::zero_correction(fc)
                                           : mixed_.step_correction(),
                              h);
      u = u_try;
      if (extrapolated) {
        std::swap(grains_.committed(), grains_.trial());
        grains_.forget_solve();
        macro_ = extrapolation_.macro();
      } else {
        commit(seg, fc, u, h);
      }
      const bool stop = clock.accept(error.value);
      macro_.segment_time = clock.time();
      ++stats_.increments;
      ++stats_.substeps;
      macro_.segment = index;
      if (seg.output_at_times) {
        if (stop) {
          macro_.time = t_start + clock.time();  // exactly the output time
          observe(macro_, grains_);
        }
      } else if (last || clock.accepted() % seg.output_every == 0) {
        observe(macro_, grains_);
      }
      end_increment(index, clock.accepted(), clock.time(), clock.planned_step(), control);
      if (last) return;
    }
  }

  // One step of the extrapolated integrator (AggregateOptions::order = k >= 2, see
  // integrators/extrapolation.hpp) over the clock's step: the aggregate is taken from its
  // committed state with k, .., 2, 1 backward Euler substeps (mixed control solved in each), and
  // the k results are combined into the grains' trial states and the extrapolation's macro state;
  // the committed states and macro_ are left as they were. False (and why) when a substep fails
  // or the combination is inadmissible.
  // The finest solution goes first, its grains starting from their rates at the step's start
  // (the combination's; the last chord continued over a step up to ten times longer is a worse
  // guess); each coarser substep then starts from the finest solution where it ends
  // (Extrapolation::coarse_substep_start), within the coarse solution's own difference from it.
  // `u`: the free components of L, from the last substep of the finest solution.
  bool extrapolated_step(const LoadSegment& seg, const std::vector<FreeComponent>& fc,
                         const Mat3& stress_start, const integrators::AdaptiveSegment& clock,
                         Eigen::VectorXd& u, const AggregateOptions& opt, std::string& why) {
    const int order = opt.order;
    extrapolation_.start() = grains_.committed();
    const MacroState macro_start = macro_;
    const Eigen::VectorXd u_start = u;
    // The finest solution starts from the step's free trend and carries its own on over its
    // substeps (the run loop records the accepted step's).
    const FreePath path_start = mixed_.path();
    auto restore_trend = [&] { mixed_.path() = path_start; };
    const double t0 = clock.time();
    const double t1 = clock.end_time();
    step_free_stress_error_ = 0.0;
    bool ok = true;
    for (int j = order; j >= 1 && ok; --j) {
      u = u_start;
      restore_trend();
      grains_.set_trend_step(0.0);  // (the history is another solution's: no trend change from it)
      double t = t0;
      for (int i = 1; i <= j && ok; ++i) {
        const double end = i == j ? t1 : t0 + (t1 - t0) * i / j;
        const double progress = i == j && clock.last() ? 1.0 : std::min(1.0, end / seg.duration);
        using ColdStart = typename aggregate_parts::GrainSweep<N>::ColdStart;
        if (j < order) {
          extrapolation_.coarse_substep_start(order, j, i, substep_rates_, u);
          mixed_.path().from_step = false;  // u is the start itself
          grains_.set_cold_starts(ColdStart::given, &substep_rates_);
        } else if (i == 1) {
          grains_.set_cold_starts(ColdStart::committed);
        }
        ok = mixed_.try_step(seg, fc, stress_target_at(seg, stress_start, progress), end - t, u,
                             opt, why);
        grains_.set_cold_starts(ColdStart::continued);
        if (ok) {
          step_free_stress_error_ = std::max(step_free_stress_error_, mixed_.free_stress_error());
          mixed_.record_free_step(u, mixed_.step_correction(), end - t);
          commit(seg, fc, u, end - t);
          if (j == order) extrapolation_.note_finest_substep(i, order, grains_.committed(), u);
        }
        t = end;
      }
      if (!ok) break;
      extrapolation_.solution(j) = grains_.committed();
      extrapolation_.solution_macro(j) = macro_;
      grains_.committed() = extrapolation_.start();
      macro_ = macro_start;
    }
    restore_trend();
    if (!ok) {
      grains_.committed() = extrapolation_.start();
      macro_ = macro_start;
      return false;
    }
    u = extrapolation_.finest_free(order);
    // The loading at the step's start: the last step's L, or the segment's own at its start.
    const std::optional<Mat3> start_l =
        t0 > 0.0 ? std::optional<Mat3>(macro_start.velocity_gradient) : std::nullopt;
    extrapolation_.combine(order, t1 - t0, admitted_flow_residual(opt.grain), grains_, start_l);
    return grains_.every_grain_ok(stats_, why);
  }

  std::string describe_error(const ErrorEstimate& e) const {
    std::ostringstream msg;
    msg << "local error estimate " << e.value << " above the tolerance (grain " << e.grain
        << ", slip system " << e.system << ")";
    return msg.str();
  }

  // Advances the aggregate by dt, halving on failure.
  void advance_increment(const LoadSegment& seg, const std::vector<FreeComponent>& fc,
                         const Mat3& stress_start, double t_local, double dt, Eigen::VectorXd& u,
                         const AggregateOptions& opt) {
    struct Piece {
      double dt;
      int depth;
    };
    std::vector<Piece> todo{{dt, 0}};
    while (!todo.empty()) {
      const Piece p = todo.back();
      todo.pop_back();
      const double progress = std::min(1.0, (t_local + p.dt) / seg.duration);
      std::string why;
      if (mixed_.try_step(seg, fc, stress_target_at(seg, stress_start, progress), p.dt, u, opt,
                          why)) {
        mixed_.record_free_step(u, mixed_.step_correction(), p.dt);
        commit(seg, fc, u, p.dt);
        t_local += p.dt;
        ++stats_.substeps;
        continue;
      }
      if (p.depth >= opt.max_cutbacks) {
        std::ostringstream msg;
        msg << "crystal step failed at time " << macro_.time << " after " << p.depth
            << " cutbacks (dt = " << p.dt << "): " << why;
        throw CrystalStepFailure(msg.str());
      }
      ++stats_.cutbacks;
      mixed_.forget_free_trend();
      todo.push_back({0.5 * p.dt, p.depth + 1});
      todo.push_back({0.5 * p.dt, p.depth + 1});
    }
  }

  void commit(const LoadSegment& seg, const std::vector<FreeComponent>& fc,
              const Eigen::VectorXd& u, double dt) {
    // The grains' states and slip-rate histories, and their average stress.
    const Vec6 trial_stress = grains_.commit(dt, stats_);
    const Mat3 l = mixed_.step_velocity_gradient(seg, fc, u, dt);
    // Deformation gradient by the Cayley (midpoint) map: exact for a pure rotation (and, under
    // dot_F, F_n + dot_F dt to round-off: step_velocity_gradient inverts the map).
    const Mat3 half = 0.5 * dt * l;
    macro_.deformation_gradient =
        (Mat3::Identity() - half)
            .lu()
            .solve((Mat3::Identity() + half) * macro_.deformation_gradient);
    if (grains_.phase().kinematics == Kinematics::small_strain) {
      macro_.strain += symmetric_part(l) * dt;
    } else {
      macro_.strain = log_strain(macro_.deformation_gradient);
    }
    macro_.stress = symmetric_from_mandel(trial_stress);
    macro_.velocity_gradient = l;
    macro_.time += dt;
  }

  aggregate_parts::GrainSweep<N> grains_;
  MacroState macro_;
  AggregateStats stats_;
  aggregate_parts::MixedControl<N> mixed_;
  aggregate_parts::Extrapolation<N> extrapolation_;
  Cursor cursor_;
  std::chrono::steady_clock::time_point session_start_ = std::chrono::steady_clock::now();
  // The largest free-stress error of the substeps of the extrapolated step last tried.
  double step_free_stress_error_ = 0.0;
  // Where the grains of an extrapolated step's substep start (extrapolated_step).
  std::vector<typename SlipTypes<N>::VecN> substep_rates_;
  double wall_before_ = 0.0;  // wall_seconds of the sessions before a restore
};

}  // namespace

AggregateOptions with_effective_grain_tolerance(AggregateOptions opt) {
  opt.grain.tolerance = integrators::residual_tolerance_for(
      opt.grain.tolerance, opt.grain_tolerance_follows_tolerance, opt.tolerance);
  return opt;
}

template <int N>
std::unique_ptr<Aggregate> make_taylor_aggregate(Phase<N> phase,
                                                 const std::vector<Mat3>& orientations,
                                                 const std::vector<double>& weights,
                                                 const typename SlipTypes<N>::VecN& initial_mu,
                                                 const GrainShare& share) {
  return std::make_unique<TaylorAggregate<N>>(std::move(phase), orientations, weights, initial_mu,
                                              share);
}

#define SUBSLIP_INSTANTIATE_AGGREGATE(N)                              \
  template std::unique_ptr<Aggregate> make_taylor_aggregate<N>(       \
      Phase<N>, const std::vector<Mat3>&, const std::vector<double>&, \
      const typename SlipTypes<N>::VecN&, const GrainShare&);

SUBSLIP_FOR_EACH_SLIP_COUNT(SUBSLIP_INSTANTIATE_AGGREGATE)

}  // namespace subslip::crystal
