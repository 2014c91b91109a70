#include "subslip/contact/contact_point.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <sstream>

#include "contact_sensitivity.hpp"
#include "path_minimum.hpp"
#include "subslip/integrators/scalar_root.hpp"
#include "subslip/integrators/step_control.hpp"

namespace subslip::contact {

namespace {

bool finite(const ContactState& s) {
  return std::isfinite(s.traction_t.x()) && std::isfinite(s.traction_t.y()) &&
         std::isfinite(s.traction_n) && std::isfinite(s.law.mu) && std::isfinite(s.law.r_s) &&
         std::isfinite(s.r) && std::isfinite(s.vp_slip);
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

// A closed contact whose step ends where f_n reaches zero, its opening: the closed step's limit
// as f_n(end) -> 0+. The flow rule holds r below r_hat (at most 1 rate-independent), so the
// traction it leaves, at most r_hat mu f_n, vanishes with f_n: the trial traction is slid off
// entirely, ds = |trial| / alpha_t, and mu softens over that slip; the state is then the open
// one. Taken as open (no slip), the step would lose the sliding the contact does up to its
// opening: an error of the size of the step, which the extrapolated solutions, each losing
// their last substep's, cancel only in their combination while their difference refuses the
// step (a slide into an opening took ten refused attempts at 1e-3, ending 1e-5 of mu off).
StepAttempt slide_into_opening(const law::SubloadingFrictionLaw& law, const ContactStiffness& c,
                               const ContactState& s0, ContactState s, const Vec2& du_t,
                               double dt) {
  const double ds = (s0.traction_t + c.alpha_t * du_t).norm() / c.alpha_t;
  s.traction_t.setZero();
  s.law.mu = law.friction_coefficient_after(s0.law.mu, ds, dt).value;
  s.law.r_s = 0.0;
  s.r = 0.0;
  s.vp_slip = s0.vp_slip + ds;
  s.vp_rate = ds / dt;
  return {s, 0, true, {}};
}

// Whether a step from s0 ends on the contact's opening: closed at its start, f_n(end) = 0.
bool opens_at_end(const ContactState& s0, double fn1) {
  return fn1 == 0.0 && s0.traction_n > 0.0;
}

}  // namespace

// The admissible set every integrator must stay in: finite, mu > 0, 0 <= r_s <= r < r_hat.
std::string admissibility_violation(const law::SubloadingFrictionLaw& law, const ContactState& s) {
  if (!finite(s)) return "non-finite state";
  if (s.law.mu <= 0.0) return "mu <= 0";
  if (s.law.r_s < 0.0) return "r_s < 0";
  if (s.law.r_s > s.r) return "r_s > r";
  if (!law.is_rate_independent() && s.r >= law.parameters().overstress.r_hat) return "r >= r_hat";
  if (law.parameters().subloading.function == law::SubloadingFunction::cot && s.law.r_s >= 2.0)
    return "r_s >= 2 (cot branch)";
  return {};
}

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

// The prescribed normal traction is affine in time, f_n(t) = rate (t - t_zero), and written
// about its zero: near an opening or a closing t - t_zero is exact (the two times are within a
// factor 2 of each other), so f_n keeps its full relative precision there. Written as fn_start +
// rate t it would carry an absolute round-off of fn_start's ulps, a relative one that grows as
// f_n falls to zero (2.8e-8 at f_n = 4.5e-8 from 5.56 MPa), and a step's substeps, each ending on
// its own rounded f_n, would see the traction jitter by that much: with the traction pinned to f_n
// by steady sliding (f_t = r mu f_n) the jitter moves the slip rate by jitter f_t / (alpha_t dt),
// and every short step there would estimate an error of that size (2.5e-8 at any length, 3.4e-9
// min before an opening that a contact slides into at constant r: no tolerance below it passes).
double normal_traction_at(const Segment& seg, const ContactStiffness& c, double fn_start,
                          double t) {
  return normal_ramp(seg, c, fn_start).at(t);
}

NormalRamp normal_ramp(const Segment& seg, const ContactStiffness& c, double fn_start) {
  if (seg.normal_control == NormalControl::velocity) {
    const double rate = c.alpha_n * seg.normal_velocity;
    return {rate, rate == 0.0 ? 0.0 : -fn_start / rate, fn_start};
  }
  if (seg.duration <= 0.0) return {0.0, 0.0, seg.normal_traction};
  const double rate = (seg.normal_traction - fn_start) / seg.duration;
  return {rate, rate == 0.0 ? 0.0 : -fn_start / rate, fn_start, seg.duration, seg.normal_traction};
}

// lambda of the contact at the start of a step (the law's traction_relaxation_rate with alpha_t).
// Beyond dt = 2/lambda the traction oscillates with a growing amplitude for many steps before it
// leaves the admissible set, so forward Euler refuses such steps (they are cut back).
double traction_relaxation_rate(const law::SubloadingFrictionLaw& law, const ContactStiffness& c,
                                const ContactState& s0) {
  if (!(s0.traction_n > 0.0)) return 0.0;  // open: no traction to relax
  return law.traction_relaxation_rate(c.alpha_t, s0.r, s0.law.r_s, s0.law.mu, s0.traction_n);
}

double rate_independent_slip(const law::SubloadingFrictionLaw& law, const ContactStiffness& c,
                             const ContactState& s0, const Vec2& du_t, double fn1, double dt) {
  const double ft0 = s0.traction_t.norm();
  // Direction of the plastic sliding: the tangential traction (2.39).
  const Vec2 t_f = ft0 > 0.0 ? Vec2(s0.traction_t / ft0) : Vec2::Zero();
  // Plastic multiplier (2.44) with the normal traction rate taken from the prescribed normal.
  const double fn0 = s0.traction_n;
  const double mu = s0.law.mu, r = s0.law.r_s;
  const double fn_rate = (fn1 - fn0) / dt;
  const double v_t = t_f.dot(du_t) / dt;
  const double numerator = (c.alpha_t * v_t - r * mu * fn_rate) / fn0 - law.creep_modulus(r, mu);
  const double denominator = law.plastic_modulus(r, mu) + c.alpha_t / fn0;
  return (fn0 > 0.0 && numerator > 0.0 && std::isfinite(denominator)) ? numerator / denominator * dt
                                                                      : 0.0;
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
    ds = rate_independent_slip(law, c, s0, du_t, fn1, dt);
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
        s.law.r_s, detail::lowest_ratio_on_path(s0.traction_t, s0.traction_n, s.traction_t, fn1,
                                                [&](double l) { return mu0 + l * (mu1 - mu0); })
                       .ratio);
  }
  s.vp_slip = s0.vp_slip + ds;
  s.vp_rate = ds / dt;
  StepAttempt out{s, 0, true, {}};
  out.why = admissibility_violation(law, s);
  out.ok = out.why.empty();
  return out;
}

namespace {

// The implicit update, and with kSensitivity its forward sensitivities (`sensitivity` from the
// start state's to the end state's, contact_sensitivity.cpp): the double path of a step without
// them compiles as it did (inlined into implicit_step: no call more per step than before).
template <bool kSensitivity>
[[gnu::always_inline]] inline StepAttempt implicit_step_of(
    const law::SubloadingFrictionLaw& law, const ContactStiffness& c, const ContactState& s0,
    const Vec2& du_t, double fn1, double dt, double residual_tolerance, ContactTangent* tangent,
    ContactSensitivity* sensitivity) {
  ContactState s = kinematic_update(s0, du_t, fn1, dt);
  if (tangent) tangent->setZero();
  if (opens_at_end(s0, fn1)) {
    if constexpr (kSensitivity)
      *sensitivity = detail::opening_step_sensitivity(law, c, s0, *sensitivity, du_t, dt);
    return slide_into_opening(law, c, s0, s, du_t, dt);
  }
  if (fn1 <= 0.0) {
    if constexpr (kSensitivity)
      *sensitivity = detail::open_step_sensitivity(law, s0, *sensitivity, dt);
    return open_contact(law, s, dt);
  }
  const Vec2 trial = s0.traction_t + c.alpha_t * du_t;
  const double ft_trial = trial.norm();
  const auto mu_elastic = law.friction_coefficient_after(s0.law.mu, 0.0, dt);
  const double r_trial = ft_trial / (fn1 * mu_elastic.value);
  // The subloading ratio the step starts from: (3.12) along the elastic predictor, where no
  // sliding occurs while r < r_s. A reversal takes the traction through zero and r_s with it;
  // the slip of the step then regrows r_s from there (3.11), and it can only occur after that
  // point: the flow rule's rate is the slip over the time left (backward Euler on that part).
  const detail::PathMinimum<double> lowest = detail::lowest_ratio_on_path(
      s0.traction_t, s0.traction_n, trial, fn1,
      [&](double l) { return law.friction_coefficient_after(s0.law.mu, 0.0, l * dt).value; });
  // At the path's start the state has r_s <= r, so a minimum there below r_s is round-off of
  // |f_t|, not a dip: taken as one it would lower r_s by an ulp on every step of steady sliding.
  const bool dips = lowest.at > 0.0 && lowest.ratio < s0.law.r_s;
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
    if constexpr (kSensitivity)
      *sensitivity =
          detail::step_sensitivity(law, c, s0, *sensitivity, du_t, fn1, dt, std::nullopt);
    return {s, 0, true, {}};
  }

  // Radial return: f_t = t (ft_trial - alpha_t ds) keeps the trial direction (2.39), so the
  // step reduces to one equation G(ds) = 0 in the slip increment ds, decreasing on
  // [0, ft_trial/alpha_t] from G(0) = r_trial - rs_start > 0 to G(max) < 0.
  // G and dG/d ds where the trial traction splits into f kept and ds slid (f = ft_trial -
  // alpha_t ds): the one residual both unknowns below (the slip, the traction) solve.
  auto flow_rule_at = [&](double ds, double f) {
    const law::ValueAndSlope mu = law.friction_coefficient_after(s0.law.mu, ds, dt);
    const double r = f / (fn1 * mu.value);
    const double dr_dds = -c.alpha_t / (fn1 * mu.value) - r / mu.value * mu.d_slip;
    const auto rs = law.subloading_ratio_after(rs_start, ds);
    const auto g = law.flow_residual(r, rs.value, ds, slip_time);
    if (!g.admissible) return std::pair{g.value, 0.0};
    return std::pair{g.value, g.d_r * dr_dds + g.d_rs * rs.d_slip + g.d_slip};
  };
  // The unknown is z = ds^(1/p) (p = 1 except for the power overstress, see slip_exponent).
  const double p = law.slip_exponent();
  auto slip_of = [p](double z) { return p == 1.0 ? z : std::pow(z, p); };
  auto residual = [&](double z) {
    const double ds = slip_of(z);
    const auto [g, dg_dds] = flow_rule_at(ds, ft_trial - c.alpha_t * ds);
    const double dds_dz = p == 1.0 ? 1.0 : p * std::pow(z, p - 1.0);
    return std::pair{g, dg_dds * dds_dz};
  };
  const double ds_max = ft_trial / c.alpha_t;
  // Start from the previous viscoplastic rate (over a smooth history it is close to the
  // answer); failing that, from the slip that would bring r back to rs_start (the
  // rate-independent answer, which lies on the far side of the root).
  double guess = s0.vp_rate * slip_time;
  if (!(guess > 0.0 && guess < ds_max)) {
    guess = (ft_trial - rs_start * fn1 * mu_elastic.value) / c.alpha_t;
  }
  constexpr double kRootResolution = 4.0 * std::numeric_limits<double>::epsilon();
  const auto root =
      safeguarded_newton(residual, 0.0, std::pow(ds_max, 1.0 / p), std::pow(guess, 1.0 / p),
                         residual_tolerance, kRootResolution, 1e-300);
  if (!root.converged) return {s, root.iterations, false, "flow rule did not converge"};

  // The trial traction splits into the traction kept and the part slid, ft_trial = f_t +
  // alpha_t ds. The slip resolves the flow rule only to |dG/d ds| ulp(ds): where the slid part is
  // much the larger (a long step of steady sliding: ds alpha_t = 1e9 f_t), the traction
  // ft_trial - alpha_t ds, a difference of two nearly equal numbers, keeps only a few digits,
  // and the flow rule is met far outside the tolerance. The traction itself resolves it to its
  // own precision, so there the root is taken again in f_t, from the slip's root.
  double ds = slip_of(root.x);
  double ft = ft_trial - c.alpha_t * ds;
  int iterations = root.iterations;
  if (!root.within_tolerance && c.alpha_t * ds > ft) {
    auto residual_in_traction = [&](double f) {
      const auto [g, dg_dds] = flow_rule_at((ft_trial - f) / c.alpha_t, f);
      return std::pair{g, -dg_dds / c.alpha_t};
    };
    const auto in_traction = safeguarded_newton(residual_in_traction, 0.0, ft_trial, ft,
                                                residual_tolerance, kRootResolution, 1e-300);
    iterations += in_traction.iterations;
    if (!in_traction.converged) return {s, iterations, false, "flow rule did not converge"};
    ft = in_traction.x;
    ds = (ft_trial - ft) / c.alpha_t;
  }
  const law::ValueAndSlope mu = law.friction_coefficient_after(s0.law.mu, ds, dt);
  const double rs_after = law.subloading_ratio_after(rs_start, ds).value;
  if (law.is_rate_independent()) {
    // The flow rule is r = r_s: the traction lies on the subloading surface. Taken from the
    // slip, r would miss r_s by the root's residual, one way or the other, and r_s = min(r_s, r)
    // would keep every miss below: over the 1e5 ... 1e6 steps of a tight tolerance r_s would
    // drift down by their sum (4e-9 after a 2-D change of direction), the more the tighter.
    ft = rs_after * fn1 * mu.value;
    s.r = rs_after;
  } else {
    s.r = ft / (fn1 * mu.value);
  }
  const double dr = -c.alpha_t / (fn1 * mu.value) - s.r / mu.value * mu.d_slip;  // d r / d ds
  s.law.mu = mu.value;
  s.traction_t = trial * (ft / ft_trial);
  s.law.r_s = std::min(rs_after, s.r);
  s.vp_slip = s0.vp_slip + ds;
  s.vp_rate = ds / slip_time;  // the end rate of the flow rule
  StepAttempt out{s, iterations, true, {}};
  out.why = admissibility_violation(law, s);
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
    const Eigen::Matrix2d tt = t * t.transpose();
    tangent->leftCols<2>() = c.alpha_t * ((ft / ft_trial) * (Eigen::Matrix2d::Identity() - tt) +
                                          (1.0 - c.alpha_t * dds_dtrial) * tt);
    tangent->col(2) = -c.alpha_t * dds_dfn * t;
  }
  if constexpr (kSensitivity) {
    if (out.ok) {
      // dG/d ds at the root: the step's Jacobian, which the sensitivities divide by.
      const auto rs = law.subloading_ratio_after(rs_start, ds);
      const auto g = law.flow_residual(s.r, rs.value, ds, slip_time);
      const double g_slip = g.d_r * dr + g.d_rs * rs.d_slip + g.d_slip;
      *sensitivity = detail::step_sensitivity(law, c, s0, *sensitivity, du_t, fn1, dt,
                                              detail::SlipRoot{ds, g_slip});
    }
  }
  return out;
}

}  // namespace

StepAttempt implicit_step(const law::SubloadingFrictionLaw& law, const ContactStiffness& c,
                          const ContactState& s0, const Vec2& du_t, double fn1, double dt,
                          double residual_tolerance, ContactTangent* tangent) {
  return implicit_step_of<false>(law, c, s0, du_t, fn1, dt, residual_tolerance, tangent, nullptr);
}

StepAttempt implicit_step(const law::SubloadingFrictionLaw& law, const ContactStiffness& c,
                          const ContactState& s0, const Vec2& du_t, double fn1, double dt,
                          double residual_tolerance, ContactTangent* tangent,
                          ContactSensitivity& sensitivity) {
  ContactSensitivity carried = sensitivity;
  StepAttempt a =
      implicit_step_of<true>(law, c, s0, du_t, fn1, dt, residual_tolerance, tangent, &carried);
  if (a.ok) sensitivity = carried;
  return a;
}

ContactState initial_state(const ContactModel& model) {
  ContactState s;
  s.law = model.initial_law_state;
  s.traction_n = model.initial_normal_traction;
  s.r = 0.0;
  s.law.r_s = std::min(s.law.r_s, s.r);
  return s;
}

}  // namespace subslip::contact
