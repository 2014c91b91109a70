#include "subslip/crystal/aggregate.hpp"

#include "grain_update.hpp"
#include "subslip/crystal/free_components.hpp"
#include "subslip/crystal/rotation.hpp"
#include "subslip/integrators/extrapolation.hpp"
#include "subslip/integrators/step_control.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <array>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <limits>
#include <numbers>
#include <sstream>
#include <stdexcept>

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

constexpr double kSqrt2 = std::numbers::sqrt2;
constexpr int kMandelIndex[3][3] = {{0, 5, 4}, {5, 1, 3}, {4, 3, 2}};

// L with the free components set to u.
Mat3 assemble_velocity_gradient(const Mat3& prescribed, const std::vector<FreeComponent>& fc,
                                const Eigen::VectorXd& u) {
  Mat3 l = prescribed;
  for (size_t k = 0; k < fc.size(); ++k) {
    l(fc[k].i, fc[k].j) = u(static_cast<int>(k));
    if (fc[k].symmetric_pair) l(fc[k].j, fc[k].i) = u(static_cast<int>(k));
  }
  return l;
}

Mat3 symmetric_part(const Mat3& l) {
  return 0.5 * (l + l.transpose());
}

// The free-stress Jacobian's singular value decomposition J = U S V^T and the residual r in its
// left singular basis, U^T r: both corrections below act on r one singular direction at a time.
struct SingularBasis {
  SingularBasis(const Eigen::MatrixXd& jac, const Eigen::VectorXd& r)
      : svd(jac, Eigen::ComputeFullU | Eigen::ComputeFullV),
        residual(svd.matrixU().transpose() * r) {}
  Eigen::JacobiSVD<Eigen::MatrixXd> svd;
  Eigen::VectorXd residual;
};

// The least change d of the free components of L whose linearised residual r + J d is at most
// `allowed` (2-norm): argmin |d| subject to |r + J d| <= allowed, the Tikhonov step
// d = -(J^T J + lambda I)^-1 J^T r with lambda where the bound is met (Morozov's discrepancy
// principle; lambda = 0, the Newton step, when it is met only there). Newton's own step solves
// the linearisation exactly, so where J is nearly singular (a grain aggregate at a yield vertex:
// a lateral mode that the stresses hardly resist, singular values 1e11 apart) it moves u far
// along that mode to remove a part of r far below the tolerance, out of the region where the
// linearisation holds. The least change removes the part of r that matters and leaves L where
// the stresses do not determine it.
Eigen::VectorXd least_change_step(const Eigen::MatrixXd& jac, const Eigen::VectorXd& r,
                                  double allowed) {
  const SingularBasis basis(jac, r);
  const Eigen::VectorXd& c = basis.residual;
  const Eigen::VectorXd& s = basis.svd.singularValues();
  // The residual left by the step of parameter lambda: components c_i lambda / (s_i^2 + lambda).
  const auto left = [&](double lambda) {
    double sum = 0.0;
    for (int i = 0; i < s.size(); ++i) {
      const double f = s(i) > 0.0 ? lambda / (s(i) * s(i) + lambda) : 1.0;
      sum += f * f * c(i) * c(i);
    }
    return std::sqrt(sum);
  };
  double lambda = 0.0;
  const double s_max = s.size() > 0 ? s(0) : 0.0;
  if (s_max > 0.0 && left(0.0) < allowed && allowed < c.norm()) {
    // left() rises monotonically from left(0) to |r|: bisection on log lambda. The bracket
    // s_max^2 e^-+80 holds every lambda that matters in double precision (above it left() is |r|
    // to 1e-35, below it the Newton step to the same), and 100 halvings of its 160 narrow it to
    // 1e-28, below the rounding of lambda: no iteration count decides the result.
    double lo = std::log(s_max * s_max) - 80.0, hi = std::log(s_max * s_max) + 80.0;
    for (int k = 0; k < 100; ++k) {
      const double mid = 0.5 * (lo + hi);
      (left(std::exp(mid)) < allowed ? lo : hi) = mid;
    }
    lambda = std::exp(lo);
  }
  Eigen::VectorXd along(s.size());
  for (int i = 0; i < s.size(); ++i)
    along(i) = s(i) > 0.0 ? -s(i) * c(i) / (s(i) * s(i) + lambda) : 0.0;
  return basis.svd.matrixV() * along;
}

// The change of the free components of L that removes the free-stress residual r to first
// order (Newton's change, -jac^-1 r), along the directions in which the stresses determine L:
// where a singular value s_i of the Jacobian is so small that a change as large as L itself
// (its largest entry) moves the stresses by no more than the tolerance, the tolerance leaves L
// along that direction undetermined to better than its own size, and it is not changed (at a
// yield vertex of a single crystal s_i / s_max reaches 1e-11; Newton's change along such a
// direction is what took the lateral flow to a far branch: docs/internals.md, "Mixed control").
Eigen::VectorXd error_correction(const Eigen::MatrixXd& jac, const Eigen::VectorXd& r,
                                 double tolerance, const Mat3& l) {
  const SingularBasis basis(jac, r);
  const Eigen::VectorXd& c = basis.residual;
  const Eigen::VectorXd& s = basis.svd.singularValues();
  const double size = l.cwiseAbs().maxCoeff();
  Eigen::VectorXd along = Eigen::VectorXd::Zero(s.size());
  for (int i = 0; i < s.size(); ++i)
    if (s(i) * size > tolerance) along(i) = -c(i) / s(i);
  return basis.svd.matrixV() * along;
}

// d(Mandel strain increment)/du_k per unit dt.
Vec6 strain_direction(const FreeComponent& c) {
  Vec6 e = Vec6::Zero();
  const int m = kMandelIndex[c.i][c.j];
  if (c.i == c.j) {
    e(m) = 1.0;
  } else {
    e(m) = c.symmetric_pair ? kSqrt2 : kSqrt2 / 2.0;  // D_ij = u or u/2, Mandel weight sqrt2
  }
  return e;
}

// Tensor component sigma_ij of a Mandel vector.
double component(const Vec6& v, int i, int j) {
  const int m = kMandelIndex[i][j];
  return i == j ? v(m) : v(m) / kSqrt2;
}

// The free components' entries of a stress (or of its change) in Mandel form, in fc's order: a
// column of the free stresses' Jacobian.
Eigen::VectorXd free_entries(const Vec6& v, const std::vector<FreeComponent>& fc) {
  Eigen::VectorXd out(static_cast<int>(fc.size()));
  for (size_t a = 0; a < fc.size(); ++a) out(static_cast<int>(a)) = component(v, fc[a].i, fc[a].j);
  return out;
}

Mat3 log_strain(const Mat3& f) {
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(f * f.transpose());
  const Eigen::Vector3d log_values = eig.eigenvalues().array().log() * 0.5;
  return eig.eigenvectors() * log_values.asDiagonal() * eig.eigenvectors().transpose();
}

template <int N>
class TaylorAggregate final : public Aggregate, private GrainFields {
 public:
  using VecN = typename SlipTypes<N>::VecN;

  TaylorAggregate(Phase<N> phase, const std::vector<Mat3>& orientations,
                  const std::vector<double>& weights, const VecN& initial_mu,
                  const GrainShare& share)
      : phase_(std::move(phase)),
        team_(*share.team),
        offset_(share.offset),
        total_(share.total > 0 ? share.total : orientations.size()) {
    const size_t n = orientations.size();
    committed_.resize(n);
    trial_.resize(n);
    tangents_.resize(n);
    reports_.resize(n);
    warm_.resize(n);
    const RateHistory<N> none{VecN::Zero(phase_.slip_count), VecN::Zero(phase_.slip_count)};
    history_.assign(n, none);
    solved_.history.assign(n, none);
    extrapolation_errors_.resize(n);
    weights_ = weights.empty() ? std::vector<double>(n, 1.0) : weights;
    std::array<parallel::ExactSum, 1> total;
    for (double w : weights_) total[0].add(w);
    team_.sum(total);
    const double sum = total[0].value();
    for (double& w : weights_) w /= sum;
    for (size_t g = 0; g < n; ++g)
      committed_[g].reset(phase_.slip_count, orientations[g], initial_mu);
  }

  int grain_count() const override { return static_cast<int>(committed_.size()); }
  int slip_count() const override { return phase_.slip_count; }
  std::size_t state_bytes_per_grain() const override {
    return sizeof(double) * static_cast<size_t>(state_values_per_grain(phase_.slip_count));
  }
  std::size_t memory_bytes_per_grain() const override {
    return 2 * sizeof(GrainState<N>) + sizeof(Tangent) + sizeof(SlipTangent<N>) + 3 * sizeof(VecN) +
           sizeof(GrainStepReport) + sizeof(double);
  }

  AggregateStats run(const std::vector<LoadSegment>& segments, const AggregateOptions& opt,
                     const MacroObserver& observe, const RunControl& control) override {
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
      observe(macro_, *this);
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
    c.free_velocity_gradient_trend = cursor_.path.trend;
    c.free_velocity_gradient_path = cursor_.path.value;
    c.free_strain_correction = cursor_.path.correction;
    c.trend_step = trend_step_;
    c.stats = stats_;
    c.stats.wall_seconds = wall_seconds();
    const int n = phase_.slip_count;
    c.values_per_grain = checkpoint_values_per_grain(n);
    c.grains.resize(committed_.size() * static_cast<size_t>(c.values_per_grain));
    double* out = c.grains.data();
    for (size_t k = 0; k < committed_.size(); ++k) {
      const auto& g = committed_[k];
      out = std::copy(g.stress.data(), g.stress.data() + 6, out);
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) *out++ = g.orientation(i, j);
      for (const auto* v : {&g.mu, &g.r_s, &g.slip, &g.rate, &history_[k].trend,
                            &history_[k].trend_change})
        out = std::copy(v->data(), v->data() + n, out);
    }
    return c;
  }

  void restore(const AggregateCheckpoint& c) override {
    const int n = phase_.slip_count;
    if (c.values_per_grain != checkpoint_values_per_grain(n) ||
        c.grains.size() != committed_.size() * static_cast<size_t>(c.values_per_grain)) {
      throw std::invalid_argument(
          "checkpoint of a different aggregate (grains or slip systems) or of an older subslip "
          "(no slip-rate trend and its change)");
    }
    const double* in = c.grains.data();
    for (size_t k = 0; k < committed_.size(); ++k) {
      auto& g = committed_[k];
      std::copy(in, in + 6, g.stress.data());
      in += 6;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) g.orientation(i, j) = *in++;
      for (auto* v : {&g.mu, &g.r_s, &g.slip, &g.rate, &history_[k].trend,
                      &history_[k].trend_change}) {
        std::copy(in, in + n, v->data());
        in += n;
      }
    }
    macro_ = c.macro;
    trend_step_ = c.trend_step;
    stats_ = c.stats;
    wall_before_ = c.stats.wall_seconds;
    cursor_ = {c.position,
               c.segment_start_stress,
               c.free_velocity_gradient,
               {c.free_velocity_gradient_trend, c.free_velocity_gradient_path,
                c.free_strain_correction, c.position.increment > 0}};
  }

 private:
  // The path of the free components of L that a step's mixed-control iteration starts from
  // (MixedPredictor::trend, continued_free). A step accepts free stresses within the tolerance,
  // and the state it commits carries that error into the next step, whose targets are absolute:
  // the L that meets them differs from the path by the error's first-order correction. So the
  // trend is taken along the path (each step's L corrected by its error and by the error it
  // inherited: path = u + (correction - previous correction) / dt), not along the accepted L,
  // and a step starts from the path continued plus the correction of the error it inherits.
  // Along the accepted L the errors were continued too: with a tolerance the first solve meets,
  // they grew as the steps went (a third-order recursion), and the free L oscillated by 2 % of
  // its value (docs/internals.md, "Mixed control").
  struct FreePath {
    Eigen::VectorXd trend;       // the path's change per unit time over the last step (1/s^2)
    Eigen::VectorXd value;       // the path at the last committed step (1/s)
    Eigen::VectorXd correction;  // strain that removes the last step's free-stress error
    bool from_step = false;      // whether value is a committed step's (of this segment)
  };

  // What the run loops carry between increments besides the grains and macro_: kept here so that
  // checkpoint() can see it from RunControl::after_increment.
  struct Cursor {
    RunPosition position;
    Mat3 stress_start = Mat3::Zero();
    Eigen::VectorXd free;
    FreePath path;
  };

  double wall_seconds() const {
    return wall_before_ +
           std::chrono::duration<double>(std::chrono::steady_clock::now() - session_start_).count();
  }

  // The segment's stress ramp start and free components of L: from the checkpoint, or from the
  // state the segment starts in (the free components from the elastic response to the new
  // loading: elastic_free_start).
  // A stress component the previous segment prescribed ramps from that prescribed value, not
  // from the stress reached (which differs by up to the tolerance): errors do not carry over
  // from segment to segment.
  void start_segment(const LoadSegment& seg, const std::vector<FreeComponent>& fc,
                     const LoadSegment* previous, const AggregateCheckpoint* resume) {
    if (resume != nullptr) {
      cursor_.stress_start = resume->segment_start_stress;
      cursor_.free = resume->free_velocity_gradient;
      cursor_.path = {resume->free_velocity_gradient_trend, resume->free_velocity_gradient_path,
                      resume->free_strain_correction, resume->position.increment > 0};
      return;
    }
    cursor_.stress_start = macro_.stress;
    if (previous != nullptr)
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          if (previous->free(i, j)) cursor_.stress_start(i, j) = previous->stress_target(i, j);
    cursor_.free = elastic_free_start(seg, fc, cursor_.stress_start);
    // The loading has just changed: no trend carries over from the last segment, and its
    // targets start from the last one's, not from the stresses reached.
    cursor_.path.trend.setZero(static_cast<int>(fc.size()));
    cursor_.path.value = cursor_.free;
    cursor_.path.correction.setZero(static_cast<int>(fc.size()));
    cursor_.path.from_step = false;
  }

  // Where a segment's mixed-control iteration starts: the free components of L for which the
  // grains' averaged elastic stiffness, in the sample frame, takes the free stresses from the
  // segment's start along their ramp with the new prescribed components. The loading has just
  // changed, and a change of loading begins elastically (an unloading, a reversal, a hold), so
  // this is the start next to the solution the path continues along; the last segment's free
  // components are not (a hold after loading started from the loading's lateral flow lands,
  // at a yield vertex, on a far branch of the step's equations with a lateral flow of 1e-2 /s
  // at constant stress: docs/internals.md, "Mixed control").
  Eigen::VectorXd elastic_free_start(const LoadSegment& seg, const std::vector<FreeComponent>& fc,
                                     const Mat3& stress_start) const {
    const int k = static_cast<int>(fc.size());
    std::array<parallel::ExactSum, 36> sum;
    for (size_t g = 0; g < committed_.size(); ++g) {
      const Mat6 c =
          weights_[g] * stiffness_in_sample_frame(phase_.stiffness, committed_[g].orientation);
      for (int i = 0; i < 36; ++i) sum[static_cast<size_t>(i)].add(c.data()[i]);
    }
    team_.sum(sum);
    Mat6 stiffness;
    for (int i = 0; i < 36; ++i) stiffness.data()[i] = sum[static_cast<size_t>(i)].value();
    const Eigen::VectorXd none = Eigen::VectorXd::Zero(k);
    const Vec6 prescribed_rate =
        stiffness * mandel_from_symmetric(symmetric_part(
                        assemble_velocity_gradient(seg.velocity_gradient, fc, none)));
    Eigen::MatrixXd jac(k, k);
    Eigen::VectorXd rhs(k);
    for (int a = 0; a < k; ++a) {
      const FreeComponent& c = fc[static_cast<size_t>(a)];
      const double ramp =
          seg.duration > 0.0 ? (seg.stress_target(c.i, c.j) - stress_start(c.i, c.j)) / seg.duration
                             : 0.0;
      rhs(a) = ramp - component(prescribed_rate, c.i, c.j);
    }
    for (int b = 0; b < k; ++b)
      jac.col(b) = free_entries(stiffness * strain_direction(fc[static_cast<size_t>(b)]), fc);
    const Eigen::VectorXd u = jac.partialPivLu().solve(rhs);
    return u.allFinite() ? u : none;
  }

  // A step failed: the free components do not change smoothly over it (a change of the grains'
  // active sets, or an L the stresses hardly determine, as in nearly ideal plasticity, which
  // changes by jumps), so there is no trend to continue until two steps have committed again.
  void forget_free_trend() {
    cursor_.path.trend.setZero();
    cursor_.path.correction.setZero();
    cursor_.path.from_step = false;
  }

  // Records a committed step of dt that took the free components to `after`, `correction` (a
  // strain) from removing its free-stress error to first order: the path's trend is its change
  // per unit time where the last value was a committed step's too (FreePath).
  void record_free_step(const Eigen::VectorXd& after, const Eigen::VectorXd& correction,
                        double dt) {
    FreePath& p = cursor_.path;
    const Eigen::VectorXd value = after + (correction - p.correction) / dt;
    if (p.from_step)
      p.trend = (value - p.value) / dt;
    else
      p.trend.setZero(after.size());
    p.value = value;
    p.correction = correction;
    p.from_step = true;
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
    const auto fc = free_components(seg.free);
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
          observe(macro_, *this);
        }
      } else if (step.increment_end &&
                 (last || step.increment % static_cast<long>(seg.output_every) == 0)) {
        observe(macro_, *this);
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
    const auto fc = free_components(seg.free);
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
        if (solved) error = extrapolation_error();
      } else {
        const double progress = clock.last() ? 1.0 : std::min(1.0, clock.end_time() / seg.duration);
        solved =
            try_step(seg, fc, stress_target_at(seg, stress_start, progress), h, u_try, opt, why);
        if (solved) error = local_error(h);
      }
      if (!solved || !(error.value <= opt.tolerance)) {
        solved ? ++stats_.rejected : ++stats_.cutbacks;
        if (!solved) forget_free_trend();
        if (solved) why = describe_error(error);
        if (!clock.refuse(!solved, error.value,
                          extrapolated ? extrapolation_resolution(fc, opt) : 0.0)) {
          if (clock.at_noise_floor())
            why = clock.noise_floor_message() + " (" + why + ")";
          else if (clock.below_time_resolution())
            why = clock.time_resolution_message() + " (last attempt: " + why + ")";
          std::ostringstream msg;
          msg << "crystal step failed at time " << macro_.time << " after " << clock.refusals()
              << " refused attempts (dt = " << h << "): " << why;
          throw CrystalStepFailure(msg.str());
        }
        continue;
      }
      const bool last = clock.last();
      // (An extrapolated step combines several solves: no one step's error to correct.)
      record_free_step(u_try, extrapolated ? zero_correction(fc) : step_correction_, h);
      u = u_try;
      if (extrapolated) {
        std::swap(committed_, trial_);
        solved_.valid = false;
        macro_ = extrapolated_macro_;
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
          observe(macro_, *this);
        }
      } else if (last || clock.accepted() % seg.output_every == 0) {
        observe(macro_, *this);
      }
      end_increment(index, clock.accepted(), clock.time(), clock.planned_step(), control);
      if (last) return;
    }
  }

  struct ErrorEstimate {
    double value = 0.0;
    size_t grain = 0;
    int system = -1;
  };

  // The local error estimate of the step just solved (trial_ from committed_): per grain and
  // slip system, dt/2 |A (gdot_end - gdot_start)| over the CRSS mu tau0, the largest of all.
  // The start rates are the committed end rates of the previous (backward Euler) step. A NaN
  // wins, so that a broken step is never accepted: the first NaN, else the first of the
  // largest, in grain order, per rank and then over the ranks in rank order (the same estimate
  // at any rank count).
  ErrorEstimate local_error(double dt) const {
    return worst_error([&](size_t g) {
      const VecN rate_change = trial_[g].rate - committed_[g].rate;
      const VecN crss = committed_[g].mu.cwiseProduct(phase_.tau0);
      return VecN((0.5 * dt) * (phase_.interaction * rate_change).cwiseAbs().cwiseQuotient(crss));
    });
  }

  // The largest of every grain's and system's error (error_of(g): per system), the same at any
  // thread or rank count: a NaN wins, then the first of the largest in grain order.
  template <class PerGrain>
  ErrorEstimate worst_error(PerGrain&& error_of) const {
    ErrorEstimate worst;
    const auto keep_worse = [&worst](double value, size_t grain, int system) {
      if (!std::isnan(worst.value) && (std::isnan(value) || value > worst.value))
        worst = {value, grain, system};
    };
    for (size_t g = 0; g < committed_.size(); ++g) {
      const VecN error = error_of(g);
      for (int a = 0; a < phase_.slip_count; ++a) keep_worse(error(a), offset_ + g, a);
    }
    if (team_.size() == 1) return worst;
    const double mine[3] = {worst.value, static_cast<double>(worst.grain),
                            static_cast<double>(worst.system)};
    const std::vector<double> all = team_.all_gather(mine);
    worst = {};
    for (size_t r = 0; r < all.size(); r += 3)
      keep_worse(all[r], static_cast<size_t>(all[r + 1]), static_cast<int>(all[r + 2]));
    return worst;
  }

  // One step of the extrapolated integrator (AggregateOptions::order = k >= 2, see
  // integrators/extrapolation.hpp) over the clock's step: the aggregate is taken from its
  // committed state with 1, 2, .., k backward Euler substeps (mixed control solved in each), and
  // the k results are combined into trial_ and extrapolated_macro_; committed_ and macro_ are
  // left as they were. False (and why) when a substep fails or the combination is inadmissible.
  // `u`: the free components of L, from the last substep of the finest solution.
  bool extrapolated_step(const LoadSegment& seg, const std::vector<FreeComponent>& fc,
                         const Mat3& stress_start, const integrators::AdaptiveSegment& clock,
                         Eigen::VectorXd& u, const AggregateOptions& opt, std::string& why) {
    const int order = opt.order;
    step_start_ = committed_;
    const MacroState macro_start = macro_;
    const Eigen::VectorXd u_start = u;
    // Every solution starts from the step's free trend; its substeps carry their own on (the
    // run loop records the accepted step's).
    const FreePath path_start = cursor_.path;
    auto restore_trend = [&] { cursor_.path = path_start; };
    const double t0 = clock.time();
    const double t1 = clock.end_time();
    bool ok = true;
    for (int j = 1; j <= order && ok; ++j) {
      u = u_start;
      restore_trend();
      // Each solution starts from the step's start, not where the last one's substeps ended:
      // its grains continue their rates along the last chord only (continued_rates).
      trend_step_ = 0.0;
      double t = t0;
      for (int i = 1; i <= j && ok; ++i) {
        const double end = i == j ? t1 : t0 + (t1 - t0) * i / j;
        const double progress = i == j && clock.last() ? 1.0 : std::min(1.0, end / seg.duration);
        ok = try_step(seg, fc, stress_target_at(seg, stress_start, progress), end - t, u, opt, why);
        if (ok) {
          record_free_step(u, step_correction_, end - t);
          commit(seg, fc, u, end - t);
        }
        t = end;
      }
      if (!ok) break;
      solutions_[static_cast<size_t>(j - 1)] = committed_;
      solution_macros_[static_cast<size_t>(j - 1)] = macro_;
      committed_ = step_start_;
      macro_ = macro_start;
    }
    restore_trend();
    if (!ok) {
      committed_ = step_start_;
      macro_ = macro_start;
      return false;
    }
    combine_solutions(order);
    return every_grain_ok(why);
  }

  // trial_ and extrapolated_macro_ from solutions_ (extrapolated_step); the per-grain error
  // estimates in extrapolation_errors_, the restoring reports in reports_.
  void combine_solutions(int order) {
    solved_.valid = false;  // trial_ is no longer the last solve's
    const auto k = static_cast<size_t>(order);
    const long n = static_cast<long>(committed_.size());
#pragma omp parallel for schedule(static) if (n > 1)
    for (long g = 0; g < n; ++g) {
      const auto gi = static_cast<size_t>(g);
      std::array<Vec6, integrators::kMaxExtrapolationOrder> stress;
      std::array<VecN, integrators::kMaxExtrapolationOrder> mu, r_s, slip, rate;
      std::array<Vec3, integrators::kMaxExtrapolationOrder> turn;
      const GrainState<N>& finest = solutions_[k - 1][gi];
      for (size_t j = 0; j < k; ++j) {
        const GrainState<N>& s = solutions_[j][gi];
        stress[j] = s.stress, mu[j] = s.mu, r_s[j] = s.r_s, slip[j] = s.slip, rate[j] = s.rate;
        // Orientations are combined as rotation vectors relative to the finest one.
        turn[j] = rotation_log(s.orientation * finest.orientation.transpose());
      }
      for (size_t j = k; j < turn.size(); ++j) {  // unused rows, kept finite
        stress[j] = stress[0], mu[j] = mu[0], r_s[j] = r_s[0], slip[j] = slip[0];
        rate[j] = rate[0], turn[j] = turn[0];
      }
      using integrators::extrapolate_implicit_euler;
      const auto e_stress = extrapolate_implicit_euler(stress, order);
      const auto e_mu = extrapolate_implicit_euler(mu, order);
      const auto e_rs = extrapolate_implicit_euler(r_s, order);
      GrainState<N>& out = trial_[gi];
      out.stress = e_stress.best;
      out.mu = e_mu.best;
      out.r_s = e_rs.best;
      out.slip = extrapolate_implicit_euler(slip, order).best;
      out.rate = extrapolate_implicit_euler(rate, order).best;
      out.orientation =
          rotation_exp(extrapolate_implicit_euler(turn, order).best) * finest.orientation;
      reports_[gi] = restore_extrapolated_state(phase_, finest, out);
      extrapolation_errors_[gi] = system_errors(e_stress.best - e_stress.second, out.mu);
      if (order >= 4) {  // the guard against a cancelling last column (guarded_estimate)
        const auto earlier = integrators::earlier_column_estimates(stress);
        const VecN previous = system_errors(earlier[0], out.mu);
        const VecN before = system_errors(earlier[1], out.mu);
        VecN& error = extrapolation_errors_[gi];
        for (int a = 0; a < phase_.slip_count; ++a)
          error(a) = integrators::guarded_estimate(error(a), previous(a), before(a));
      }
      if (switches_phase(step_start_[gi], gi, order)) {
        // A system switched between elastic and slipping inside the step: the solution has a
        // kink there and no error expansion in powers of the step, so the estimate is backward
        // Euler's own (one substep against two): such a step is shortened until that meets the
        // tolerance.
        const GrainState<N>& one = solutions_[0][gi];
        const GrainState<N>& two = solutions_[1][gi];
        extrapolation_errors_[gi] =
            extrapolation_errors_[gi].cwiseMax(system_errors(one.stress - two.stress, out.mu));
      }
    }
    combine_macro(order);
  }

  // An error estimate per system from a difference of the stress: the resolved shear stress
  // over the CRSS, on what the grain's state determines. mu and r_s of each system are not in
  // it: they follow the system's own slip, and where several systems can carry the same strain
  // (a nearly rate-independent law at a vertex) the split of slip among them, and with it their
  // mu and r_s, is not determined to the precision a tolerance asks for. Where the split is
  // determined, a CRSS error of a slipping system shows in its resolved shear (it slips at
  // r ~ 1), and an idle system's CRSS hardens with the slipping systems' slip at their rates.
  VecN system_errors(const Vec6& stress, const VecN& mu_now) const {
    const VecN crss = mu_now.cwiseProduct(phase_.tau0);
    return (phase_.schmid.transpose() * stress).cwiseAbs().cwiseQuotient(crss);
  }

  // Whether a system of grain g switched between elastic and slipping in the step from `start`:
  // it slips (a non-zero rate) at the end of one of the `order` solutions and not at the start,
  // or the other way round.
  bool switches_phase(const GrainState<N>& start, size_t g, int order) const {
    for (int j = 0; j < order; ++j) {
      const VecN& rate = solutions_[static_cast<size_t>(j)][g].rate;
      for (int a = 0; a < phase_.slip_count; ++a)
        if ((rate(a) != 0.0) != (start.rate(a) != 0.0)) return true;
    }
    return false;
  }

  // The macroscopic state of the combination: F and L extrapolated like the grains (with mixed
  // control they differ between the solutions), the strain from F, the stress averaged anew.
  void combine_macro(int order) {
    const auto k = static_cast<size_t>(order);
    std::array<Mat3, integrators::kMaxExtrapolationOrder> f, l, strain;
    for (size_t j = 0; j < f.size(); ++j) {  // (unused rows: the finest, kept finite)
      const MacroState& m = solution_macros_[std::min(j, k - 1)];
      f[j] = m.deformation_gradient, l[j] = m.velocity_gradient, strain[j] = m.strain;
    }
    extrapolated_macro_ = solution_macros_[0];  // time and segment: the same in every solution
    extrapolated_macro_.deformation_gradient =
        integrators::extrapolate_implicit_euler(f, order).best;
    extrapolated_macro_.velocity_gradient = integrators::extrapolate_implicit_euler(l, order).best;
    extrapolated_macro_.strain = phase_.kinematics == Kinematics::small_strain
                                     ? integrators::extrapolate_implicit_euler(strain, order).best
                                     : log_strain(extrapolated_macro_.deformation_gradient);
    extrapolated_macro_.stress = symmetric_from_mandel(average_stress(trial_));
  }

  // What the extrapolated estimate resolves (as for the contact point): the grains' states are
  // exact to a few ulps of r (at most r_hat), to their flow-rule tolerance and, under mixed
  // control, to the free stresses' tolerance over the smallest CRSS (mu no lower than the
  // smaller of mu_s and mu_k: the law moves it between them); the estimate's weights amplify
  // that (estimate_noise_gain).
  double extrapolation_resolution(const std::vector<FreeComponent>& fc,
                                  const AggregateOptions& opt) const {
    constexpr double kEps = std::numeric_limits<double>::epsilon();
    double largest_ratio = 1.0, smallest_mu = std::numeric_limits<double>::infinity();
    for (const auto& law : phase_.laws) {
      const auto& p = law.parameters();
      largest_ratio = std::max(largest_ratio, p.overstress.r_hat);
      smallest_mu = std::min({smallest_mu, p.friction.mu_s, p.friction.mu_k});
    }
    double mixed = 0.0;
    if (!fc.empty()) {
      const double scale = std::max(macro_.stress.cwiseAbs().maxCoeff(), phase_.tau0.maxCoeff());
      mixed = opt.stress_tolerance * scale / (smallest_mu * phase_.tau0.minCoeff());
    }
    return integrators::estimate_noise_gain(opt.order) *
           (opt.grain.tolerance + mixed + 4.0 * kEps * (1.0 + largest_ratio));
  }

  ErrorEstimate extrapolation_error() const {
    return worst_error([&](size_t g) { return extrapolation_errors_[g]; });
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
      if (try_step(seg, fc, stress_target_at(seg, stress_start, progress), p.dt, u, opt, why)) {
        record_free_step(u, step_correction_, p.dt);
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
      forget_free_trend();
      todo.push_back({0.5 * p.dt, p.depth + 1});
      todo.push_back({0.5 * p.dt, p.depth + 1});
    }
  }

  // Runs every grain from the committed state with L; false (and why) when any grain fails.
  // Cold (a step's first solve): each grain's Newton iteration starts from its committed slip
  // rates continued over the step along the parabola through the rates of the last three
  // committed states (continued_rates; a system whose continued rate would change sign starts
  // from its committed rate): on a loading path the rates change smoothly and the continued
  // rates start the iteration at a third-order distance from the solution (on the default
  // scene with L prescribed, 1.18 Newton iterations per solve; 1.38 along the chord of the
  // last step, 2.1 from the committed rates). Should that fail, again from the committed rates.
  // `warm`: each grain's Newton iteration starts from the slip rates of its last successful
  // solve (warm_: in a mixed-control iteration, at a nearby L of the same step), carried to L
  // to first order by its slip tangent where one was computed in this step (the Newton
  // iteration then starts at a second-order distance from the solution), and, should that
  // fail, again from the committed rates; on success warm_ holds the new rates.
  bool solve_grains(const Mat3& l, double dt, bool want_tangent, const AggregateOptions& opt,
                    std::string& why, bool warm = false) {
    const long n = static_cast<long>(committed_.size());
    const bool implicit = opt.method == CrystalMethod::implicit;
    const bool slip_tangent = want_tangent && implicit;
    if (slip_tangent && slip_tangents_.size() != committed_.size())
      slip_tangents_.resize(committed_.size());
    const bool carried = warm && slip_tangents_current_;
    // The tangents are taken along the free components' strain directions (tangent_directions_);
    // the change of L since the last solve lies in their span, with these coefficients (the
    // directions have disjoint Mandel components).
    const Vec6 strain_rate_change = mandel_from_symmetric(symmetric_part(l - warm_l_));
    const Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 6, 1> direction_change =
        (tangent_directions_.transpose() * strain_rate_change)
            .cwiseQuotient(tangent_directions_.colwise().squaredNorm().transpose());
    GrainStepOptions grain_options = opt.grain;
    grain_options.tangent_directions = tangent_directions_;
    solved_.valid = false;
    std::array<parallel::ExactSum, 6> stress_sum;
#pragma omp parallel if (n > 1)
    {
      std::array<parallel::ExactSum, 6> part;
#pragma omp for schedule(static) nowait
      for (long g = 0; g < n; ++g) {
        const auto gi = static_cast<size_t>(g);
        Tangent* t = want_tangent ? &tangents_[gi] : nullptr;
        if (implicit) {
          solve_implicit_grain(gi, l, dt, grain_options, t, warm, carried, slip_tangent,
                               direction_change);
        } else {
          reports_[gi] = explicit_grain_step(phase_, committed_[gi], l, dt, trial_[gi], t);
          if (t) *t = (*t * tangent_directions_).eval();
        }
        if (reports_[gi].ok) note_solved_grain(gi, dt, part);
      }
#pragma omp critical(subslip_solved_stress)
      for (size_t i = 0; i < 6; ++i) stress_sum[i].merge(part[i]);
    }
    team_.sum(stress_sum);
    stats_.grain_solves += static_cast<long>(total_);
    const bool ok = every_grain_ok(why);
    if (ok) {
      for (int i = 0; i < 6; ++i)
        solved_.average_stress(i) = stress_sum[static_cast<size_t>(i)].value();
      solved_.dt = dt;
      solved_.trend_step = trend_step_;
      solved_.valid = true;
    }
    // The slip tangents belong to this step (its dt and start state): a cold solve starts a
    // step, and a failed solve leaves warm_ at mixed Ls.
    slip_tangents_current_ = ok && (slip_tangent || (warm && slip_tangents_current_));
    warm_l_ = l;
    return ok;
  }

  // Grain gi's implicit step (solve_grains): from its own start (continued rates, or the warm
  // rates carried by its slip tangent), then, should that fail, from its committed rates.
  void solve_implicit_grain(
      size_t gi, const Mat3& l, double dt, const GrainStepOptions& grain_options, Tangent* t,
      bool warm, bool carried, bool slip_tangent,
      const Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 6, 1>& direction_change) {
    GrainStepReport& rep = reports_[gi];
    SlipTangent<N>* st = slip_tangent ? &slip_tangents_[gi] : nullptr;
    if (!warm) {
      rep = cold_implicit_step(phase_, committed_[gi], history_[gi], trend_step_, l, dt,
                               grain_options, trial_[gi], t, st);
    } else if (carried) {
      VecN start = warm_[gi];
      start.noalias() += slip_tangents_[gi] * direction_change;
      rep = implicit_step_from(phase_, committed_[gi], l, dt, grain_options, start, true,
                               trial_[gi], t, st);
    } else {
      rep = implicit_step_from(phase_, committed_[gi], l, dt, grain_options, warm_[gi], true,
                               trial_[gi], t, st);
    }
    if (rep.ok) warm_[gi] = trial_[gi].rate;
  }

  // What commit() needs of grain gi's solved step, taken while its states are in cache: its
  // slip-rate trend and the trend's change (as commit() would compute them, for a step of dt
  // after one of trend_step_), and its weighted stress added to the thread's part of the
  // average (exact sums: the same bits in any order).
  void note_solved_grain(size_t gi, double dt, std::array<parallel::ExactSum, 6>& part) {
    history_after_step(committed_[gi], trial_[gi], history_[gi], trend_step_, dt,
                       solved_.history[gi]);
    const Vec6 s = weights_[gi] * trial_[gi].sample_stress();
    for (int i = 0; i < 6; ++i) part[static_cast<size_t>(i)].add(s(i));
  }

  // The average stress of trial_: the last solve's (solve_grains) where trial_ is still its.
  Vec6 trial_average_stress() const {
    return solved_.valid ? solved_.average_stress : average_stress(trial_);
  }

  // Whether every grain's report (reports_) is ok; else why, for the first failing grain. The
  // reports' Newton iterations are added to the statistics.
  bool every_grain_ok(std::string& why) {
    // Serial, then over the ranks: the iterations, and the first failing grain (by index).
    constexpr auto kNone = std::numeric_limits<std::int64_t>::max();
    std::array<std::int64_t, 1> iterations{0}, failed{kNone};
    for (size_t g = 0; g < committed_.size(); ++g) {
      iterations[0] += reports_[g].iterations;
      if (!reports_[g].ok && failed[0] == kNone) failed[0] = static_cast<std::int64_t>(g + offset_);
    }
    team_.sum(iterations);
    team_.min(failed);
    stats_.newton_iterations += iterations[0];
    if (failed[0] == kNone) return true;
    // The rank holding the failed grain says why.
    const auto g = static_cast<size_t>(failed[0]);
    const bool mine = g >= offset_ && g < offset_ + committed_.size();
    std::array<std::int64_t, 1> owner{mine ? team_.rank() : team_.size()};
    team_.min(owner);
    if (mine) why = describe_failure(g - offset_, reports_[g - offset_]);
    team_.broadcast(why, static_cast<int>(owner[0]));
    return false;
  }

  std::string describe_failure(size_t g, const GrainStepReport& rep) const {
    std::ostringstream msg;
    const auto& s = committed_[g];
    msg << "grain " << offset_ + g << ", slip system " << rep.system << ": " << rep.why
        << " (after " << rep.iterations << " iterations)";
    if (rep.system >= 0) {
      const VecN r = loading_ratio(phase_, s);
      // Full precision: near the limits (r_s -> 1, r -> r_hat) six digits would read "1".
      msg << std::setprecision(17) << "; start state: mu = " << s.mu(rep.system)
          << ", r = " << r(rep.system) << ", r_s = " << s.r_s(rep.system)
          << ", slip = " << s.slip(rep.system);
      if (phase_.pressure_sensitive) describe_plane_pressure(s, rep.system, msg);
    }
    return msg.str();
  }

  // With the pressure-sensitive reading a step can stall where a plane is about to open under
  // tension (docs/grain_step.md, "The pressure-sensitive reading under tension"): the failure
  // names the normal tractions f_n = tau0 - M_a : sigma at the step's start, the failing
  // system's and the smallest of the grain's, in the scene's stress unit.
  void describe_plane_pressure(const GrainState<N>& s, int system, std::ostringstream& msg) const {
    const VecN fn = normal_traction(phase_, s);
    int lowest = 0;
    const double smallest = fn.minCoeff(&lowest);
    msg << ", f_n = " << fn(system) << "; smallest plane normal traction f_n = " << smallest
        << " (system " << lowest << "; the plane opens at f_n <= 0)";
  }

  // The volume average of the grains' sample-frame stress, over the team (exact sums). The
  // threads sum their grains apart and merge: exact, so the same bits at any thread count.
  Vec6 average_stress(const std::vector<GrainState<N>>& grains) const {
    std::array<parallel::ExactSum, 6> sum;
    const long n = static_cast<long>(grains.size());
#pragma omp parallel if (n > 1)
    {
      std::array<parallel::ExactSum, 6> part;
#pragma omp for schedule(static) nowait
      for (long g = 0; g < n; ++g) {
        const auto gi = static_cast<size_t>(g);
        const Vec6 s = weights_[gi] * grains[gi].sample_stress();
        for (int i = 0; i < 6; ++i) part[static_cast<size_t>(i)].add(s(i));
      }
#pragma omp critical(subslip_average_stress)
      for (int i = 0; i < 6; ++i) sum[static_cast<size_t>(i)].merge(part[static_cast<size_t>(i)]);
    }
    team_.sum(sum);
    Vec6 mean;
    for (int i = 0; i < 6; ++i) mean(i) = sum[static_cast<size_t>(i)].value();
    return mean;
  }

  // The mixed-control residual of the trial state: the free stresses minus their targets.
  struct MixedResidual {
    Eigen::VectorXd value;  // per free component
    double merit = 0.0;     // 1/2 |value|^2, what the line search decreases
    double size = 0.0;      // max |value_a|, what the convergence test bounds
  };

  MixedResidual free_stress_residual(const std::vector<FreeComponent>& fc,
                                     const Mat3& target) const {
    const Vec6 sigma = trial_average_stress();
    MixedResidual r;
    r.value.resize(static_cast<int>(fc.size()));
    for (size_t a = 0; a < fc.size(); ++a) {
      r.value(static_cast<int>(a)) = component(sigma, fc[a].i, fc[a].j) - target(fc[a].i, fc[a].j);
    }
    r.merit = 0.5 * r.value.squaredNorm();
    r.size = r.value.cwiseAbs().maxCoeff();
    return r;
  }

  // What the free stresses of the trial state can be resolved to, below which no L does better.
  struct StressResolution {
    // Round-off of the grain stresses and of the elastic trial increment C D dt they are
    // computed from (a large step's trial is mostly cancelled by the plastic correction).
    double round_off = 0.0;
    // The grains' Newton tolerance: a flow-rule residual delta (traction-ratio units) leaves a
    // resolved-shear error below delta mu f_n (every row's slope dG/dr >= 1), so the stress is
    // a function of L only to about this (measured: 2e-12 .. 1e-11 MPa at mu tau0 = 20 MPa
    // and delta = 1e-12; the bound is 8 delta max(mu f_n)).
    double grain_noise = 0.0;
  };

  StressResolution stress_resolution(const Mat3& l, double dt, const AggregateOptions& opt) const {
    constexpr double kEps = std::numeric_limits<double>::epsilon();
    const double elastic = phase_.stiffness.cwiseAbs().maxCoeff() * l.cwiseAbs().maxCoeff() * dt;
    std::array<double, 2> largest{0.0, 0.0};  // stress, strength
    for (const auto& s : trial_) {
      largest[0] = std::max(largest[0], s.stress.cwiseAbs().maxCoeff());
      const VecN fn = phase_.pressure_sensitive
                          ? VecN(phase_.tau0 - phase_.plane_normal_dyad.transpose() * s.stress)
                          : phase_.tau0;
      largest[1] = std::max(largest[1], s.mu.cwiseProduct(fn).cwiseAbs().maxCoeff());
    }
    team_.max(largest);
    return {16.0 * kEps * (largest[0] + elastic), 8.0 * opt.grain.tolerance * largest[1]};
  }

  // d(free stresses)/d(free components of L) from the averaged consistent tangents of the trial
  // state (exact sums: independent of the thread and rank counts). A free component not paired with
  // its transpose also spins: its skew part W turns the stress, d sigma = (W sigma - sigma W) dt
  // (with it, L_13 free alone takes as few grain solves per increment as L_13 and L_31 free as a
  // pair).
  Eigen::MatrixXd free_stress_jacobian(const std::vector<FreeComponent>& fc, double dt) const {
    // The grains' tangents are d sigma / d(D dt) along the free components' strain directions
    // (tangent_directions_): column b is d sigma / d u_b per dt.
    // Only the free components' rows of the mean tangent enter the Jacobian (free_entries), so
    // only those entries of the grains' tangents are summed (the others stay zero).
    const int k = static_cast<int>(fc.size());
    std::array<int, 6> rows{};
    for (int a = 0; a < k; ++a) {
      const FreeComponent& c = fc[static_cast<size_t>(a)];
      rows[static_cast<size_t>(a)] = kMandelIndex[c.i][c.j];
    }
    std::array<parallel::ExactSum, 36> sum;
    for (size_t g = 0; g < tangents_.size(); ++g) {
      const Tangent& t = tangents_[g];
      for (int b = 0; b < k; ++b)
        for (int a = 0; a < k; ++a)
          sum[static_cast<size_t>(b * k + a)].add(weights_[g] * t(rows[static_cast<size_t>(a)], b));
    }
    team_.sum(std::span(sum).first(static_cast<size_t>(k * k)));
    Tangent mean_tangent = Tangent::Zero(6, k);
    for (int b = 0; b < k; ++b)
      for (int a = 0; a < k; ++a)
        mean_tangent(rows[static_cast<size_t>(a)], b) = sum[static_cast<size_t>(b * k + a)].value();
    const Mat3 sigma = symmetric_from_mandel(trial_average_stress());
    Eigen::MatrixXd jac(k, k);
    for (int b = 0; b < k; ++b) {
      const FreeComponent& c = fc[static_cast<size_t>(b)];
      Vec6 dsigma = mean_tangent.col(b) * dt;
      if (!c.symmetric_pair && c.i != c.j) {
        const Mat3 e = c.direction();
        const Mat3 w = 0.5 * (e - e.transpose());
        dsigma += mandel_from_symmetric(w * sigma - sigma * w) * dt;
      }
      jac.col(b) = free_entries(dsigma, fc);
    }
    return jac;
  }

  // The mixed-control iterate: free components of L, the full L, and its residual (the grains'
  // trial_ and tangents_ belong to it).
  struct MixedIterate {
    Eigen::VectorXd u;
    Mat3 l;
    MixedResidual residual;
  };

  // Solves the grains at the free components u; false (and why) when a grain fails. `warm`:
  // from the rates of the previous iteration (solve_grains); the first of a step starts cold.
  bool evaluate_mixed(const LoadSegment& seg, const std::vector<FreeComponent>& fc,
                      const Mat3& target, double dt, const Eigen::VectorXd& u,
                      const AggregateOptions& opt, MixedIterate& out, std::string& why,
                      bool warm = true, bool want_tangent = false) {
    ++stats_.mixed_iterations;
    const Mat3 l = assemble_velocity_gradient(seg.velocity_gradient, fc, u);
    if (!solve_grains(l, dt, want_tangent, opt, why, warm)) return false;
    out = {u, l, free_stress_residual(fc, target)};
    return true;
  }

  enum class Search { decreased, stalled, failed };

  // Backtracking along the Newton update delta on the merit 1/2 |residual|^2 (Armijo): at stiff
  // settings (G/tau0 ~ 1e5, strain steps ~ 1e-2) the full update computed from an elastic
  // tangent overshoots the yield by orders of magnitude, and an L at which a grain fails counts
  // as infinitely bad. Each trial costs one aggregate solve, taken from `budget`; `halvings`
  // bounds the trials. On `decreased`, `it` is the new iterate (else the grains hold the last
  // trial, not `it`); on `failed`, `why` says why.
  Search mixed_line_search(const LoadSegment& seg, const std::vector<FreeComponent>& fc,
                           const Mat3& target, double dt, const Eigen::VectorXd& delta,
                           const AggregateOptions& opt, int halvings, MixedIterate& it, int& budget,
                           std::string& why) {
    MixedIterate next;
    std::string grain_why;
    double alpha = 1.0;
    for (int ls = 0; ls < halvings && budget > 0; ++ls, alpha *= 0.5) {
      --budget;
      std::string trial_why;
      if (!evaluate_mixed(seg, fc, target, dt, it.u + alpha * delta, opt, next, trial_why)) {
        if (grain_why.empty()) grain_why = trial_why;
        continue;
      }
      if (next.residual.merit <= (1.0 - 1e-4 * alpha) * it.residual.merit) {
        it = std::move(next);
        return Search::decreased;
      }
    }
    std::ostringstream msg;
    msg << "mixed control: the free components of L did not converge (free stress error "
        << it.residual.size << ", not reduced along the Newton update";
    if (!grain_why.empty()) msg << "; there " << grain_why;
    msg << ")";
    why = msg.str();
    return Search::stalled;
  }

  // One attempt at the increment: fixed L, or Newton with a line search on the free components
  // of L. Converged when the free stresses are within stress_tolerance x scale of their targets
  // or within their round-off; or, when the error is already below the grains' own noise
  // (StressResolution::grain_noise) and a short line search finds no decrease, at that noise:
  // a tolerance tighter than what the state resolves is met as well as it can be, not failed.
  //
  // The iteration starts from the last step's free components, or with MixedPredictor::trend
  // from those continued along their trend over the last step (on a loading path they change
  // smoothly, so the first sweep lands at a second-order distance from the step's solution:
  // fewer Newton iterations of the grains in the sweeps that follow). The trend is a guess:
  // where the step fails from there (an L poorly determined by the stresses, as in nearly ideal
  // plasticity, changes by jumps and has no trend) it is tried again from the last step's free
  // components before it is cut back.
  bool try_step(const LoadSegment& seg, const std::vector<FreeComponent>& fc, const Mat3& target,
                double dt, Eigen::VectorXd& u, const AggregateOptions& opt, std::string& why) {
    step_correction_ = zero_correction(fc);
    if (fc.empty()) return solve_grains(seg.velocity_gradient, dt, false, opt, why);
    if (opt.predictor == MixedPredictor::last)
      return solve_free_components(seg, fc, target, dt, u, opt, why);
    const Eigen::VectorXd start = continued_free(u, dt);
    Eigen::VectorXd solution = start;
    if (!solve_free_components(seg, fc, target, dt, solution, opt, why)) {
      if (start == u) return false;
      solution = u;
      if (!solve_free_components(seg, fc, target, dt, solution, opt, why)) return false;
    }
    u = solution;
    return true;
  }

  static Eigen::VectorXd zero_correction(const std::vector<FreeComponent>& fc) {
    return Eigen::VectorXd::Zero(static_cast<int>(fc.size()));
  }

  // The free components' path continued along its trend over dt, plus the correction of the
  // free-stress error the step inherits (FreePath); a component whose start would change sign
  // from u (or start from zero) keeps its value u, as the grains' continued slip rates do
  // (continued_rates): a component relaxing towards zero, as the lateral L of a hold does, over
  // steps longer than its relaxation would be carried past zero.
  Eigen::VectorXd continued_free(const Eigen::VectorXd& u, double dt) const {
    const FreePath& p = cursor_.path;
    Eigen::VectorXd start =
        p.from_step ? Eigen::VectorXd(p.value + p.trend * dt + p.correction / dt) : u;
    for (int k = 0; k < start.size(); ++k)
      if (!(start(k) * u(k) > 0.0)) start(k) = u(k);
    return start;
  }

  // try_step's iteration from the free components u (on success their solution).
  bool solve_free_components(const LoadSegment& seg, const std::vector<FreeComponent>& fc,
                             const Mat3& target, double dt, Eigen::VectorXd& u,
                             const AggregateOptions& opt, std::string& why) {
    tangent_directions_.resize(6, static_cast<int>(fc.size()));
    for (size_t b = 0; b < fc.size(); ++b)
      tangent_directions_.col(static_cast<int>(b)) = strain_direction(fc[b]);
    const double scale =
        std::max(target.cwiseAbs().maxCoeff(),
                 std::max(macro_.stress.cwiseAbs().maxCoeff(), phase_.tau0.maxCoeff()));
    const double tolerance = opt.stress_tolerance * scale;
    // At most max_mixed_iterations Newton updates and twice as many aggregate solves in all
    // (line-search trials included): a step that fails is cut back, which is cheaper.
    int budget = 2 * opt.max_mixed_iterations;
    constexpr double kNearTolerance = 100.0;
    constexpr int kNonmonotoneUpdates = 5;
    int nonmonotone = 0;
    MixedIterate it;
    if (!evaluate_mixed(seg, fc, target, dt, u, opt, it, why, false, true)) return false;
    // The Jacobian of the step's first iterate serves every update of the step (a chord
    // iteration: the averaged tangent barely changes over the few iterations of one step, and
    // the later grain solves need no tangent); it is renewed where its update does not decrease
    // the error.
    Eigen::MatrixXd jacobian = free_stress_jacobian(fc, dt);
    bool fresh = true;
    for (int iteration = 0;; ++iteration) {
      const StressResolution resolution = stress_resolution(it.l, dt, opt);
      if (it.residual.size <= std::max(tolerance, resolution.round_off)) {
        u = it.u;
        step_correction_ = dt * error_correction(jacobian, it.residual.value, tolerance, it.l);
        return true;
      }
      if (iteration == opt.max_mixed_iterations || budget == 0) break;
      // Half the tolerance is left to the step's own nonlinearity.
      const Eigen::VectorXd delta = least_change_step(
          jacobian, it.residual.value, 0.5 * std::max(tolerance, resolution.round_off));
      const double previous_size = it.residual.size;
      if (!delta.allFinite()) {
        why = "mixed control: non-finite Jacobian of the free stresses";
        return false;
      }
      const bool at_noise = it.residual.size <= resolution.grain_noise;
      const Search search =
          mixed_line_search(seg, fc, target, dt, delta, opt, at_noise ? 2 : 10, it, budget, why);
      if (search == Search::decreased) {
        // A chord iteration converges linearly; where it contracts the error by less than
        // half per update, Newton's own Jacobian is worth a tangent (docs/internals.md,
        // "Mixed control").
        const bool slow = it.residual.size > 0.5 * previous_size;
        if (slow && !fresh && budget-- > 0) {
          if (!evaluate_mixed(seg, fc, target, dt, it.u, opt, it, why, true, true)) return false;
          jacobian = free_stress_jacobian(fc, dt);
          fresh = true;
        } else {
          fresh = false;
        }
        continue;
      }
      if (!fresh && budget-- > 0) {  // a stale Jacobian: renewed at the current iterate
        if (!evaluate_mixed(seg, fc, target, dt, it.u, opt, it, why, true, true)) return false;
        jacobian = free_stress_jacobian(fc, dt);
        fresh = true;
        continue;
      }
      if (at_noise) {
        // No L does better than this one: the grains are re-solved there (the line search left
        // its last trial in them).
        if (!evaluate_mixed(seg, fc, target, dt, it.u, opt, it, why)) return false;
        u = it.u;
        step_correction_ = dt * error_correction(jacobian, it.residual.value, tolerance, it.l);
        return true;
      }
      // Near the tolerance the stress can be noisier than grain_noise says (measured at G/tau0
      // = 1e5 in long holds: ~1e-10 relative, where the Newton update is no descent direction):
      // there a few full, non-monotone updates are taken, which land within the tolerance.
      const bool near =
          it.residual.size <= kNearTolerance * std::max(tolerance, resolution.grain_noise);
      if (!near || nonmonotone++ == kNonmonotoneUpdates || budget-- <= 0) return false;
      if (!evaluate_mixed(seg, fc, target, dt, it.u + delta, opt, it, why)) return false;
    }
    std::ostringstream msg;
    msg << "mixed control: the free components of L did not converge in "
        << opt.max_mixed_iterations << " iterations (free stress error " << it.residual.size
        << ", tolerance " << tolerance << ")";
    why = msg.str();
    return false;
  }

  void commit(const LoadSegment& seg, const std::vector<FreeComponent>& fc,
              const Eigen::VectorXd& u, double dt) {
    // The last solve's grain loop took the trends and the average stress (note_solved_grain)
    // where trial_ is its and the step and the last one's length are those it took them for.
    const bool noted = solved_.valid && solved_.dt == dt && solved_.trend_step == trend_step_;
    solved_.valid = false;
    if (noted) {
      std::swap(history_, solved_.history);
    } else {
      const long n = static_cast<long>(committed_.size());
#pragma omp parallel for schedule(static) if (n > 1)
      for (long g = 0; g < n; ++g) {
        const auto gi = static_cast<size_t>(g);
        history_after_step(committed_[gi], trial_[gi], history_[gi], trend_step_, dt,
                           history_[gi]);
      }
    }
    trend_step_ = dt;
    const Vec6 trial_stress = noted ? solved_.average_stress : average_stress(trial_);
    std::swap(committed_, trial_);
    stats_.grain_steps += static_cast<long>(total_);
    const Mat3 l = fc.empty() ? seg.velocity_gradient
                              : assemble_velocity_gradient(seg.velocity_gradient, fc, u);
    // Deformation gradient by the Cayley (midpoint) map: exact for a pure rotation.
    const Mat3 half = 0.5 * dt * l;
    macro_.deformation_gradient =
        (Mat3::Identity() - half)
            .lu()
            .solve((Mat3::Identity() + half) * macro_.deformation_gradient);
    if (phase_.kinematics == Kinematics::small_strain) {
      macro_.strain += symmetric_part(l) * dt;
    } else {
      macro_.strain = log_strain(macro_.deformation_gradient);
    }
    macro_.stress = symmetric_from_mandel(trial_stress);
    macro_.velocity_gradient = l;
    macro_.time += dt;
  }

  // GrainFields
  template <class F>
  void per_grain(double* out, int width, F&& f) const {
    for (size_t g = 0; g < committed_.size(); ++g)
      f(committed_[g], out + g * static_cast<size_t>(width));
  }
  void stress(double* out) const override {
    per_grain(out, 6, [](const GrainState<N>& s, double* row) {
      const Mat3 t = symmetric_from_mandel(s.sample_stress());
      const double v[6] = {t(0, 0), t(1, 1), t(2, 2), t(1, 2), t(0, 2), t(0, 1)};
      std::copy(v, v + 6, row);
    });
  }
  void orientation(double* out) const override {
    per_grain(out, 9, [](const GrainState<N>& s, double* row) {
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) row[3 * i + j] = s.orientation(i, j);
    });
  }
  void per_system(double* out, const std::function<double(const GrainState<N>&, int)>& f) const {
    const int n = phase_.slip_count;
    per_grain(out, n, [&](const GrainState<N>& s, double* row) {
      for (int a = 0; a < n; ++a) row[a] = f(s, a);
    });
  }
  void slip(double* out) const override {
    per_system(out, [](const auto& s, int a) { return s.slip(a); });
  }
  void slip_rate(double* out) const override {
    per_system(out, [](const auto& s, int a) { return s.rate(a); });
  }
  void crss(double* out) const override {
    per_system(out, [this](const auto& s, int a) { return s.mu(a) * phase_.tau0(a); });
  }
  void ratio(double* out) const override {
    const int n = phase_.slip_count;
    per_grain(out, n, [&](const GrainState<N>& s, double* row) {
      const VecN r = loading_ratio(phase_, s);
      for (int a = 0; a < n; ++a) row[a] = r(a);
    });
  }
  void subloading_ratio(double* out) const override {
    per_system(out, [](const auto& s, int a) { return s.r_s(a); });
  }

  Phase<N> phase_;
  const parallel::Team& team_;
  size_t offset_ = 0;  // of this rank's grains in the aggregate
  size_t total_ = 0;   // grains of the aggregate (over the team)
  // The strain along the free components that removes the free-stress error of the last step
  // try_step solved, to first order (zero where it solved none: FreePath).
  Eigen::VectorXd step_correction_;
  std::vector<GrainState<N>> committed_, trial_;
  std::vector<Tangent> tangents_;
  std::vector<GrainStepReport> reports_;
  // The grains' slip-rate history (continued_rates): the rates' change per unit time over the
  // last committed step, trend_, and that trend's change per unit time since the step before,
  // trend_change_ (valid where trend_step_ > 0, the last step's length).
  std::vector<RateHistory<N>> history_;
  double trend_step_ = 0.0;
  // What commit() takes from the grain loop of the last solve (note_solved_grain): each grain's
  // trend and trend change over the step dt solved after one of trend_step, and the average
  // stress of trial_. Valid while trial_ and committed_ are that solve's.
  struct SolvedStep {
    std::vector<RateHistory<N>> history;
    Vec6 average_stress = Vec6::Zero();
    double dt = 0.0, trend_step = 0.0;
    bool valid = false;
  } solved_;
  std::vector<VecN> warm_;      // slip rates of each grain's last successful solve (solve_grains)
  Mat3 warm_l_ = Mat3::Zero();  // the L of that solve
  // The strain directions of the free components the tangents are taken along (set for each
  // mixed-control step).
  StrainDirections tangent_directions_ = Mat6::Identity();
  // d dgamma / d(D dt) of each grain from the last solve with tangents, and whether it belongs
  // to the step being solved (solve_grains).
  std::vector<SlipTangent<N>> slip_tangents_;
  bool slip_tangents_current_ = false;
  // The extrapolated integrator's work space (extrapolated_step): the start state, the solutions
  // with 1 .. k substeps, the combined macroscopic state and per-grain error estimates.
  std::vector<GrainState<N>> step_start_;
  std::array<std::vector<GrainState<N>>, integrators::kMaxExtrapolationOrder> solutions_;
  std::array<MacroState, integrators::kMaxExtrapolationOrder> solution_macros_;
  MacroState extrapolated_macro_;
  std::vector<VecN> extrapolation_errors_;
  std::vector<double> weights_;
  MacroState macro_;
  AggregateStats stats_;
  Cursor cursor_;
  std::chrono::steady_clock::time_point session_start_ = std::chrono::steady_clock::now();
  double wall_before_ = 0.0;  // wall_seconds of the sessions before a restore
};

}  // namespace

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
