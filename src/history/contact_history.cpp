// The history driver of a contact point (contact_history.hpp): every step an update of a
// point::ContactPoint.
#include "subslip/history/contact_history.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>
#include <utility>

#include "subslip/integrators/extrapolation.hpp"
#include "subslip/integrators/inner_tolerance.hpp"
#include "subslip/integrators/step_control.hpp"

namespace subslip::history {

using contact::ContactState;
using contact::Segment;
using contact::StepAttempt;
using contact::Vec2;

namespace {

// What a user needs to find a failed step: when, how far it was cut, why, and the state.
std::string failure_message(const ContactState& s, int cutbacks, double dt,
                            const std::string& why) {
  std::ostringstream msg;
  msg << "contact step failed at time " << s.time << " after " << cutbacks
      << " cutbacks (dt = " << dt << "): " << why << "; state: mu = " << s.law.mu << ", r = " << s.r
      << ", r_s = " << s.law.r_s << ", f_t = " << s.traction_t.norm() << ", f_n = " << s.traction_n;
  return msg.str();
}

// The viscoplastic sliding velocity of a state, as a vector along its tangential traction.
Vec2 sliding_velocity(const ContactState& s, double speed) {
  const double ft = s.traction_t.norm();
  return ft > 0.0 ? Vec2(s.traction_t * (speed / ft)) : Vec2::Zero();
}

// One update of `point` from s over dt: tangential slip du_t, normal traction fn1 at the end.
point::ContactUpdate update_point(const point::ContactPoint& point, const ContactState& s,
                                  const Vec2& du_t, double fn1, double dt) {
  return point.update(s, point::ContactStep{du_t, fn1, dt});
}

}  // namespace

double effective_residual_tolerance(const IntegratorOptions& opt) {
  return integrators::residual_tolerance_for(opt.residual_tolerance, opt.residual_follows_tolerance,
                                             opt.tolerance);
}

point::ContactParameters point_parameters(const contact::ContactModel& model,
                                          const IntegratorOptions& opt) {
  point::ContactParameters p;
  p.law = model.law;
  p.stiffness = model.stiffness;
  p.residual_tolerance = effective_residual_tolerance(opt);
  p.method = opt.method;
  p.tangent = false;
  return p;
}

namespace {

// What the steps of a run carry besides the state: nothing, or the sensitivities to the law's
// constants (updated by each accepted update, left where an update fails).
struct NoSensitivity {
  point::ContactUpdate update(const point::ContactPoint& point, const ContactState& s,
                              const Vec2& du_t, double fn1, double dt) {
    return update_point(point, s, du_t, fn1, dt);
  }
};
struct CarriedSensitivity {
  contact::ContactSensitivity value;
  point::ContactUpdate update(const point::ContactPoint& point, const ContactState& s,
                              const Vec2& du_t, double fn1, double dt) {
    return point.update(s, point::ContactStep{du_t, fn1, dt}, value);
  }
};

// Takes the piece of length dt starting t_local into the segment whole, or, where its update
// fails, as its two halves (recursively, at most opt.max_cutbacks deep: no allocation).
template <class Carry>
void advance_piece(const point::ContactPoint& point, const IntegratorOptions& opt,
                   const Segment& seg, double fn_start, double dt, int depth, ContactState& s,
                   double& t_local, StepStats& stats, Carry& carry) {
  const Vec2 du = seg.velocity * dt;
  const double fn1 =
      contact::normal_traction_at(seg, point.parameters().stiffness, fn_start, t_local + dt);
  const point::ContactUpdate a = carry.update(point, s, du, fn1, dt);
  stats.iterations += a.report.iterations;
  if (a.report.ok) {
    s = a.state;
    t_local += dt;
    ++stats.substeps;
    return;
  }
  if (depth >= opt.max_cutbacks) throw StepFailure(failure_message(s, depth, dt, a.report.why));
  ++stats.cutbacks;
  for (int half = 0; half < 2; ++half)
    advance_piece(point, opt, seg, fn_start, 0.5 * dt, depth + 1, s, t_local, stats, carry);
}

template <class Carry>
ContactState advance_carrying(const point::ContactPoint& point, const IntegratorOptions& opt,
                              const ContactState& s0, const Segment& seg, double fn_start,
                              double t_in_segment, double dt, StepStats& stats, Carry& carry) {
  ContactState s = s0;
  double t_local = t_in_segment;
  stats = {};
  stats.substeps = 0;
  advance_piece(point, opt, seg, fn_start, dt, 0, s, t_local, stats, carry);
  return s;
}

}  // namespace

ContactState advance(const point::ContactPoint& point, const IntegratorOptions& opt,
                     const ContactState& s0, const Segment& seg, double fn_start,
                     double t_in_segment, double dt, StepStats& stats) {
  NoSensitivity none;
  return advance_carrying(point, opt, s0, seg, fn_start, t_in_segment, dt, stats, none);
}

namespace {

// The sliding velocities at the ends of one implicit (backward Euler) step from s0 to s1, and
// the unit of its error: dt/2 alpha_t / (f_n mu), so that error(|change of velocity|) is dt/2
// |change of df_t/dt| in units of the yield traction (of the loading ratio r). The elastic part
// alpha_t v of the traction rate is constant within a segment, so only the viscoplastic sliding
// velocity contributes.
//
// Where the start velocity comes from matters. For the rate-dependent forms it is the end
// velocity ds/dt of the previous implicit step: the law's rate at s0 is the same quantity in
// exact arithmetic, but near r_hat the rate is so steep in r that the flow-rule residual alone
// (1e-12 in r) moves it by more than the change being measured, and steady sliding at impact
// speed would crawl. For the rate-independent form the sliding velocity is set by this step's
// loading (consistency), and the forward-Euler multiplier at s0 gives it.
struct StepSliding {
  Vec2 start = Vec2::Zero(), end = Vec2::Zero();
  double half_dt_alpha = 0.0, yield = 0.0;  // yield 0: an open contact, nothing to resolve
  // (speed times factor, in local_error's order of operations: factor 1 is exact)
  double error(double speed, double factor = 1.0) const {
    return yield > 0.0 ? half_dt_alpha * speed * factor / yield : 0.0;
  }
};

StepSliding step_sliding(const point::ContactPoint& point, const ContactState& s0,
                         const ContactState& s1, const Vec2& du_t, double fn1, double dt) {
  const law::SubloadingFrictionLaw& law = point.law();
  const contact::ContactStiffness& c = point.parameters().stiffness;
  StepSliding out;
  out.yield = s1.traction_n * s1.law.mu;
  if (!(out.yield > 0.0)) return out;
  // (f_n(end) = s1.traction_n = fn1 > 0 here: an open step has no yield traction.)
  const double start_speed = law.is_rate_independent()
                                 ? contact::rate_independent_slip(law, c, s0, du_t, fn1, dt) / dt
                                 : s0.vp_rate;
  out.start = sliding_velocity(s0, start_speed);
  out.end = sliding_velocity(s1, s1.vp_rate);
  out.half_dt_alpha = 0.5 * dt * c.alpha_t;
  return out;
}

// Backward Euler's own local error: dt/2 |df_t/dt(end) - df_t/dt(start)| (step_sliding).
double local_error(const point::ContactPoint& point, const ContactState& s0, const ContactState& s1,
                   const Vec2& du_t, double fn1, double dt) {
  const StepSliding v = step_sliding(point, s0, s1, du_t, fn1, dt);
  return v.error((v.end - v.start).norm());
}

// Backward Euler's own estimate (local_error) filtered through the traction's Jacobian at the
// step's end, as Shampine filters it for stiff problems: (I + dt J)^-1 e. The Jacobian,
// -alpha_t [v_p' n n^T + v_p / |f_t| (I - n n^T)], relaxes the traction's magnitude through the
// flow rule (lambda = -d(df_t/dt)/df_t) and its direction at alpha_t v_p / |f_t|, so the estimate
// has a radial part, filtered at lambda, and a part of the direction, filtered at the direction's
// rate (below); in 1-D, where the direction's part is zero, it is local_error filtered at lambda.
// Where the traction relaxes onto a state the step resolves (a hold: the end is the same for any
// long step) lambda dt is large and the radial part vanishes; where the sliding rate at the start
// is lost in a transient much shorter than the step while the loading moves the traction on (the
// first step of a reversal from steady sliding), lambda at the end is small and the estimate
// stays: the extrapolated solutions, all longer than the transient, agree there and see nothing.
double filtered_local_error(const point::ContactPoint& point, const ContactState& s0,
                            const ContactState& s1, const Vec2& du_t, double fn1, double dt) {
  const law::SubloadingFrictionLaw& law = point.law();
  const StepSliding v = step_sliding(point, s0, s1, du_t, fn1, dt);
  const double e = v.error((v.end - v.start).norm());
  if (!(e > 0.0) || !(s1.vp_rate > 0.0)) return e;
  // Sliding under the rate-independent form holds r = r_s (consistency): the traction relaxes
  // onto the flow rule at once (lambda infinite), and the filter leaves nothing. A step that
  // ends sticking keeps the estimate (above), and so does a switch inside the step (the
  // extrapolated step's own check).
  if (law.is_rate_independent()) return 0.0;
  const double slip = s1.vp_slip - s0.vp_slip;
  const auto g = law.flow_residual(s1.r, s1.law.r_s, slip, dt);
  if (!g.admissible || !(g.d_slip < 0.0)) return e;
  // G(r, slip) = 0 at the end: d(slip rate)/dr = -G_r / (G_slip dt), and f_t = f_n mu r.
  const double rate_per_r = -g.d_r / (g.d_slip * dt);
  const double alpha_t = point.parameters().stiffness.alpha_t;
  const double lambda = alpha_t * rate_per_r / (fn1 * s1.law.mu);
  const double ft1 = s1.traction_t.norm();
  if (!(ft1 > 0.0)) return e;  // (no direction to filter along)
  const Vec2 n1 = s1.traction_t / ft1;
  const double lambda_direction = alpha_t * s1.vp_rate / ft1;
  const double radial = v.error(std::abs((v.end - v.start).dot(n1)));
  // The direction's error: the traction turns from n0 to n1 while it slides, at up to the larger
  // of the two rates (a contact that starts almost elastic and yields inside the step slides at
  // the end's rate through the rest of the turn, which the ends' velocities alone, then along n1,
  // do not show). |n0 x n1| is zero from rest and in 1-D.
  const double ft0 = s0.traction_t.norm();
  const double turn =
      ft0 > 0.0 ? std::abs(s0.traction_t.x() * n1.y() - s0.traction_t.y() * n1.x()) / ft0 : 0.0;
  const double direction = v.error(std::max(v.start.norm(), v.end.norm()), turn);
  const double radial_filtered = lambda > 0.0 ? radial / (1.0 + dt * lambda) : radial;
  return std::hypot(radial_filtered, direction / (1.0 + dt * lambda_direction));
}

// The state variables an extrapolated step combines; the rest (time, slip, f_n) is kinematics,
// the same in every solution of the step.
using Combined = Eigen::Matrix<double, 6, 1>;

Combined combined_part(const ContactState& s) {
  Combined v;
  v << s.traction_t, s.law.mu, s.law.r_s, s.vp_slip, s.vp_rate;
  return v;
}

// The extrapolated state: `kinematics` (the one-step solution) with the combined variables
// `v`, r recomputed from them. The combination can leave the admissible set only at the order
// of its error; where it does the constraint is restored (r_s <= r, r_s < 1 for the cot form,
// which a step from r_s >= 1 cannot leave; rates >= 0), and r >= r_hat or mu <= 0 fail the step.
StepAttempt extrapolated_state(const point::ContactPoint& point, ContactState kinematics,
                               const Combined& v, const ContactState& finest) {
  ContactState& s = kinematics;
  s.traction_t = v.head<2>();
  s.law.mu = v(2);
  s.law.r_s = v(3);
  s.vp_slip = v(4);
  s.vp_rate = std::max(v(5), 0.0);
  s.r =
      s.traction_n > 0.0 && s.law.mu > 0.0 ? s.traction_t.norm() / (s.traction_n * s.law.mu) : 0.0;
  if (!(s.law.r_s < 1.0) && finest.law.r_s < 1.0) s.law.r_s = finest.law.r_s;
  s.law.r_s = std::clamp(s.law.r_s, 0.0, s.r);
  StepAttempt out{s, 0, true, {}};
  out.why = point.admissibility_violation(s);
  out.ok = out.why.empty();
  return out;
}

// The extrapolated error estimate |best - second| (extrapolation.hpp) in units of the yield:
// the traction over f_n mu, mu relative, and r_s.
double extrapolation_error(const Combined& difference, const ContactState& s) {
  const double yield = s.traction_n * s.law.mu;
  const double traction = yield > 0.0 ? difference.head<2>().norm() / yield : 0.0;
  return std::max({traction, std::abs(difference(2)) / s.law.mu, std::abs(difference(3))});
}

// Whether a substep ending in `after` switched the contact's phase relative to the step's
// start `s0`: it ends sticking where the step started sliding or the other way round, or it
// ends sliding against the direction the step started sliding in (a reversal through zero
// traction, sliding, sticking and sliding back, inside the substep).
bool switches_phase(const ContactState& s0, const ContactState& after) {
  const bool sliding = after.vp_rate > 0.0, was_sliding = s0.vp_rate > 0.0;
  return sliding != was_sliding ||
         (sliding && was_sliding && after.traction_t.dot(s0.traction_t) < 0.0);
}

struct ExtrapolatedStep {
  StepAttempt attempt;
  double error = 0.0;
};

// What the error estimate resolves: the states it compares (the extrapolated estimate's), or
// whose slip increments over their steps give the rates it compares (backward Euler's), are
// exact to a few ulps of r (at most r_hat) and to the flow-rule tolerance (|dG/dr| >= 1: a
// residual delta leaves at most delta in r), and the estimate's weights amplify that
// (estimate_noise_gain).
double estimate_resolution(const law::SubloadingFrictionLaw& law, const IntegratorOptions& opt) {
  constexpr double kEps = std::numeric_limits<double>::epsilon();
  const double largest_ratio = std::max(1.0, law.parameters().overstress.r_hat);
  return integrators::estimate_noise_gain(opt.order) *
         (effective_residual_tolerance(opt) + 4.0 * kEps * (1.0 + largest_ratio));
}

// A segment's prescribed normal traction over time into it (linear: a ramp to a traction, or a
// normal velocity against the normal stiffness), and the time it crosses zero inside the
// segment, where the contact opens or closes. That crossing is a kink of the loading that a step
// across it steps over: a step that ends open computes no slip for any part of it, so the
// sliding before the opening inside the step (and the softening of mu by it) is lost, and every
// extrapolated solution of the step, ending open too, agrees with the others. The adaptive
// steps end on it (a stop of the clock), where the traction is exactly zero.
struct NormalLoad {
  const Segment& seg;
  contact::NormalRamp ramp;
  double crossing = -1.0;  // time into the segment, or < 0 where it does not cross zero

  // An affine f_n whose zero lies inside the segment changes sign there.
  NormalLoad(const Segment& s, const contact::ContactStiffness& c, double fn_start)
      : seg(s), ramp(contact::normal_ramp(s, c, fn_start)) {
    if (ramp.rate != 0.0 && ramp.zero > 0.0 && ramp.zero < seg.duration) crossing = ramp.zero;
  }
  double at(double t) const { return ramp.at(t); }
};

// One step of the extrapolated integrator from s0 at time t0 into the segment to t1: backward
// Euler with 1, 2, .., order substeps, combined (integrators/extrapolation.hpp).
ExtrapolatedStep extrapolated_step(const point::ContactPoint& point, const IntegratorOptions& opt,
                                   const NormalLoad& normal, const ContactState& s0, double t0,
                                   double t1) {
  const Segment& seg = normal.seg;
  std::array<Combined, integrators::kMaxExtrapolationOrder> solutions;
  ContactState one_step, finest;
  int iterations = 0;
  bool switched = false;  // in any substep of any solution (switches_phase)
  for (int j = 1; j <= opt.order; ++j) {
    ContactState s = s0;
    double t = t0;
    for (int i = 1; i <= j; ++i) {
      const double end = i == j ? t1 : t0 + (t1 - t0) * i / j;
      const double h = end - t;
      point::ContactUpdate a = update_point(point, s, seg.velocity * h, normal.at(end), h);
      iterations += a.report.iterations;
      if (!a.report.ok) return {{s, iterations, false, std::move(a.report.why)}, 0.0};
      switched = switched || switches_phase(s0, a.state);
      s = a.state;
      t = end;
    }
    solutions[static_cast<size_t>(j - 1)] = combined_part(s);
    if (j == 1) one_step = s;
    finest = s;
  }
  const auto e = integrators::extrapolate_implicit_euler(solutions, opt.order);
  ExtrapolatedStep out{extrapolated_state(point, one_step, e.best, finest), 0.0};
  out.attempt.iterations = iterations;
  if (!out.attempt.ok) return out;
  const ContactState& end = out.attempt.state;
  out.error = extrapolation_error(e.best - e.second, end);
  if (opt.order >= 4) {  // the guard against a cancelling last column (guarded_estimate)
    const auto earlier = integrators::earlier_column_estimates(solutions);
    out.error = integrators::guarded_estimate(out.error, extrapolation_error(earlier[0], end),
                                              extrapolation_error(earlier[1], end));
  }
  {
    const double t_from_start = t1 - t0;
    const double fn1 = normal.at(t1);
    out.error = std::max(
        out.error,
        filtered_local_error(point, s0, one_step, seg.velocity * t_from_start, fn1, t_from_start));
  }
  if (switched) {
    // A switch between sticking and sliding inside the step: the solution has a kink there and
    // no error expansion in powers of the step, so the step is judged as a backward Euler step:
    // by the one-substep solution against the two-substep one, and by backward Euler's own
    // estimate, which compares the sliding velocity at the step's start with the one-substep
    // solution's at its end. The second is what sees a switch that every solution steps over:
    // a contact sliding at the start of a reversal whose solutions all end sticking (each
    // evaluates the flow rule only where the traction has already unloaded) agree with each
    // other exactly, while the true path slides on until r falls to r_s. A step with a switch
    // is shortened until both meet the tolerance; it then ends near the switch, and its error
    // is the local error of one first-order step there.
    const double t_from_start = t1 - t0;
    const double fn1 = normal.at(t1);
    out.error = std::max(
        {out.error, extrapolation_error(solutions[0] - solutions[1], out.attempt.state),
         local_error(point, s0, one_step, seg.velocity * t_from_start, fn1, t_from_start)});
  }
  return out;
}

// One segment with adaptive steps. The first step is the segment's first increment; the step
// then follows the error estimate, and a failed step (no convergence, inadmissible state) is
// halved like a cutback.
void run_segment_adaptive(const point::ContactPoint& point, const IntegratorOptions& opt,
                          const Segment& seg, int index, double t_start, ContactState& s,
                          RunStats& stats, const OutputCallback& on_output) {
  const NormalLoad normal(seg, point.parameters().stiffness, s.traction_n);
  const bool extrapolated = opt.order >= 2;
  // Backward Euler's resolution is a bound (a rate resolved far better than the flow-rule
  // tolerance leaves the estimate far below it): its floor is an estimate that stopped falling.
  const integrators::EstimateNoise noise{estimate_resolution(point.law(), opt), !extrapolated,
                                         !extrapolated};
  integrators::AdaptiveSegment clock(seg.duration, contact::increment_lengths(seg).front(),
                                     opt.tolerance, integrators::estimate_order(opt.order),
                                     integrators::after_accepted_limits(opt.order));
  // The steps end on the output times asked for and on the normal traction's crossing of zero;
  // only the first are written.
  std::vector<double> stops;
  std::vector<bool> written;
  if (seg.output_at_times) {
    stops = seg.output_times;
    written.assign(stops.size(), true);
  }
  if (normal.crossing > 0.0) {
    const auto at = std::lower_bound(stops.begin(), stops.end(), normal.crossing);
    if (at == stops.end() || *at != normal.crossing) {
      written.insert(written.begin() + (at - stops.begin()), false);
      stops.insert(at, normal.crossing);
    }
  }
  if (!stops.empty()) clock.set_stops(stops);
  std::size_t stops_passed = clock.stops_passed();
  for (;;) {
    const double h = clock.step();
    StepAttempt a;
    double error = 0.0;
    if (extrapolated) {
      ExtrapolatedStep e = extrapolated_step(point, opt, normal, s, clock.time(), clock.end_time());
      a = std::move(e.attempt);
      error = e.error;
    } else {
      const Vec2 du = seg.velocity * h;
      const double fn1 = normal.at(clock.end_time());
      point::ContactUpdate u = update_point(point, s, du, fn1, h);
      a = {std::move(u.state), u.report.iterations, u.report.ok, std::move(u.report.why)};
      error = a.ok ? local_error(point, s, a.state, du, fn1, h) : 0.0;
    }
    stats.iterations += a.iterations;
    if (!a.ok || !(error <= opt.tolerance)) {
      a.ok ? ++stats.rejected : ++stats.cutbacks;
      if (!clock.refuse(!a.ok, error, noise)) {
        std::string why = !a.ok                    ? a.why
                          : clock.at_noise_floor() ? clock.noise_floor_message()
                          : clock.estimate_does_not_fall()
                              ? clock.not_falling_message()
                              : "local error estimate stays above the tolerance";
        if (clock.below_time_resolution())
          why = clock.time_resolution_message() + " (last attempt: " + why + ")";
        throw StepFailure(failure_message(s, clock.refusals(), h, why), clock.named_tolerance());
      }
      continue;
    }
    const bool last = clock.last();
    s = a.state;
    clock.accept(error);
    bool at_output = false;  // the step ended on an output time (and maybe the crossing)
    for (; stops_passed < clock.stops_passed(); ++stops_passed)
      at_output = at_output || written[stops_passed];
    // The time of every step's end from the segment's start and the time into it (the output
    // time where the step ends on one): the running sum of thousands of steps drifts by many
    // ulps of the absolute time, which on a steep ramp late in a history (a re-slide 61 min
    // in) is a difference of 1e-6 of mu_s between a run and its reference at "the same" time.
    s.time = t_start + clock.time();
    ++stats.increments;
    ++stats.substeps;
    if (seg.output_at_times) {
      if (at_output) on_output(s, index);
    } else if (last || clock.accepted() % seg.output_every == 0) {
      on_output(s, index);
    }
    if (last) return;
  }
}

}  // namespace

namespace {

// One segment in fixed increments (each cut back where it fails); emit(s, segment) at its
// output increments.
template <class Carry, class Emit>
void run_segment_fixed(const point::ContactPoint& point, const IntegratorOptions& opt,
                       const Segment& seg, int index, double t_start, ContactState& s,
                       RunStats& stats, Carry& carry, const Emit& emit) {
  const double fn_start = s.traction_n;
  const auto dts = contact::increment_lengths(seg);
  const std::vector<double> none;
  const auto steps =
      integrators::fixed_steps(dts, seg.output_at_times ? seg.output_times : none, seg.duration);
  double t_local = 0.0;
  for (const integrators::FixedStep& step : steps) {
    StepStats st;
    s = advance_carrying(point, opt, s, seg, fn_start, t_local, step.length, st, carry);
    t_local = step.end;  // (the running sum of the increments where none is split)
    ++stats.increments;
    stats.substeps += st.substeps;
    stats.iterations += st.iterations;
    stats.cutbacks += st.cutbacks;
    if (seg.output_at_times) {
      if (step.output_time) {
        s.time = t_start + step.end;  // exactly the output time (the sum of steps rounds)
        emit(s, index);
      }
      continue;
    }
    const auto i = static_cast<size_t>(step.increment - 1);
    const bool last = i + 1 == dts.size();
    if (last || (i + 1) % static_cast<size_t>(seg.output_every) == 0) emit(s, index);
  }
}

}  // namespace

RunStats run_history(const contact::ContactModel& model, const std::vector<Segment>& segments,
                     const IntegratorOptions& opt, const OutputCallback& on_output) {
  const auto start = std::chrono::steady_clock::now();
  const point::ContactPoint point(point_parameters(model, opt));
  RunStats stats;
  ContactState s = contact::initial_state(model);
  on_output(s, -1);
  const bool adaptive = opt.tolerance > 0.0 && opt.method == contact::Method::implicit;
  NoSensitivity none;
  // Where each segment starts in time, from the durations (not the sum of the steps, which
  // rounds): output times are that plus their time into the segment.
  double t_start = 0.0;
  for (size_t k = 0; k < segments.size(); t_start += segments[k++].duration) {
    if (adaptive) {
      run_segment_adaptive(point, opt, segments[k], static_cast<int>(k), t_start, s, stats,
                           on_output);
    } else {
      run_segment_fixed(point, opt, segments[k], static_cast<int>(k), t_start, s, stats, none,
                        on_output);
    }
  }
  stats.wall_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

RunStats run_history(const contact::ContactModel& model, const std::vector<Segment>& segments,
                     const IntegratorOptions& opt, bool initial_mu_is_mu_s,
                     const SensitivityCallback& on_output) {
  if (opt.method != contact::Method::implicit || opt.tolerance > 0.0)
    throw std::invalid_argument(
        "sensitivities need fixed increments of the implicit update (no tolerance)");
  const auto start = std::chrono::steady_clock::now();
  const point::ContactPoint point(point_parameters(model, opt));
  RunStats stats;
  ContactState s = contact::initial_state(model);
  CarriedSensitivity carry{contact::initial_sensitivity(initial_mu_is_mu_s)};
  auto emit = [&](const ContactState& state, int segment) {
    on_output(state, carry.value, segment);
  };
  emit(s, -1);
  double t_start = 0.0;
  for (size_t k = 0; k < segments.size(); t_start += segments[k++].duration)
    run_segment_fixed(point, opt, segments[k], static_cast<int>(k), t_start, s, stats, carry, emit);
  stats.wall_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

}  // namespace subslip::history
