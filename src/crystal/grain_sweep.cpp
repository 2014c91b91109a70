#include "grain_sweep.hpp"

#include <iomanip>
#include <limits>
#include <span>

namespace subslip::crystal::aggregate_parts {

template <int N>
GrainSweep<N>::GrainSweep(Phase<N> phase, const std::vector<Mat3>& orientations,
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
  weights_ = weights.empty() ? std::vector<double>(n, 1.0) : weights;
  std::array<parallel::ExactSum, 1> total;
  for (double w : weights_) total[0].add(w);
  team_.sum(total);
  const double sum = total[0].value();
  for (double& w : weights_) w /= sum;
  for (size_t g = 0; g < n; ++g)
    committed_[g].reset(phase_.slip_count, orientations[g], initial_mu);
}

// The grains' elastic stiffness, averaged: where a segment's mixed-control iteration starts
// (MixedControl::elastic_free_start).
template <int N>
Mat6 GrainSweep<N>::average_stiffness() const {
  std::array<parallel::ExactSum, 36> sum;
  for (size_t g = 0; g < committed_.size(); ++g) {
    const Mat6 c =
        weights_[g] * stiffness_in_sample_frame(phase_.stiffness, committed_[g].orientation);
    for (int i = 0; i < 36; ++i) sum[static_cast<size_t>(i)].add(c.data()[i]);
  }
  team_.sum(sum);
  Mat6 stiffness;
  for (int i = 0; i < 36; ++i) stiffness.data()[i] = sum[static_cast<size_t>(i)].value();
  return stiffness;
}

// The local error estimate of the step just solved (trial_ from committed_): per grain and
// slip system, dt/2 |A (gdot_end - gdot_start)| over its yield scale, the largest of all.
// The start rates are the committed end rates of the previous (backward Euler) step. A NaN
// wins, so that a broken step is never accepted: the first NaN, else the first of the
// largest, in grain order, per rank and then over the ranks in rank order (the same estimate
// at any rank count).
template <int N>
ErrorEstimate GrainSweep<N>::local_error(double dt) const {
  return worst_error([&](size_t g) {
    const VecN rate_change = trial_[g].rate - committed_[g].rate;
    const VecN scale = yield_scale(phase_, committed_[g]);
    return VecN((0.5 * dt) * (phase_.interaction * rate_change).cwiseAbs().cwiseQuotient(scale));
  });
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
template <int N>
bool GrainSweep<N>::solve(const Mat3& l, double dt, bool want_tangent, const AggregateOptions& opt,
                          AggregateStats& stats, std::string& why, bool warm) {
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
  stats.grain_solves += static_cast<long>(total_);
  const bool ok = every_grain_ok(stats, why);
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

// Grain gi's implicit step (solve): from its own start (continued rates, or the warm rates
// carried by its slip tangent), then, should that fail, from its committed rates.
template <int N>
void GrainSweep<N>::solve_implicit_grain(
    size_t gi, const Mat3& l, double dt, const GrainStepOptions& grain_options, Tangent* t,
    bool warm, bool carried, bool slip_tangent,
    const Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 6, 1>& direction_change) {
  GrainStepReport& rep = reports_[gi];
  SlipTangent<N>* st = slip_tangent ? &slip_tangents_[gi] : nullptr;
  if (!warm && cold_start_ != ColdStart::continued) {
    const VecN& start = cold_start_ == ColdStart::given ? (*cold_starts_)[gi] : committed_[gi].rate;
    rep = implicit_step_from(phase_, committed_[gi], l, dt, grain_options, start,
                             start != committed_[gi].rate, trial_[gi], t, st);
  } else if (!warm) {
    rep = cold_implicit_step(phase_, committed_[gi], history_[gi], trend_step_, l, dt,
                             grain_options, trial_[gi], t, st);
  } else if (carried) {
    VecN start = warm_[gi];
    start.noalias() += slip_tangents_[gi] * direction_change;
    rep = implicit_step_from(phase_, committed_[gi], l, dt, grain_options, start, true, trial_[gi],
                             t, st);
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
template <int N>
void GrainSweep<N>::note_solved_grain(size_t gi, double dt,
                                      std::array<parallel::ExactSum, 6>& part) {
  history_after_step(committed_[gi], trial_[gi], history_[gi], trend_step_, dt,
                     solved_.history[gi]);
  const Vec6 s = weights_[gi] * trial_[gi].sample_stress();
  for (int i = 0; i < 6; ++i) part[static_cast<size_t>(i)].add(s(i));
}

// Whether every grain's report (reports_) is ok; else why, for the first failing grain. The
// reports' Newton iterations are added to the statistics.
template <int N>
bool GrainSweep<N>::every_grain_ok(AggregateStats& stats, std::string& why) {
  // Serial, then over the ranks: the iterations, and the first failing grain (by index).
  constexpr auto kNone = std::numeric_limits<std::int64_t>::max();
  std::array<std::int64_t, 1> iterations{0}, failed{kNone};
  for (size_t g = 0; g < committed_.size(); ++g) {
    iterations[0] += reports_[g].iterations;
    if (!reports_[g].ok && failed[0] == kNone) failed[0] = static_cast<std::int64_t>(g + offset_);
  }
  team_.sum(iterations);
  team_.min(failed);
  stats.newton_iterations += iterations[0];
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

template <int N>
std::string GrainSweep<N>::describe_failure(size_t g, const GrainStepReport& rep) const {
  std::ostringstream msg;
  const auto& s = committed_[g];
  msg << "grain " << offset_ + g << ", slip system " << rep.system << ": " << rep.why << " (after "
      << rep.iterations << " iterations)";
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
template <int N>
void GrainSweep<N>::describe_plane_pressure(const GrainState<N>& s, int system,
                                            std::ostringstream& msg) const {
  const VecN fn = normal_traction(phase_, s);
  int lowest = 0;
  const double smallest = fn.minCoeff(&lowest);
  msg << ", f_n = " << fn(system) << "; smallest plane normal traction f_n = " << smallest
      << " (system " << lowest << "; the plane opens at f_n <= 0)";
}

// The volume average of the grains' sample-frame stress, over the team (exact sums). The
// threads sum their grains apart and merge: exact, so the same bits at any thread count.
template <int N>
Vec6 GrainSweep<N>::average_stress(const std::vector<GrainState<N>>& grains) const {
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

template <int N>
std::array<double, 2> GrainSweep<N>::largest_stress_and_strength() const {
  std::array<double, 2> largest{0.0, 0.0};  // stress, strength
  for (const auto& s : trial_) {
    largest[0] = std::max(largest[0], s.stress.cwiseAbs().maxCoeff());
    const VecN fn = normal_traction(phase_, s);
    largest[1] = std::max(largest[1], s.mu.cwiseProduct(fn).cwiseAbs().maxCoeff());
  }
  team_.max(largest);
  return largest;
}

template <int N>
double GrainSweep<N>::smallest_strength() const {
  std::array<double, 1> negated{-std::numeric_limits<double>::max()};
  for (const auto& s : trial_) {
    const VecN fn = normal_traction(phase_, s);
    for (int a = 0; a < fn.size(); ++a)
      if (fn(a) > 0.0) negated[0] = std::max(negated[0], -s.mu(a) * fn(a));
  }
  team_.max(negated);
  return -negated[0];
}

// The grains' tangents are d sigma / d(D dt) along the free components' strain directions
// (tangent_directions_): column b is d sigma / d u_b per dt. Only the free components' rows of
// the mean tangent enter the mixed control's Jacobian (free_entries), so only those entries of
// the grains' tangents are summed (the others stay zero).
template <int N>
Tangent GrainSweep<N>::mean_tangent(const std::array<int, 6>& rows, int k) const {
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
  return mean_tangent;
}

template <int N>
Vec6 GrainSweep<N>::commit(double dt, AggregateStats& stats) {
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
      history_after_step(committed_[gi], trial_[gi], history_[gi], trend_step_, dt, history_[gi]);
    }
  }
  trend_step_ = dt;
  const Vec6 trial_stress = noted ? solved_.average_stress : average_stress(trial_);
  std::swap(committed_, trial_);
  stats.grain_steps += static_cast<long>(total_);
  return trial_stress;
}

// GrainFields
template <int N>
void GrainSweep<N>::stress(double* out) const {
  per_grain(out, 6, [](const GrainState<N>& s, double* row) {
    const Mat3 t = symmetric_from_mandel(s.sample_stress());
    const double v[6] = {t(0, 0), t(1, 1), t(2, 2), t(1, 2), t(0, 2), t(0, 1)};
    std::copy(v, v + 6, row);
  });
}

template <int N>
void GrainSweep<N>::orientation(double* out) const {
  per_grain(out, 9, [](const GrainState<N>& s, double* row) {
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) row[3 * i + j] = s.orientation(i, j);
  });
}

template <int N>
void GrainSweep<N>::per_system(double* out,
                               const std::function<double(const GrainState<N>&, int)>& f) const {
  const int n = phase_.slip_count;
  per_grain(out, n, [&](const GrainState<N>& s, double* row) {
    for (int a = 0; a < n; ++a) row[a] = f(s, a);
  });
}

template <int N>
void GrainSweep<N>::slip(double* out) const {
  per_system(out, [](const auto& s, int a) { return s.slip(a); });
}

template <int N>
void GrainSweep<N>::slip_rate(double* out) const {
  per_system(out, [](const auto& s, int a) { return s.rate(a); });
}

template <int N>
void GrainSweep<N>::crss(double* out) const {
  per_system(out, [this](const auto& s, int a) { return s.mu(a) * phase_.tau0(a); });
}

template <int N>
void GrainSweep<N>::strength(double* out) const {
  const int n = phase_.slip_count;
  per_grain(out, n, [&](const GrainState<N>& s, double* row) {
    const VecN fn = normal_traction(phase_, s);
    for (int a = 0; a < n; ++a) row[a] = s.mu(a) * fn(a);
  });
}

template <int N>
void GrainSweep<N>::ratio(double* out) const {
  const int n = phase_.slip_count;
  per_grain(out, n, [&](const GrainState<N>& s, double* row) {
    const VecN r = loading_ratio(phase_, s);
    for (int a = 0; a < n; ++a) row[a] = r(a);
  });
}

template <int N>
void GrainSweep<N>::subloading_ratio(double* out) const {
  per_system(out, [](const auto& s, int a) { return s.r_s(a); });
}

template <int N>
void GrainSweep<N>::resolved_shear(double* out) const {
  const int n = phase_.slip_count;
  per_grain(out, n, [&](const GrainState<N>& s, double* row) {
    const VecN tau = phase_.schmid.transpose() * s.stress;
    for (int a = 0; a < n; ++a) row[a] = tau(a);
  });
}

template <int N>
void GrainSweep<N>::values(GrainField f, double* out) const {
  switch (f) {
    case GrainField::stress:
      return stress(out);
    case GrainField::orientation:
      return orientation(out);
    case GrainField::slip:
      return slip(out);
    case GrainField::slip_rate:
      return slip_rate(out);
    case GrainField::crss:
      return crss(out);
    case GrainField::strength:
      return strength(out);
    case GrainField::r:
      return ratio(out);
    case GrainField::r_s:
      return subloading_ratio(out);
    case GrainField::tau:
      return resolved_shear(out);
  }
}

#define SUBSLIP_INSTANTIATE_GRAIN_SWEEP(N) template class GrainSweep<N>;

SUBSLIP_FOR_EACH_SLIP_COUNT(SUBSLIP_INSTANTIATE_GRAIN_SWEEP)

}  // namespace subslip::crystal::aggregate_parts
