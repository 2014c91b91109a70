#include "aggregate_extrapolation.hpp"

#include "kernel_detail.hpp"
#include "subslip/crystal/rotation.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <limits>

namespace subslip::crystal::aggregate_parts {

Mat3 log_strain(const Mat3& f) {
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(f * f.transpose());
  const Eigen::Vector3d log_values = eig.eigenvalues().array().log() * 0.5;
  return eig.eigenvectors() * log_values.asDiagonal() * eig.eigenvectors().transpose();
}

// trial_ and extrapolated_macro_ from solutions_ (extrapolated_step); the per-grain error
// estimates in errors_, the restoring reports in reports_.
template <int N>
void Extrapolation<N>::combine(int order, double dt, double flow_residual, GrainSweep<N>& grains,
                               const std::optional<Mat3>& start_l) {
  grains.forget_solve();  // its trial states are no longer the last solve's
  const Phase<N>& phase = grains.phase();
  std::vector<GrainState<N>>& trial = grains.trial();
  std::vector<GrainStepReport>& reports = grains.reports();
  const auto k = static_cast<size_t>(order);
  const long n = static_cast<long>(grains.committed().size());
  // The loading at the step's end: the solutions' L (under mixed control as solved, each its last
  // substep's mean) combined like the states, L at the end to the combination's order; the next
  // step reads it as its start's (MacroState::velocity_gradient of the combination).
  const Mat3 l_at_end = combined_velocity_gradient(order);
  const Mat3 l_at_start = start_l.value_or(l_at_end);
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
    GrainState<N>& out = trial[gi];
    out.stress = e_stress.best;
    out.mu = e_mu.best;
    out.r_s = e_rs.best;
    out.slip = extrapolate_implicit_euler(slip, order).best;
    out.rate = extrapolate_implicit_euler(rate, order).best;
    out.orientation =
        rotation_exp(extrapolate_implicit_euler(turn, order).best) * finest.orientation;
    reports[gi] = restore_extrapolated_state(phase, finest, out, flow_residual);
    const VecN scale = yield_scale(phase, out);
    errors_[gi] = system_errors(phase, e_stress.best - e_stress.second, scale);
    if (order >= 4) {  // the guard against a cancelling last column (guarded_estimate)
      const auto earlier = integrators::earlier_column_estimates(stress);
      const VecN previous = system_errors(phase, earlier[0], scale);
      const VecN before = system_errors(phase, earlier[1], scale);
      VecN& error = errors_[gi];
      for (int a = 0; a < phase.slip_count; ++a)
        error(a) = integrators::guarded_estimate(error(a), previous(a), before(a));
    }
    if (!switches_phase(phase, step_start_[gi], gi, order, out)) {
      errors_[gi] =
          errors_[gi].cwiseMax(turn_errors(phase, step_start_[gi], out, l_at_start, l_at_end, dt));
    } else {
      const Loading at_start = loading(phase, step_start_[gi], l_at_start);
      errors_[gi] = errors_[gi].cwiseMax(
          switch_step_errors(phase, gi, order, out, dt, at_start, !start_l.has_value()));
    }
  }
  combine_macro(order, l_at_end, grains);
}

template <int N>
void Extrapolation<N>::note_finest_substep(int m, int order,
                                           const std::vector<GrainState<N>>& grains,
                                           const Eigen::VectorXd& free) {
  finest_free_[static_cast<size_t>(m - 1)] = free;
  if (m == order) return;  // (its rates are the finest solution's, solution(order))
  std::vector<VecN>& rates = finest_rates_[static_cast<size_t>(m - 1)];
  rates.resize(grains.size());
  for (size_t g = 0; g < grains.size(); ++g) rates[g] = grains[g].rate;
}

template <int N>
void Extrapolation<N>::coarse_substep_start(int order, int j, int i, std::vector<VecN>& rates,
                                            Eigen::VectorXd& free) const {
  // The substep spans [i - 1, i] / j of the step, the finest's substep m [m - 1, m] / order.
  const double begin = static_cast<double>(i - 1) / j, end = static_cast<double>(i) / j;
  free.setZero(finest_free_[0].size());
  for (int m = 1; m <= order; ++m) {
    const double overlap = std::min(end, static_cast<double>(m) / order) -
                           std::max(begin, static_cast<double>(m - 1) / order);
    if (overlap > 0.0) free += (overlap / (end - begin)) * finest_free_[static_cast<size_t>(m - 1)];
  }
  // The finest's rates at the end of its substep m (0: the step's start).
  const auto finest_rate = [&](int m, size_t g) -> const VecN& {
    if (m == 0) return step_start_[g].rate;
    if (m == order) return solutions_[static_cast<size_t>(order - 1)][g].rate;
    return finest_rates_[static_cast<size_t>(m - 1)][g];
  };
  // The substep's end lies in the finest's substep `within`, at w of it (w = 1: its end).
  const double position = end * order;
  const int within = std::clamp(static_cast<int>(std::ceil(position)), 1, order);
  const double w = position - (within - 1);
  rates.resize(step_start_.size());
  for (size_t g = 0; g < rates.size(); ++g) {
    rates[g] = w >= 1.0 ? finest_rate(within, g)
                        : VecN((1.0 - w) * finest_rate(within - 1, g) + w * finest_rate(within, g));
  }
}

// The error estimate of grain g on a step in which a system switched between elastic and
// slipping (switches_phase). The solution has a kink there and no error expansion in powers of
// the step, so the step is judged as a backward Euler step: by the one-substep solution against
// the two-substep one, and by backward Euler's own estimate of the resolved shears, dt/2 A
// (rates at the one-substep solution's end - at the step's start) taken over the rates that jump
// (the switching systems', and those of slipping systems whose rate no flow rule sets), filtered
// through the relaxation of the systems that slip throughout the step (relaxed), over the CRSS;
// the larger, times the bound on the combination's error at a kink in those units
// (integrators::combination_kink_bound: a half for orders 2 and 3), since the combination is
// what the step accepts. The second sees a switch every solution steps over: a system slipping at
// the start of a reversal whose solutions all end elastic (each evaluates the flow rule only where
// the stress has already unloaded) agree with each other exactly, while the true path slips on
// until the system's r falls to r_s. Such a step is shortened until both meet the tolerance.
// `at_start`: how each system loads at the step's start (at a segment's first step, under the
// new loading: classify_switches_at_start); `segment_start`: whether the step is a segment's first.
template <int N>
typename Extrapolation<N>::VecN Extrapolation<N>::switch_step_errors(
    const Phase<N>& phase, size_t g, int order, const GrainState<N>& combined, double dt,
    const Loading& at_start, bool segment_start) const {
  const GrainState<N>& one = solutions_[0][g];
  const GrainState<N>& two = solutions_[1][g];
  const GrainState<N>& start = step_start_[g];
  // The systems that slip in one sense at the start, at the end of every solution and in their
  // combination: they slip throughout the step (as far as its samples tell).
  std::array<bool, SlipTypes<N>::MaxN> steady{};
  for (int a = 0; a < phase.slip_count; ++a) {
    const double sense = start.rate(a);
    bool throughout = sense != 0.0 && combined.rate(a) * sense > 0.0;
    for (int j = 0; j < order; ++j)
      throughout = throughout && solutions_[static_cast<size_t>(j)][g].rate(a) * sense > 0.0;
    steady[static_cast<size_t>(a)] = throughout;
  }
  std::array<bool, SlipTypes<N>::MaxN> started{}, stopped{};
  if (segment_start)
    classify_switches_at_start(phase, g, order, at_start, steady, started, stopped);
  // Only the rates that jump carry a kink. A system that slips throughout the step at a rate its
  // flow rule sets from tau, r_s and mu has a continuous rate (only its slope jumps where another
  // system switches), and the extrapolation's own estimate measures its smooth change at the
  // step's order; the filter below carries its response to the others' jumps. What stays: the
  // switching systems' rate changes, and those of slipping systems whose rate no flow rule sets
  // (rate-independent ones, set by consistency, and any whose flow rule gives no finite positive
  // relaxation at the step's end, as one at r = r_hat whose CRSS softens with its slip).
  VecN inverse_relaxation = inverse_relaxations(phase, start, one, steady, dt);
  VecN rate_jump = one.rate - start.rate;
  for (int a = 0; a < phase.slip_count; ++a)
    if (inverse_relaxation(a) >= 0.0) rate_jump(a) = 0.0;
  // A system the segment's new loading starts or stops keeps its rate change (the transient is
  // the error), relaxed at the rate it relaxes where it slips: at the end for a start, at the
  // step's start for a stop.
  for (int a = 0; a < phase.slip_count; ++a) {
    const auto i = static_cast<size_t>(a);
    if (stopped[i]) {
      inverse_relaxation(a) = relaxation_at_start(phase, a, start, dt);
    } else if (started[i]) {
      inverse_relaxation(a) = relaxation_at_end(phase, a, start, one, dt);
    }
  }
  // A start located inside the step (located_starts) leaves the rest of the estimate and is
  // judged apart (located_start_errors).
  const MatNN drive = driving_interaction(phase, start.stress);
  const VecN onset =
      located_starts(phase, drive, g, order, combined, at_start, steady, started, stopped);
  VecN located_jump = VecN::Zero(phase.slip_count);
  for (int a = 0; a < phase.slip_count; ++a)
    if (onset(a) >= 0.0) located_jump(a) = rate_jump(a), rate_jump(a) = 0.0;
  const VecN shear_error = (0.5 * dt) * (phase.interaction * rate_jump);
  // (Without plane pressure K = A, and the drive's error is the resolved shears'.)
  const VecN drive_error =
      phase.pressure_sensitive ? VecN((0.5 * dt) * (drive * rate_jump)) : shear_error;
  const VecN located_error =
      located_start_errors(phase, drive, start, one, inverse_relaxation, onset, located_jump, dt);
  const double bound = integrators::combination_kink_bound(order);
  const VecN error =
      bound *
      system_errors(phase, one.stress - two.stress, yield_scale(phase, combined))
          .cwiseMax(
              (relaxed(phase, drive, inverse_relaxation, shear_error, drive_error).cwiseAbs() +
               located_error)
                  .cwiseQuotient(yield_scale(phase, start)));
  return error.cwiseMax(bound * switching_subloading_errors(phase, one, two, steady));
}

// The error a switch leaves in the subloading ratio of each system that starts or stops in the
// step, in r_s's unit (the yield's, as the resolved shears' estimate): the one-substep solution's
// r_s against the two-substep one's; 0 for a system that slips throughout the step and for a
// rate-independent one. A slipping system's resolved shear rides on its subloading surface, tau =
// (r_s + its overstress) times its yield traction, so an r_s left off where a system starts is a
// resolved-shear error of that size; but it shows only after the step, as the system settles
// onto its flow rule, and the step's resolved shears, relaxed through the flow rules, do not hold
// it. Measured on the power form with xi = 1, kappa = 10 of crystal_pressure_sensitive.yaml at
// 1e-7: a system starting 0.9 s into the hold left r_s 4e-6 off with tau within the tolerance,
// and tau drifted to 5.6 times the tolerance over the next 7 s as r_s relaxed. A system that
// slips throughout the step has r_s following its own slip on the surface (covered by its
// resolved shear, which the extrapolation measures); a rate-independent one at a vertex has an
// r_s no better determined than the split of slip (the reason r_s is not in system_errors).
template <int N>
typename Extrapolation<N>::VecN Extrapolation<N>::switching_subloading_errors(
    const Phase<N>& phase, const GrainState<N>& one, const GrainState<N>& two,
    const std::array<bool, SlipTypes<N>::MaxN>& steady) {
  VecN error = VecN::Zero(phase.slip_count);
  for (int a = 0; a < phase.slip_count; ++a) {
    const auto i = static_cast<size_t>(a);
    if (steady[i] || phase.laws[i].is_rate_independent()) continue;
    error(a) = std::abs(one.r_s(a) - two.r_s(a));
  }
  return error;
}

// A system idle at the step's start (or slipping there the other way), unloading there, that ends
// slipping in one sense in every solution and in their combination, against the sign of its
// resolved shear at the start: its tau passes zero inside the step, and there its |tau| turns to
// grow. An idle system sits on its subloading surface (r_s follows r down, (3.12)), so it starts
// slipping at that turn, at a rate continuous in the state (zero at r = r_s): its switch is
// located, at theta = |tau| / (the fall of |tau| at the start), the time the unloading at the
// start's rate takes to zero; for a system still slipping the other way at the start, the fall
// without its own slip (which stops first and speeds the fall while it lasts): the latest the
// crossing can be, and the estimate below grows with theta. On a pressure-sensitive plane r =
// |tau| / (mu f_n) passes zero with |tau|, and the fall is that of f_n r (Loading; its own slip's
// part through `drive`, driving_interaction): theta is where r's line reaches zero. Returns theta
// of every such system, -1 for the others (and for a rate-independent system, whose rate jumps).
// A turn of |tau| on one side of zero is not located (its time depends on how the growth runs
// between the step's ends, which the samples do not show; a crossing of zero lies on the
// unloading's own line) and keeps its kink.
template <int N>
typename Extrapolation<N>::VecN Extrapolation<N>::located_starts(
    const Phase<N>& phase, const MatNN& drive, size_t g, int order, const GrainState<N>& combined,
    const Loading& at_start, const std::array<bool, SlipTypes<N>::MaxN>& steady,
    const std::array<bool, SlipTypes<N>::MaxN>& started,
    const std::array<bool, SlipTypes<N>::MaxN>& stopped) const {
  VecN onset = VecN::Constant(phase.slip_count, -1.0);
  const GrainState<N>& start = step_start_[g];
  const VecN tau = phase.schmid.transpose() * start.stress;
  for (int a = 0; a < phase.slip_count; ++a) {
    const auto i = static_cast<size_t>(a);
    if (steady[i] || started[i] || stopped[i] || !at_start.unloading(a)) continue;
    if (phase.laws[i].is_rate_independent()) continue;
    const double sense = combined.rate(a) > 0.0 ? 1.0 : (combined.rate(a) < 0.0 ? -1.0 : 0.0);
    bool slips = sense != 0.0 && start.rate(a) * sense <= 0.0 && tau(a) * sense < 0.0;
    for (int j = 0; j < order; ++j)
      slips = slips && solutions_[static_cast<size_t>(j)][g].rate(a) * sense > 0.0;
    if (!slips) continue;
    // The fall once its own slip the other way (if any) has stopped: the latest crossing.
    const double fall = -at_start.growth(a) - drive(a, a) * std::abs(start.rate(a));
    if (fall > 0.0) onset(a) = std::abs(tau(a)) / fall;
  }
  return onset;
}

// The error of the starts located inside the step (onset: their times, -1 elsewhere), of their
// rate changes `jump` (at the end of the one-substep solution, from the step's start). The
// one-substep solution spreads the start over the whole step: where the system relaxes quickly
// (a stiff start) it ends short of the overstress (rate / D, D = d rate / d tau) by the part of
// the step before the start, rate / D theta / dt, and the transient after the start is what
// backward Euler's estimate over that part, (dt - theta) / 2 A jump, filtered through the
// system's relaxation there (its flow rule at the one-substep end over dt - theta, as a start at a
// segment's start; the steady systems relax it too), measures: jump / D / 2. Together, with
// rate = jump dt / (dt - theta), the filtered estimate times (dt + theta) / (dt - theta). Where
// the start is not stiff that exceeds backward Euler's estimate over the whole step, dt / 2 A
// jump, the kink bound's, which bounds it wherever the kink lies: the smaller of the two, per
// system. The starts' relaxation is kept out of the rest of the estimate: they do not relax what
// happened before them.
template <int N>
typename Extrapolation<N>::VecN Extrapolation<N>::located_start_errors(
    const Phase<N>& phase, const MatNN& drive, const GrainState<N>& start, const GrainState<N>& one,
    const VecN& inverse_relaxation, const VecN& onset, const VecN& jump, double dt) {
  const int n = phase.slip_count;
  if (!(onset.array() >= 0.0).any()) return VecN::Zero(n);
  const VecN kink = ((0.5 * dt) * (phase.interaction * jump)).cwiseAbs();
  VecN relaxation = inverse_relaxation;
  VecN after_jump = VecN::Zero(n);
  double latest = 0.0;
  for (int a = 0; a < n; ++a) {
    if (!(onset(a) >= 0.0)) continue;
    const double after = dt - std::min(onset(a), dt);
    const double inverse =
        after > 0.0 ? inverse_relaxation_of(phase, a, start, one.stress, one.mu(a), one.r_s(a),
                                            std::abs(one.slip(a) - start.slip(a)), after)
                    : -1.0;
    // No finite relaxation over the part after the start (a flow rule that gives none there):
    // no transient model holds, and the kink bound judges every located start of the grain.
    if (inverse < 0.0) return kink;
    relaxation(a) = inverse;
    after_jump(a) = (0.5 * after) * jump(a);
    latest = std::max(latest, onset(a));
  }
  const VecN shear_jump = phase.interaction * after_jump;
  const VecN filtered = relaxed(phase, drive, relaxation, shear_jump,
                                phase.pressure_sensitive ? VecN(drive * after_jump) : shear_jump)
                            .cwiseAbs() *
                        ((dt + latest) / (dt - latest));
  return filtered.cwiseMin(kink);
}

// 1 / (dt d|rate|/d|tau|) of each system that slips in one sense throughout the step (`steady`)
// at a rate its flow rule sets, from the flow rule at the end of the one-substep solution with
// the subloading ratio and the CRSS carried along by its slip (their rise with slip is what
// bounds the relaxation near r_s = 0: U(r_s) ~ 4e4 per unit slip at r_s = 0.003, where the flow
// rule alone at fixed r_s is 1e6 times stiffer); -1 for every other system. A system that starts,
// stops or reverses inside the step changes the Jacobian there. A rate-independent system has no
// flow rule with a rate (its slip follows from consistency with the loading, and where several
// slip at a vertex their split is not determined); taken as relaxing at once (D^-1 = 0), the
// filter credits it with absorbing every part of the error its slip could carry: two FCC grains
// reversed (crystal_law_edges.yaml, mu_k = 3, kappa = 10, neg_log) ran 94 and 624 times the
// tolerance at 1e-6 and 1e-7, their references at 1e-9 and 1e-8 1.4e-5 ... 1.6e-5 of the CRSS
// apart; kept out, 0.58 and 0.45 times, the references 3.3e-9 ... 4.9e-9 apart. A flow rule that
// gives no finite positive relaxation (r at r_hat with the CRSS softening) holds its rate by
// consistency as well. A pressure-sensitive system relaxes through its flow rule in r = |tau| /
// (mu f_n) at the stress's f_n, the strength's move with the slip carried by the filter
// (driving_interaction).
template <int N>
typename Extrapolation<N>::VecN Extrapolation<N>::inverse_relaxations(
    const Phase<N>& phase, const GrainState<N>& start, const GrainState<N>& one,
    const std::array<bool, SlipTypes<N>::MaxN>& steady, double dt) {
  VecN inverse_relaxation = VecN::Constant(phase.slip_count, -1.0);
  for (int a = 0; a < phase.slip_count; ++a)
    if (steady[static_cast<size_t>(a)])
      inverse_relaxation(a) = relaxation_at_end(phase, a, start, one, dt);
  return inverse_relaxation;
}

// 1 / (dt d|rate|/d|tau|) of system a from its flow rule at `stress`, yield traction mu f_n (the
// CRSS mu tau0 without the pressure-sensitive reading; f_n at `stress`, held) and subloading
// ratio r_s after a slip of `slip` from `start` over dt, its r_s and mu carried along by the slip;
// -1 for a rate-independent system or where the flow rule gives no finite positive relaxation.
template <int N>
double Extrapolation<N>::inverse_relaxation_of(const Phase<N>& phase, int a,
                                               const GrainState<N>& start, const Vec6& stress,
                                               double mu, double r_s, double slip, double dt) {
  const law::SubloadingFrictionLaw& law = phase.laws[static_cast<size_t>(a)];
  if (law.is_rate_independent()) return -1.0;
  const double strength = detail::normal_traction(phase, stress)(a);
  if (!(strength > 0.0)) return -1.0;  // an open plane carries no shear: no flow rule applies
  const double crss = mu * strength;
  const double r = std::abs(phase.schmid.col(a).dot(stress)) / crss;
  const law::FlowResidual g = law.flow_residual(r, r_s, slip, dt);
  if (!g.admissible || !(slip > 0.0)) return -1.0;
  // G's slope in the slip with r_s and mu moving along (r = tau / (mu tau0) at fixed tau).
  const double slope =
      g.d_slip + g.d_rs * law.subloading_ratio_after(start.r_s(a), slip).d_slip -
      g.d_r * (r / mu) * law.friction_coefficient_after(start.mu(a), slip, dt).d_slip;
  const double rate_per_shear = -g.d_r / (slope * dt * crss);
  if (rate_per_shear > 0.0 && std::isfinite(rate_per_shear)) return 1.0 / (dt * rate_per_shear);
  return -1.0;
}

// A segment's first step starts where the loading changes, and a switch that change sets off
// starts at the step's start, not anywhere inside it as the kink bound supposes. A rate-dependent
// rate is continuous in the state (zero at r = r_s), so such a switch is a transient from the
// step's start at the rate the system relaxes through its flow rule: what every solution misses of
// it is its rate change filtered through that relaxation, as the steady systems' response is, and
// not backward Euler's dt/2 of it (which the kink bound takes, and which fell with the step until
// it resolved the transient). Of the systems that switch in the step (not `steady`), by how they
// load under the new loading at the step's start (`at_start`, with the start's rates):
// * `started`: idle at the start and loading there, slipping at the end of the one-substep
//   solution and at no solution's end the other way: relaxed as at the one-substep solution's end;
// * `stopped`: slipping at the start and unloading there, at no solution's end slipping the other
//   way: relaxed as at the step's start (relaxation_at_start), where it still slips.
// An idle system that starts on the other side later in the step, or a slipping one loaded at the
// start that stops later, switches inside the step and keeps its kink. Measured on the Cu [001]
// crystal of crystal_fcc_schmid_stiff.yaml (G/tau0 = 100, 1 /s, 10 increments): reversed, the
// stop read 0.095 at dt = 0.01 s (the kink bound) where the path is 7.7e-6 off, and the step was
// refused down to 1e-4 s; filtered, 3.8e-6. A rate-independent system (its rate jumps with the
// loading) keeps the kink bound.
template <int N>
void Extrapolation<N>::classify_switches_at_start(
    const Phase<N>& phase, size_t g, int order, const Loading& at_start,
    const std::array<bool, SlipTypes<N>::MaxN>& steady,
    std::array<bool, SlipTypes<N>::MaxN>& started,
    std::array<bool, SlipTypes<N>::MaxN>& stopped) const {
  const GrainState<N>& start = step_start_[g];
  const GrainState<N>& one = solutions_[0][g];
  // Whether no solution ends slipping against `sense` (their combination may pass zero).
  const auto never_against = [&](int a, double sense) {
    for (int j = 0; j < order; ++j)
      if (solutions_[static_cast<size_t>(j)][g].rate(a) * sense < 0.0) return false;
    return true;
  };
  for (int a = 0; a < phase.slip_count; ++a) {
    const auto i = static_cast<size_t>(a);
    if (steady[i]) continue;  // (a rate-independent system gets no relaxation: its kink stays)
    if (start.rate(a) == 0.0 && at_start.loading(a) && one.rate(a) != 0.0 &&
        never_against(a, one.rate(a)))
      started[i] = true;
    else if (start.rate(a) != 0.0 && at_start.unloading(a) && never_against(a, start.rate(a)))
      stopped[i] = true;
  }
}

// inverse_relaxation_of for system a at the end of the one-substep solution `one`, after its slip
// there from `start`.
template <int N>
double Extrapolation<N>::relaxation_at_end(const Phase<N>& phase, int a, const GrainState<N>& start,
                                           const GrainState<N>& one, double dt) {
  return inverse_relaxation_of(phase, a, start, one.stress, one.mu(a), one.r_s(a),
                               std::abs(one.slip(a) - start.slip(a)), dt);
}

// inverse_relaxation_of for system a at the step's start: its flow rule at the start's stress,
// after a step of dt at the start's rate.
template <int N>
double Extrapolation<N>::relaxation_at_start(const Phase<N>& phase, int a,
                                             const GrainState<N>& start, double dt) {
  const law::SubloadingFrictionLaw& law = phase.laws[static_cast<size_t>(a)];
  const double slip = std::abs(start.rate(a)) * dt;
  const double r_s = law.subloading_ratio_after(start.r_s(a), slip).value;
  const double mu = law.friction_coefficient_after(start.mu(a), slip, dt).value;
  return inverse_relaxation_of(phase, a, start, start.stress, mu, r_s, slip, dt);
}

// How the slip rates move what drives each system's rate, d(drive_a) = -K_ab d(gamma_b): the
// interaction matrix A (tau_a moves by -A_ab per unit slip of b), and on a pressure-sensitive
// plane also its strength's move. Such a system's rate follows r = |tau| / (mu f_n); at fixed mu,
// f_n dr = d|tau| - (|tau| / f_n) df_n, and a slip of b raises f_n,a by M_a : C : P_b, so in tau's
// sign K_ab = A_ab + (tau_a / f_n,a) M_a : C : P_b. At `stress` (an open plane, f_n <= 0, keeps A).
template <int N>
typename Extrapolation<N>::MatNN Extrapolation<N>::driving_interaction(const Phase<N>& phase,
                                                                       const Vec6& stress) {
  MatNN drive = phase.interaction;
  if (!phase.pressure_sensitive) return drive;
  const VecN fn = detail::normal_traction(phase, stress);
  const VecN tau = phase.schmid.transpose() * stress;
  for (int a = 0; a < phase.slip_count; ++a)
    if (fn(a) > 0.0) drive.row(a) += (tau(a) / fn(a)) * phase.normal_interaction.row(a);
  return drive;
}

// Backward Euler's error of the resolved shears, `error` (A times the slips' error), filtered
// through the step's Jacobian as Shampine filters it for stiff problems (as the contact step's
// estimate is): the systems that relax through their flow rule over the whole step
// (inverse_relaxations: D^-1 / dt, negative for the others, whose part of the error stays) absorb
// the error of what drives them, `drive_error` (K times the slips' error, K = `drive`,
// driving_interaction: A without plane pressure), by slipping y more: (D_S^-1 / dt + K_SS) y =
// drive_error_S, and the resolved shears keep error - A_S y. Solved with the pseudo-inverse where
// that matrix is singular to working precision (nearly rate-independent systems, D^-1 -> 0; more
// systems than independent directions). Measured on the [-123] single crystal: the refused steps
// fall from about half of the accepted ones to a tenth; on a soft pyramidal HCP aggregate (tau0
// 0.163 MPa) the error stays 0.6 ... 0.9 times the tolerance
// (docs/integrators.md, "Where the expansion does not hold: switches").
template <int N>
typename Extrapolation<N>::VecN Extrapolation<N>::relaxed(const Phase<N>& phase, const MatNN& drive,
                                                          const VecN& inverse_relaxation,
                                                          const VecN& error,
                                                          const VecN& drive_error) {
  const int n = phase.slip_count;
  if (!(inverse_relaxation.array() >= 0.0).any()) return error;
  MatNN k = MatNN::Identity(n, n);  // the other systems' rows: y = 0
  VecN rhs = VecN::Zero(n);
  for (int a = 0; a < n; ++a) {
    if (inverse_relaxation(a) < 0.0) continue;
    rhs(a) = drive_error(a);
    for (int b = 0; b < n; ++b) k(a, b) = inverse_relaxation(b) < 0.0 ? 0.0 : drive(a, b);
    k(a, a) += inverse_relaxation(a);
  }
  return error - phase.interaction * k.completeOrthogonalDecomposition().solve(rhs);
}

// An error estimate per system from a difference of the stress: the resolved shear stress
// over the CRSS, on what the grain's state determines. mu and r_s of each system are not in
// it: they follow the system's own slip, and where several systems can carry the same strain
// (a nearly rate-independent law at a vertex) the split of slip among them, and with it their
// mu and r_s, is not determined to the precision a tolerance asks for. Where the split is
// determined, a CRSS error of a slipping system shows in its resolved shear (it slips at
// r ~ 1), and an idle system's CRSS hardens with the slipping systems' slip at their rates.
template <int N>
typename Extrapolation<N>::VecN Extrapolation<N>::system_errors(const Phase<N>& phase,
                                                                const Vec6& stress,
                                                                const VecN& scale) const {
  return (phase.schmid.transpose() * stress).cwiseAbs().cwiseQuotient(scale);
}

// Whether |tau| of each system grows or falls at a state under L: d|tau|/dt = sign(tau) P : C :
// (D - sum_b gdot_b P_b), the lattice stress rate with the state's slip rates. A rate within the
// rounding of its terms does neither (16 ulp of their sum of magnitudes, the round-off level the
// grain solves take for their residuals): an idle system in a hold, where the slipping systems'
// relaxation nearly balances, has no sign there.
template <int N>
typename Extrapolation<N>::Loading Extrapolation<N>::loading(const Phase<N>& phase,
                                                             const GrainState<N>& s,
                                                             const Mat3& velocity_gradient) {
  constexpr double kEps = std::numeric_limits<double>::epsilon();
  const Vec6 strain_rate = detail::lattice_kinematics(s.orientation, velocity_gradient).strain_rate;
  const VecN elastic = phase.schmid.transpose() * (phase.stiffness * strain_rate);
  const VecN plastic = phase.interaction * s.rate;
  const VecN terms = elastic.cwiseAbs() + phase.interaction.cwiseAbs() * s.rate.cwiseAbs();
  const VecN tau = phase.schmid.transpose() * s.stress;
  Loading out;
  // (|tau| grows from zero whichever way tau moves: its right derivative there is |dtau/dt|.)
  out.growth = (elastic - plastic).cwiseProduct(tau.cwiseSign());
  for (int a = 0; a < phase.slip_count; ++a)
    if (tau(a) == 0.0) out.growth(a) = std::abs(elastic(a) - plastic(a));
  out.rounding = 16.0 * kEps * terms;
  if (phase.pressure_sensitive) add_strength_change(phase, s, strain_rate, tau, out);
  return out;
}

// A pressure-sensitive system loads as r = |tau| / (mu f_n) grows, and its strength moves with
// the normal stress on its plane: f_n d(|tau| / f_n)/dt = d|tau|/dt - |tau| / f_n df_n/dt, with
// df_n/dt = -M : C : (D - sum_b gdot_b P_b). In a reversal under confinement an idle system can
// turn to slip while its |tau| falls; on |tau| alone that turn went unseen (two FCC grains under
// 300 MPa, rate-independent, reversed: 18 times the tolerance at 1e-7, 0.48 with it). An open
// plane (f_n <= 0) carries no shear: it neither loads nor unloads.
template <int N>
void Extrapolation<N>::add_strength_change(const Phase<N>& phase, const GrainState<N>& s,
                                           const Vec6& strain_rate, const VecN& tau, Loading& out) {
  constexpr double kEps = std::numeric_limits<double>::epsilon();
  const VecN fn = detail::normal_traction(phase, s.stress);
  const VecN normal_elastic = phase.c_normal_dyad.transpose() * strain_rate;
  const VecN normal_plastic = phase.normal_interaction * s.rate;
  const VecN normal_terms =
      normal_elastic.cwiseAbs() + phase.normal_interaction.cwiseAbs() * s.rate.cwiseAbs();
  for (int a = 0; a < phase.slip_count; ++a) {
    if (!(fn(a) > 0.0)) {
      out.growth(a) = 0.0;
      continue;
    }
    const double ratio = std::abs(tau(a)) / fn(a);
    out.growth(a) += ratio * (normal_elastic(a) - normal_plastic(a));
    out.rounding(a) += 16.0 * kEps * ratio * normal_terms(a);
  }
}

// Whether a system of grain g switched between elastic and slipping in the step from `start`:
// it slips (a non-zero rate) at the end of one of the `order` solutions, or in their combination
// (`combined`), and not at the start, or the other way round, or it slips at both in opposite
// senses (a reversal inside the step).
// The combination is what sees a system stop inside the step while every solution ends on its
// slipping side: their rates fall towards zero from one solution to the next (-1.9e-5 at the
// start, -6.5e-6 and -3.7e-7 /s after one and two substeps) and the combination passes zero
// (+5.7e-6). Each solution pins the system's resolved shear at its flow stress, so they agree
// with each other to 1e-10 of the CRSS, while the true path has stopped and unloaded
// elastically: 1.6e-5 of the CRSS off (a prismatic grain of
// inputs/extreme/crystal_hcp_families.yaml, tau0 = 0.163 MPa, tolerance 1e-8).
template <int N>
bool Extrapolation<N>::switches_phase(const Phase<N>& phase, const GrainState<N>& start, size_t g,
                                      int order, const GrainState<N>& combined) const {
  const auto differs_from_start = [&](const VecN& rate) {
    for (int a = 0; a < phase.slip_count; ++a)
      if ((rate(a) > 0.0) != (start.rate(a) > 0.0) || (rate(a) < 0.0) != (start.rate(a) < 0.0))
        return true;
    return false;
  };
  for (int j = 0; j < order; ++j)
    if (differs_from_start(solutions_[static_cast<size_t>(j)][g].rate)) return true;
  return differs_from_start(combined.rate);
}

// The error of an idle system whose |tau| turned to grow inside the step (every sample found it
// elastic), per system over the CRSS; zero for the others. An idle system sits on its subloading
// surface (r_s follows r down, (3.12)), so from the turn on it slips, and the step, elastic
// throughout, let its |tau| grow by the part after the turn: with d|tau|/dt falling at the start
// (g0 < 0) and growing at the end (g1 > 0), linear in between, that part is g1^2 dt /
// (2 (g1 - g0)), an upper bound on the error (slip would have held |tau| lower). It falls like
// the square of the step's part after the turn, so the step shrinks towards the turn at the
// clock's order. `start_l` and `end_l`: the L each state is loaded by (the combinations' L of
// this step and of the one before: a turn is seen once, where the sign changes from one step's
// end to the next's). Measured without it on the prismatic case of the same scene: 3e-7 ...
// 1.3e-6 of the CRSS off at 1e-8; docs/integrators.md has the readings not taken.
template <int N>
typename Extrapolation<N>::VecN Extrapolation<N>::turn_errors(const Phase<N>& phase,
                                                              const GrainState<N>& start,
                                                              const GrainState<N>& combined,
                                                              const Mat3& start_l,
                                                              const Mat3& end_l, double dt) {
  const int n = phase.slip_count;
  VecN error = VecN::Zero(n);
  const Loading at_start = loading(phase, start, start_l);
  const Loading at_end = loading(phase, combined, end_l);
  for (int a = 0; a < n; ++a) {
    if (combined.rate(a) != 0.0 || !at_start.unloading(a) || !at_end.loading(a)) continue;
    const double g0 = at_start.growth(a), g1 = at_end.growth(a);
    error(a) = g1 * g1 * dt / (2.0 * (g1 - g0));
  }
  return error.cwiseQuotient(yield_scale(phase, start));
}

// The solutions' L combined like the grains' states (with mixed control they differ between
// the solutions): L at the step's end to the combination's order.
template <int N>
Mat3 Extrapolation<N>::combined_velocity_gradient(int order) const {
  const auto k = static_cast<size_t>(order);
  std::array<Mat3, integrators::kMaxExtrapolationOrder> l;
  for (size_t j = 0; j < l.size(); ++j)  // (unused rows: the finest, kept finite)
    l[j] = solution_macros_[std::min(j, k - 1)].velocity_gradient;
  return integrators::extrapolate_implicit_euler(l, order).best;
}

// The macroscopic state of the combination: F extrapolated like the grains, L as combined
// (combined_velocity_gradient), the strain from F, the stress averaged anew.
template <int N>
void Extrapolation<N>::combine_macro(int order, const Mat3& velocity_gradient,
                                     const GrainSweep<N>& grains) {
  const auto k = static_cast<size_t>(order);
  std::array<Mat3, integrators::kMaxExtrapolationOrder> f, strain;
  for (size_t j = 0; j < f.size(); ++j) {  // (unused rows: the finest, kept finite)
    const MacroState& m = solution_macros_[std::min(j, k - 1)];
    f[j] = m.deformation_gradient, strain[j] = m.strain;
  }
  extrapolated_macro_ = solution_macros_[0];  // time and segment: the same in every solution
  extrapolated_macro_.deformation_gradient = integrators::extrapolate_implicit_euler(f, order).best;
  extrapolated_macro_.velocity_gradient = velocity_gradient;
  extrapolated_macro_.strain = grains.phase().kinematics == Kinematics::small_strain
                                   ? integrators::extrapolate_implicit_euler(strain, order).best
                                   : log_strain(extrapolated_macro_.deformation_gradient);
  extrapolated_macro_.stress = symmetric_from_mandel(grains.average_stress(grains.trial()));
}

// What the error estimate resolves (as for the contact point), the extrapolated one or
// backward Euler's (whose rates are the slip increments over their steps): the grains' states
// are exact to a few ulps of r (at most r_hat), to their flow-rule tolerance and, under mixed
// control, to the free-stress error the step's solves were accepted with (at most the free
// stresses' tolerance, often far below it); that is an error of the stress, and the estimate
// divides the stress by the yield scale of the system that decides it (`deciding_scale`, at the
// step's start), so it enters over that scale. The estimate's weights amplify the sum
// (estimate_noise_gain). (A bound from the tolerance and the laws' mu_s and mu_k instead is
// 100 times too fine where the CRSS starts at 0.01 mu_s tau0, and too coarse where the free
// stresses are met far within their tolerance: there an estimate flat at the stresses'
// round-off was refused 20-30 times down to the time's resolution, or a reference that runs
// was stopped.)
template <int N>
double Extrapolation<N>::resolution(const Phase<N>& phase, const AggregateOptions& opt,
                                    double free_stress_error, double deciding_scale) {
  constexpr double kEps = std::numeric_limits<double>::epsilon();
  double largest_ratio = 1.0;
  for (const auto& law : phase.laws)
    largest_ratio = std::max(largest_ratio, law.parameters().overstress.r_hat);
  const double mixed = deciding_scale > 0.0 ? free_stress_error / deciding_scale : 0.0;
  return integrators::estimate_noise_gain(opt.order) *
         (opt.grain.tolerance + mixed + 4.0 * kEps * (1.0 + largest_ratio));
}

#define SUBSLIP_INSTANTIATE_EXTRAPOLATION(N) template class Extrapolation<N>;

SUBSLIP_FOR_EACH_SLIP_COUNT(SUBSLIP_INSTANTIATE_EXTRAPOLATION)

}  // namespace subslip::crystal::aggregate_parts
