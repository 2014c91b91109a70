#include "subslip/contact/contact_point.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>

#include "subslip/integrators/extrapolation.hpp"
#include "subslip/integrators/scalar_root.hpp"
#include "subslip/integrators/step_control.hpp"

namespace subslip::contact {

namespace {

bool finite(const ContactState& s) {
  return std::isfinite(s.traction_t.x()) && std::isfinite(s.traction_t.y()) &&
         std::isfinite(s.traction_n) && std::isfinite(s.law.mu) && std::isfinite(s.law.r_s) &&
         std::isfinite(s.r) && std::isfinite(s.vp_slip);
}

// The admissible set every integrator must stay in: finite, mu > 0, 0 <= r_s <= r < r_hat.
std::string inadmissible_reason(const law::SubloadingFrictionLaw& law, const ContactState& s) {
  if (!finite(s)) return "non-finite state";
  if (s.law.mu <= 0.0) return "mu <= 0";
  if (s.law.r_s < 0.0) return "r_s < 0";
  if (s.law.r_s > s.r) return "r_s > r";
  if (!law.is_rate_independent() && s.r >= law.parameters().overstress.r_hat) return "r >= r_hat";
  if (law.parameters().subloading.function == law::SubloadingFunction::cot && s.law.r_s >= 2.0)
    return "r_s >= 2 (cot branch)";
  return {};
}

// State with the kinematic part of the increment applied (time, slip, normal traction).
ContactState kinematic_update(const ContactState& s0, const Vec2& du_t, double fn1, double dt) {
  ContactState s = s0;
  s.time += dt;
  s.slip += du_t;
  s.slip_path += du_t.norm();
  s.traction_n = fn1;
  return s;
}

// An open contact (f_n <= 0) transmits no traction: friction state relaxes to r = r_s = 0 and
// mu recovers with time.
StepAttempt open_contact(const law::SubloadingFrictionLaw& law, ContactState s, double dt) {
  s.traction_t.setZero();
  s.law.mu = law.friction_coefficient_after(s.law.mu, 0.0, dt).value;
  s.law.r_s = 0.0;
  s.r = 0.0;
  s.vp_rate = 0.0;
  return {s, 0, true, {}};
}

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

// The lowest loading ratio r = |f_t|/(f_n mu) on the straight traction path of a step, from
// (f0, fn0) at its start to (f1, fn1) at its end; mu_at(l) is mu at the path parameter l. Where
// r < r_s on that path no viscoplastic sliding occurs and (3.12) makes r_s follow r down, so a
// step whose path passes near zero traction (a reversal) must start r_s from this minimum,
// not from r_s0. |f|^2/fn^2 = (a + 2bl + cl^2)/(p + ql)^2 has one stationary point, where
// (cp - bq) l = qa - bp, a minimum when cp - bq > 0; otherwise the minimum is at an end,
// which the callers already cover (r_s0 <= r0, and r_s <= r at the end). mu only scales the
// ratio and changes little over a step, so it is evaluated at that point.
struct PathMinimum {
  double ratio = std::numeric_limits<double>::infinity();
  double at = 0.0;  // path parameter in [0, 1]
};
template <class MuAt>
PathMinimum lowest_ratio_on_path(const Vec2& f0, double fn0, const Vec2& f1, double fn1,
                                 MuAt&& mu_at) {
  if (!(fn0 > 0.0) || !(fn1 > 0.0)) return {};
  const Vec2 df = f1 - f0;
  const double a = f0.squaredNorm(), b = f0.dot(df), c = df.squaredNorm();
  const double p = fn0, q = fn1 - fn0;
  const double den = c * p - b * q;
  if (!(den > 0.0)) return {};
  const double l = std::clamp((q * a - b * p) / den, 0.0, 1.0);
  return {(f0 + l * df).norm() / ((p + l * q) * mu_at(l)), l};
}

}  // namespace

std::vector<double> increment_lengths(const Segment& seg) {
  std::vector<double> dt(static_cast<size_t>(seg.increments));
  double sum = 0.0, h = 1.0;
  for (auto& d : dt) {
    d = h;
    sum += h;
    h *= seg.growth;
  }
  for (auto& d : dt) d *= seg.duration / sum;
  return dt;
}

double normal_traction_at(const Segment& seg, const ContactStiffness& c, double fn_start,
                          double t) {
  if (seg.normal_control == NormalControl::velocity)
    return fn_start + c.alpha_n * seg.normal_velocity * t;
  if (seg.duration <= 0.0) return seg.normal_traction;
  return fn_start + (seg.normal_traction - fn_start) * (t / seg.duration);
}

// lambda of the contact at the start of a step (the law's traction_relaxation_rate with alpha_t).
// Beyond dt = 2/lambda the traction oscillates with a growing amplitude for many steps before it
// leaves the admissible set, so forward Euler refuses such steps (they are cut back).
double traction_relaxation_rate(const law::SubloadingFrictionLaw& law, const ContactStiffness& c,
                                const ContactState& s0) {
  if (!(s0.traction_n > 0.0)) return 0.0;  // open: no traction to relax
  return law.traction_relaxation_rate(c.alpha_t, s0.r, s0.law.r_s, s0.law.mu, s0.traction_n);
}

StepAttempt forward_euler_step(const law::SubloadingFrictionLaw& law, const ContactStiffness& c,
                               const ContactState& s0, const Vec2& du_t, double fn1, double dt,
                               integrators::ExplicitStability stability) {
  ContactState s = kinematic_update(s0, du_t, fn1, dt);
  if (fn1 <= 0.0) return open_contact(law, s, dt);
  const auto& fp = law.parameters().friction;
  const double ft0 = s0.traction_t.norm();
  // Direction of the viscoplastic sliding: the tangential traction (2.39).
  const Vec2 t_f = ft0 > 0.0 ? Vec2(s0.traction_t / ft0) : Vec2::Zero();

  double ds;  // viscoplastic (or plastic) slip of the step
  if (law.is_rate_independent()) {
    // Plastic multiplier (2.44) with the normal traction rate taken from the prescribed normal.
    const double fn0 = s0.traction_n;
    const double mu = s0.law.mu, r = s0.law.r_s;
    const double fn_rate = (fn1 - fn0) / dt;
    const double v_t = t_f.dot(du_t) / dt;
    const double numerator = (c.alpha_t * v_t - r * mu * fn_rate) / fn0 - law.creep_modulus(r, mu);
    const double denominator = law.plastic_modulus(r, mu) + c.alpha_t / fn0;
    ds = (fn0 > 0.0 && numerator > 0.0 && std::isfinite(denominator)) ? numerator / denominator * dt
                                                                      : 0.0;
  } else {
    if (const double lambda = traction_relaxation_rate(law, c, s0);
        stability == integrators::ExplicitStability::refuse_unstable_steps &&
        !(dt * lambda <= 2.0)) {
      std::ostringstream why;
      why << "forward Euler step above its stability limit 2/lambda = " << 2.0 / lambda
          << " (lambda = alpha_t phi_r / (f_n mu) = " << lambda << ")";
      return {s0, 0, false, why.str()};
    }
    ds = dt * law.slip_rate(s0.r, s0.law.r_s);
  }

  s.traction_t = s0.traction_t + c.alpha_t * (du_t - ds * t_f);
  s.law.mu = s0.law.mu + fp.kappa * (1.0 - s0.law.mu / fp.mu_k) * ds +
             fp.xi * (1.0 - s0.law.mu / fp.mu_s) * dt;
  s.r = s.traction_t.norm() / (fn1 * s.law.mu);
  if (ds > 0.0) {
    // Method 2: r_s by forward Euler of (3.11). U(0) is infinite, so the very first slip from
    // r_s = 0 uses the analytical integral (2.28), which is regular there.
    s.law.r_s = s0.law.r_s > 0.0 ? s0.law.r_s + law.subloading_rate(s0.law.r_s) * ds
                                 : law.subloading_ratio_after(0.0, ds).value;
  }
  // (3.12): r_s follows r down whenever no viscoplastic sliding would occur, also inside the
  // step: a reversal that takes the traction through zero leaves r_s = 0 (the next step's
  // slip regrows it). The rate-independent form keeps r_s = r (the slip is set by consistency).
  s.law.r_s = std::min(s.law.r_s, s.r);
  if (law.is_rate_independent()) {
    if (ds <= 0.0) s.law.r_s = s.r;
  } else {
    const double mu0 = s0.law.mu, mu1 = s.law.mu;
    s.law.r_s = std::min(
        s.law.r_s,
        lowest_ratio_on_path(s0.traction_t, s0.traction_n, s.traction_t, fn1, [&](double l) {
          return mu0 + l * (mu1 - mu0);
        }).ratio);
  }
  s.vp_slip = s0.vp_slip + ds;
  s.vp_rate = ds / dt;
  StepAttempt out{s, 0, true, {}};
  out.why = inadmissible_reason(law, s);
  out.ok = out.why.empty();
  return out;
}

StepAttempt implicit_step(const law::SubloadingFrictionLaw& law, const ContactStiffness& c,
                          const ContactState& s0, const Vec2& du_t, double fn1, double dt,
                          double residual_tolerance, ContactTangent* tangent) {
  ContactState s = kinematic_update(s0, du_t, fn1, dt);
  if (tangent) tangent->setZero();
  if (fn1 <= 0.0) return open_contact(law, s, dt);
  const Vec2 trial = s0.traction_t + c.alpha_t * du_t;
  const double ft_trial = trial.norm();
  const auto mu_elastic = law.friction_coefficient_after(s0.law.mu, 0.0, dt);
  const double r_trial = ft_trial / (fn1 * mu_elastic.value);
  // The subloading ratio the step starts from: (3.12) along the elastic predictor, where no
  // sliding occurs while r < r_s. A reversal takes the traction through zero and r_s with it;
  // the slip of the step then regrows r_s from there (3.11), and it can only occur after that
  // point: the flow rule's rate is the slip over the time left (backward Euler on that part).
  const PathMinimum lowest = lowest_ratio_on_path(
      s0.traction_t, s0.traction_n, trial, fn1,
      [&](double l) { return law.friction_coefficient_after(s0.law.mu, 0.0, l * dt).value; });
  const bool dips = lowest.ratio < s0.law.r_s;
  const double rs_start = dips ? lowest.ratio : s0.law.r_s;
  const double slip_time = dips && lowest.at < 1.0 ? (1.0 - lowest.at) * dt : dt;

  if (r_trial <= rs_start || ft_trial == 0.0) {
    // No viscoplastic sliding: the subloading ratio follows r (3.12).
    s.traction_t = trial;
    s.law.mu = mu_elastic.value;
    s.r = r_trial;
    s.law.r_s = std::min(rs_start, r_trial);
    s.vp_rate = 0.0;
    if (tangent) tangent->leftCols<2>() = c.alpha_t * Eigen::Matrix2d::Identity();
    return {s, 0, true, {}};
  }

  // Radial return: f_t = t (ft_trial - alpha_t ds) keeps the trial direction (2.39), so the
  // step reduces to one equation G(ds) = 0 in the slip increment ds, decreasing on
  // [0, ft_trial/alpha_t] from G(0) = r_trial - rs_start > 0 to G(max) < 0.
  auto ratio_at = [&](double ds, double& dr_dds, law::ValueAndSlope& mu) {
    mu = law.friction_coefficient_after(s0.law.mu, ds, dt);
    const double ft = ft_trial - c.alpha_t * ds;
    const double r = ft / (fn1 * mu.value);
    dr_dds = -c.alpha_t / (fn1 * mu.value) - r / mu.value * mu.d_slip;
    return r;
  };
  // The unknown is z = ds^(1/p) (p = 1 except for the power overstress, see slip_exponent).
  const double p = law.slip_exponent();
  auto slip_of = [p](double z) { return p == 1.0 ? z : std::pow(z, p); };
  auto residual = [&](double z) {
    const double ds = slip_of(z);
    double dr;
    law::ValueAndSlope mu;
    const double r = ratio_at(ds, dr, mu);
    const auto rs = law.subloading_ratio_after(rs_start, ds);
    const auto g = law.flow_residual(r, rs.value, ds, slip_time);
    if (!g.admissible) return std::pair{g.value, 0.0};
    const double dds_dz = p == 1.0 ? 1.0 : p * std::pow(z, p - 1.0);
    return std::pair{g.value, (g.d_r * dr + g.d_rs * rs.d_slip + g.d_slip) * dds_dz};
  };
  const double ds_max = ft_trial / c.alpha_t;
  // Start from the previous viscoplastic rate (over a smooth history it is close to the
  // answer); failing that, from the slip that would bring r back to rs_start (the
  // rate-independent answer, which lies on the far side of the root).
  double guess = s0.vp_rate * slip_time;
  if (!(guess > 0.0 && guess < ds_max)) {
    guess = (ft_trial - rs_start * fn1 * mu_elastic.value) / c.alpha_t;
  }
  const auto root =
      safeguarded_newton(residual, 0.0, std::pow(ds_max, 1.0 / p), std::pow(guess, 1.0 / p),
                         residual_tolerance, 4.0 * std::numeric_limits<double>::epsilon(), 1e-300);
  if (!root.converged) return {s, root.iterations, false, "flow rule did not converge"};

  const double ds = slip_of(root.x);
  double dr;
  law::ValueAndSlope mu;
  s.r = ratio_at(ds, dr, mu);
  s.law.mu = mu.value;
  s.traction_t = trial * ((ft_trial - c.alpha_t * ds) / ft_trial);
  s.law.r_s = std::min(law.subloading_ratio_after(rs_start, ds).value, s.r);
  s.vp_slip = s0.vp_slip + ds;
  s.vp_rate = ds / slip_time;  // the end rate of the flow rule
  StepAttempt out{s, root.iterations, true, {}};
  out.why = inadmissible_reason(law, s);
  out.ok = out.why.empty();
  if (tangent && out.ok) {
    // f_t = t (ft_trial - alpha_t ds), t = trial / ft_trial, with ds(ft_trial, f_n) the root of
    // G(r, r_s(ds), ds) = 0 at r = (ft_trial - alpha_t ds) / (f_n mu(ds)).
    const auto rs = law.subloading_ratio_after(rs_start, ds);
    const auto g = law.flow_residual(s.r, rs.value, ds, slip_time);
    const double g_slip = g.d_r * dr + g.d_rs * rs.d_slip + g.d_slip;
    const double dds_dtrial = -g.d_r / (fn1 * mu.value) / g_slip;
    const double dds_dfn = g.d_r * s.r / fn1 / g_slip;
    const Vec2 t = trial / ft_trial;
    const double ft = ft_trial - c.alpha_t * ds;
    const Eigen::Matrix2d tt = t * t.transpose();
    tangent->leftCols<2>() = c.alpha_t * ((ft / ft_trial) * (Eigen::Matrix2d::Identity() - tt) +
                                          (1.0 - c.alpha_t * dds_dtrial) * tt);
    tangent->col(2) = -c.alpha_t * dds_dfn * t;
  }
  return out;
}

ContactState advance(const law::SubloadingFrictionLaw& law, const ContactStiffness& c,
                     const IntegratorOptions& opt, const ContactState& s0, const Segment& seg,
                     double fn_start, double t_in_segment, double dt, StepStats& stats) {
  // The increment is taken whole when possible; a failed piece is replaced by its two halves.
  struct Piece {
    double dt;
    int depth;
  };
  std::vector<Piece> todo{{dt, 0}};
  ContactState s = s0;
  double t_local = t_in_segment;
  stats = {};
  stats.substeps = 0;
  while (!todo.empty()) {
    const Piece p = todo.back();
    todo.pop_back();
    const Vec2 du = seg.velocity * p.dt;
    const double fn1 = normal_traction_at(seg, c, fn_start, t_local + p.dt);
    StepAttempt a = opt.method == Method::implicit
                        ? implicit_step(law, c, s, du, fn1, p.dt, opt.residual_tolerance)
                        : forward_euler_step(law, c, s, du, fn1, p.dt);
    stats.iterations += a.iterations;
    if (a.ok) {
      s = a.state;
      t_local += p.dt;
      ++stats.substeps;
      continue;
    }
    if (p.depth >= opt.max_cutbacks) {
      throw StepFailure(failure_message(s, p.depth, p.dt, a.why));
    }
    ++stats.cutbacks;
    todo.push_back({0.5 * p.dt, p.depth + 1});
    todo.push_back({0.5 * p.dt, p.depth + 1});
  }
  return s;
}

ContactState initial_state(const ContactModel& model) {
  ContactState s;
  s.law = model.initial_law_state;
  s.traction_n = model.initial_normal_traction;
  s.r = 0.0;
  s.law.r_s = std::min(s.law.r_s, s.r);
  return s;
}

namespace {

// Local error of one implicit (backward Euler) step from s0 to s1: dt/2 |df_t/dt(end) -
// df_t/dt(start)|, in units of the yield traction f_n mu (so in units of the loading ratio r).
// The elastic part alpha_t v of the traction rate is constant within a segment, so only the
// viscoplastic sliding velocity contributes.
//
// Where the start velocity comes from matters. For the rate-dependent forms it is the end
// velocity ds/dt of the previous implicit step: the law's rate at s0 is the same quantity in
// exact arithmetic, but near r_hat the rate is so steep in r that the flow-rule residual alone
// (1e-12 in r) moves it by more than the change being measured, and steady sliding at impact
// speed would crawl. For the rate-independent form the sliding velocity is set by this step's
// loading (consistency), and the forward-Euler multiplier at s0 gives it.
double local_error(const law::SubloadingFrictionLaw& law, const ContactStiffness& c,
                   const ContactState& s0, const ContactState& s1, const Vec2& du_t, double fn1,
                   double dt) {
  const double yield = s1.traction_n * s1.law.mu;
  if (!(yield > 0.0)) return 0.0;  // open contact: no traction, nothing to resolve
  const double start_speed = law.is_rate_independent()
                                 ? forward_euler_step(law, c, s0, du_t, fn1, dt).state.vp_rate
                                 : s0.vp_rate;
  const Vec2 change = sliding_velocity(s1, s1.vp_rate) - sliding_velocity(s0, start_speed);
  return 0.5 * dt * c.alpha_t * change.norm() / yield;
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
StepAttempt extrapolated_state(const law::SubloadingFrictionLaw& law, ContactState kinematics,
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
  out.why = inadmissible_reason(law, s);
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

// Whether a step from s0 switched between sticking and sliding: one of its `order` solutions
// ends in the other phase (`sliding`: whether each does).
bool switches_phase(const ContactState& s0,
                    const std::array<bool, integrators::kMaxExtrapolationOrder>& sliding,
                    int order) {
  const bool start = s0.vp_rate > 0.0;
  return std::any_of(sliding.begin(), sliding.begin() + order, [&](bool b) { return b != start; });
}

struct ExtrapolatedStep {
  StepAttempt attempt;
  double error = 0.0;
};

// What the extrapolated estimate resolves: the states it combines are exact to a few ulps of
// r (at most r_hat) and to the flow-rule tolerance (|dG/dr| >= 1: a residual delta leaves at
// most delta in r), and the estimate's weights amplify that (estimate_noise_gain).
double extrapolation_resolution(const law::SubloadingFrictionLaw& law,
                                const IntegratorOptions& opt) {
  constexpr double kEps = std::numeric_limits<double>::epsilon();
  const double largest_ratio = std::max(1.0, law.parameters().overstress.r_hat);
  return integrators::estimate_noise_gain(opt.order) *
         (opt.residual_tolerance + 4.0 * kEps * (1.0 + largest_ratio));
}

// One step of the extrapolated integrator from s0 at time t0 into the segment to t1: backward
// Euler with 1, 2, .., order substeps, combined (integrators/extrapolation.hpp).
ExtrapolatedStep extrapolated_step(const law::SubloadingFrictionLaw& law, const ContactStiffness& c,
                                   const IntegratorOptions& opt, const Segment& seg,
                                   double fn_start, const ContactState& s0, double t0, double t1) {
  std::array<Combined, integrators::kMaxExtrapolationOrder> solutions;
  ContactState one_step, finest;
  int iterations = 0;
  std::array<bool, integrators::kMaxExtrapolationOrder> sliding{};  // at the end, per solution
  for (int j = 1; j <= opt.order; ++j) {
    ContactState s = s0;
    double t = t0;
    for (int i = 1; i <= j; ++i) {
      const double end = i == j ? t1 : t0 + (t1 - t0) * i / j;
      const double h = end - t;
      const StepAttempt a =
          implicit_step(law, c, s, seg.velocity * h, normal_traction_at(seg, c, fn_start, end), h,
                        opt.residual_tolerance);
      iterations += a.iterations;
      if (!a.ok) return {{s, iterations, false, a.why}, 0.0};
      s = a.state;
      t = end;
    }
    solutions[static_cast<size_t>(j - 1)] = combined_part(s);
    sliding[static_cast<size_t>(j - 1)] = s.vp_rate > 0.0;
    if (j == 1) one_step = s;
    finest = s;
  }
  const auto e = integrators::extrapolate_implicit_euler(solutions, opt.order);
  ExtrapolatedStep out{extrapolated_state(law, one_step, e.best, finest), 0.0};
  out.attempt.iterations = iterations;
  if (!out.attempt.ok) return out;
  const ContactState& end = out.attempt.state;
  out.error = extrapolation_error(e.best - e.second, end);
  if (opt.order >= 4) {  // the guard against a cancelling last column (guarded_estimate)
    const auto earlier = integrators::earlier_column_estimates(solutions);
    out.error = integrators::guarded_estimate(out.error, extrapolation_error(earlier[0], end),
                                              extrapolation_error(earlier[1], end));
  }
  if (switches_phase(s0, sliding, opt.order)) {
    // A switch between sticking and sliding inside the step: the solution has a kink there and
    // no error expansion in powers of the step, so the estimate is backward Euler's own (one
    // substep against two): a step with a switch is shortened until that meets the tolerance.
    out.error =
        std::max(out.error, extrapolation_error(solutions[0] - solutions[1], out.attempt.state));
  }
  return out;
}

// One segment with adaptive steps. The first step is the segment's first increment; the step
// then follows the error estimate, and a failed step (no convergence, inadmissible state) is
// halved like a cutback.
void run_segment_adaptive(const law::SubloadingFrictionLaw& law, const ContactModel& model,
                          const IntegratorOptions& opt, const Segment& seg, int index,
                          double t_start, ContactState& s, RunStats& stats,
                          const OutputCallback& on_output) {
  const ContactStiffness& c = model.stiffness;
  const double fn_start = s.traction_n;
  const bool extrapolated = opt.order >= 2;
  const double resolution = extrapolated ? extrapolation_resolution(law, opt) : 0.0;
  integrators::AdaptiveSegment clock(seg.duration, increment_lengths(seg).front(), opt.tolerance,
                                     integrators::estimate_order(opt.order),
                                     integrators::after_accepted_limits(opt.order));
  if (seg.output_at_times) clock.set_stops(seg.output_times);
  for (;;) {
    const double h = clock.step();
    StepAttempt a;
    double error = 0.0;
    if (extrapolated) {
      ExtrapolatedStep e =
          extrapolated_step(law, c, opt, seg, fn_start, s, clock.time(), clock.end_time());
      a = std::move(e.attempt);
      error = e.error;
    } else {
      const Vec2 du = seg.velocity * h;
      const double fn1 = normal_traction_at(seg, c, fn_start, clock.end_time());
      a = implicit_step(law, c, s, du, fn1, h, opt.residual_tolerance);
      error = a.ok ? local_error(law, c, s, a.state, du, fn1, h) : 0.0;
    }
    stats.iterations += a.iterations;
    if (!a.ok || !(error <= opt.tolerance)) {
      a.ok ? ++stats.rejected : ++stats.cutbacks;
      if (!clock.refuse(!a.ok, error, resolution)) {
        std::string why = !a.ok ? a.why
                          : clock.at_noise_floor()
                              ? clock.noise_floor_message()
                              : "local error estimate stays above the tolerance";
        if (clock.below_time_resolution())
          why = clock.time_resolution_message() + " (last attempt: " + why + ")";
        throw StepFailure(failure_message(s, clock.refusals(), h, why));
      }
      continue;
    }
    const bool last = clock.last();
    s = a.state;
    const bool stop = clock.accept(error);
    ++stats.increments;
    ++stats.substeps;
    if (seg.output_at_times) {
      if (stop) {
        s.time = t_start + clock.time();  // exactly the output time (the sum of steps rounds)
        on_output(s, index);
      }
    } else if (last || clock.accepted() % seg.output_every == 0) {
      on_output(s, index);
    }
    if (last) return;
  }
}

}  // namespace

RunStats run_history(const ContactModel& model, const std::vector<Segment>& segments,
                     const IntegratorOptions& opt, const OutputCallback& on_output) {
  const auto start = std::chrono::steady_clock::now();
  const law::SubloadingFrictionLaw law(model.law);
  RunStats stats;
  ContactState s = initial_state(model);
  on_output(s, -1);
  const bool adaptive = opt.tolerance > 0.0 && opt.method == Method::implicit;
  // Where each segment starts in time, from the durations (not the sum of the steps, which
  // rounds): output times are that plus their time into the segment.
  double t_start = 0.0;
  for (size_t k = 0; k < segments.size(); t_start += segments[k++].duration) {
    const Segment& seg = segments[k];
    if (adaptive) {
      run_segment_adaptive(law, model, opt, seg, static_cast<int>(k), t_start, s, stats, on_output);
      continue;
    }
    const double fn_start = s.traction_n;
    const auto dts = increment_lengths(seg);
    const std::vector<double> none;
    const auto steps =
        integrators::fixed_steps(dts, seg.output_at_times ? seg.output_times : none, seg.duration);
    double t_local = 0.0;
    for (const integrators::FixedStep& step : steps) {
      StepStats st;
      s = advance(law, model.stiffness, opt, s, seg, fn_start, t_local, step.length, st);
      t_local = step.end;  // (the running sum of the increments where none is split)
      ++stats.increments;
      stats.substeps += st.substeps;
      stats.iterations += st.iterations;
      stats.cutbacks += st.cutbacks;
      if (seg.output_at_times) {
        if (step.output_time) {
          s.time = t_start + step.end;  // exactly the output time (the sum of steps rounds)
          on_output(s, static_cast<int>(k));
        }
        continue;
      }
      const auto i = static_cast<size_t>(step.increment - 1);
      const bool last = i + 1 == dts.size();
      if (last || (i + 1) % static_cast<size_t>(seg.output_every) == 0) {
        on_output(s, static_cast<int>(k));
      }
    }
  }
  stats.wall_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

}  // namespace subslip::contact
