// The single contact point as an ODE system for CVODE (see cvode_peer.hpp):
//   y = (f_t,x, f_t,y, mu, z, u_vp), dense BDF with a difference-quotient Jacobian.
#include <chrono>
#include <cmath>
#include <sstream>

#include "cvode_solver.hpp"

namespace subslip::cvode {

namespace {

using contact::Vec2;

enum Index { kFx = 0, kFy, kMu, kZ, kSlip, kSize };

// What the right-hand side needs: the law, the stiffness and the current segment.
struct ContactOde {
  ContactOde(const law::SubloadingFrictionLaw& l, const contact::ContactStiffness& c)
      : law(l), z_variable(l), stiffness(c) {}
  const law::SubloadingFrictionLaw& law;
  detail::SubloadingVariable z_variable;
  contact::ContactStiffness stiffness;
  const contact::Segment* segment = nullptr;
  double t_start = 0.0;   // segment start time
  double fn_start = 0.0;  // f_n at the segment start
  double fn_rate = 0.0;   // df_n/dt within the segment
  long rejected = 0;      // recoverable right-hand-side failures
  std::string why;        // the last one

  double normal_traction(double t) const {
    return contact::normal_traction_at(*segment, stiffness, fn_start, t - t_start);
  }
};

// The rates and the derived quantities at one state.
struct ContactRates {
  double fn, r, r_s, phi;
  Vec2 dft;
  double dmu, dz;
};

// Fills `out`; returns an empty string, or why the state is not admissible.
const char* contact_rates(const ContactOde& ode, double t, const double* y, ContactRates& out) {
  const auto& f = ode.law.parameters().friction;
  const Vec2 ft(y[kFx], y[kFy]);
  const double mu = y[kMu];
  out.fn = ode.normal_traction(t);
  if (!ft.allFinite() || !std::isfinite(mu) || !std::isfinite(y[kZ])) return "non-finite state";
  if (!(mu > 0.0)) return "mu <= 0";
  if (!(out.fn > 0.0)) return "f_n <= 0 (contact open)";
  const double ft_norm = ft.norm();
  out.r = ft_norm / (out.fn * mu);
  out.r_s = ode.z_variable.ratio_of(y[kZ]);
  if (out.r >= ode.law.parameters().overstress.r_hat) return "r >= r_hat";
  out.phi = ode.law.slip_rate(out.r, out.r_s);
  const Vec2 direction = ft_norm > 0.0 ? Vec2(ft / ft_norm) : Vec2::Zero();  // t_f (2.39)
  out.dft = ode.stiffness.alpha_t * (ode.segment->velocity - out.phi * direction);
  out.dmu = f.kappa * (1.0 - mu / f.mu_k) * out.phi + f.xi * (1.0 - mu / f.mu_s);
  if (out.r > out.r_s) {
    out.dz = ode.z_variable.sliding_rate(y[kZ], out.phi);
  } else {
    // (3.12): no viscoplastic sliding, r_s follows r down.
    const double r_rate =
        direction.dot(out.dft) / (out.fn * mu) - out.r * (out.dmu / mu + ode.fn_rate / out.fn);
    out.dz = r_rate < 0.0 ? ode.z_variable.slope(out.r_s) * r_rate : 0.0;
  }
  return "";
}

int contact_rhs(double t, const double* in, double* out, void* user_data) {
  auto& ode = *static_cast<ContactOde*>(user_data);
  ContactRates k;
  const char* why = contact_rates(ode, t, in, k);
  if (*why) {
    ++ode.rejected;
    ode.why = why;
    return 1;  // recoverable: CVODE retries with a smaller step
  }
  out[kFx] = k.dft.x();
  out[kFy] = k.dft.y();
  out[kMu] = k.dmu;
  out[kZ] = k.dz;
  out[kSlip] = k.phi;
  return 0;
}

void check_applicable(const contact::ContactModel& model,
                      const std::vector<contact::Segment>& segments) {
  if (model.law.overstress.form == law::OverstressForm::rate_independent)
    throw std::invalid_argument(
        "CVODE peer: not applicable to the rate_independent overstress form (its slip rate is "
        "set by the consistency condition and has no ODE form); use the implicit integrator");
  double fn = model.initial_normal_traction;
  if (!(fn > 0.0))
    throw std::invalid_argument("CVODE peer: the initial normal traction must be > 0");
  for (size_t k = 0; k < segments.size(); ++k) {
    const auto& seg = segments[k];
    const double fn_end = contact::normal_traction_at(seg, model.stiffness, fn, seg.duration);
    if (!(fn_end > 0.0))  // f_n is linear within a segment: positive at both ends suffices
      throw std::invalid_argument("CVODE peer: the contact opens (f_n <= 0) in segment " +
                                  std::to_string(k) +
                                  "; the ODE form needs a closed contact, use the implicit "
                                  "integrator");
    fn = fn_end;
  }
}

std::vector<double> absolute_tolerances(const contact::ContactModel& model,
                                        const std::vector<contact::Segment>& segments,
                                        double atol_scale) {
  double fn_max = model.initial_normal_traction, fn = fn_max;
  for (const auto& seg : segments) {
    fn = contact::normal_traction_at(seg, model.stiffness, fn, seg.duration);
    fn_max = std::max(fn_max, fn);
  }
  const auto& f = model.law.friction;
  const double traction = fn_max * std::max(f.mu_s, f.mu_k);  // the yield scale
  const double slip = traction / model.stiffness.alpha_t;     // elastic slip at that traction
  std::vector<double> atol(kSize);
  atol[kFx] = atol[kFy] = atol_scale * traction;
  atol[kMu] = atol_scale * std::max(f.mu_s, f.mu_k);
  atol[kZ] = atol_scale;
  atol[kSlip] = atol_scale * slip;
  return atol;
}

}  // namespace

history::RunStats run_contact_history(const contact::ContactModel& model,
                                      const std::vector<contact::Segment>& segments,
                                      const CvodeOptions& options,
                                      const history::OutputCallback& on_output,
                                      CvodeStats* cvode_stats) {
  const auto start = std::chrono::steady_clock::now();
  check_applicable(model, segments);
  const law::SubloadingFrictionLaw law(model.law);
  ContactOde ode(law, model.stiffness);
  detail::Solver solver(kSize, &contact_rhs, &ode, options,
                        absolute_tolerances(model, segments, options.atol_scale), false);

  contact::ContactState s = contact::initial_state(model);
  double* y = solver.state();
  y[kFx] = s.traction_t.x(), y[kFy] = s.traction_t.y(), y[kMu] = s.law.mu;
  y[kZ] = ode.z_variable.z_of(s.law.r_s), y[kSlip] = s.vp_slip;
  on_output(s, -1);

  history::RunStats stats;
  CvodeStats cv;
  Vec2 slip_start = s.slip;
  double path_start = s.slip_path;
  // The state the other integrators report, from the ODE state at time t.
  auto report = [&](double t, const double* state, int segment) {
    contact::ContactState out = s;
    ContactRates k;
    const char* why = contact_rates(ode, t, state, k);
    const double elapsed = t - ode.t_start;
    out.time = t;
    out.slip = slip_start + ode.segment->velocity * elapsed;
    out.slip_path = path_start + ode.segment->velocity.norm() * elapsed;
    out.traction_t = Vec2(state[kFx], state[kFy]);
    out.traction_n = ode.normal_traction(t);
    out.law.mu = state[kMu];
    out.vp_slip = state[kSlip];
    out.r = out.traction_t.norm() / (out.traction_n * out.law.mu);
    out.law.r_s = std::min(ode.z_variable.ratio_of(state[kZ]), out.r);
    out.vp_rate = *why ? law.slip_rate(out.r, out.law.r_s) : k.phi;
    on_output(out, segment);
    return out;
  };

  double t = 0.0;
  for (size_t k = 0; k < segments.size(); ++k) {
    const contact::Segment& seg = segments[k];
    ode.segment = &seg;
    ode.t_start = t;
    ode.fn_start = s.traction_n;
    ode.fn_rate = seg.normal_control == contact::NormalControl::velocity
                      ? model.stiffness.alpha_n * seg.normal_velocity
                  : seg.duration > 0.0 ? (seg.normal_traction - ode.fn_start) / seg.duration
                                       : 0.0;
    slip_start = s.slip;
    path_start = s.slip_path;
    const double t_end = t + seg.duration;
    std::vector<double> outputs =
        detail::output_times(t, contact::increment_lengths(seg), seg.output_every);
    outputs.back() = t_end;
    stats.increments += seg.increments;
    if (seg.duration > 0.0) solver.restart(t, t_end);
    const int index = static_cast<int>(k);
    std::function<void(double, const double*)> on_step;
    if (options.report_every_step)
      on_step = [&](double ts, const double* state) { report(ts, state, index); };
    for (double t_out : outputs) {
      if (seg.duration > 0.0 && !solver.integrate_to(t_out, on_step)) {
        std::ostringstream msg;
        msg << "CVODE failed in segment " << k << " before time " << t_out << ": "
            << solver.message();
        if (!ode.why.empty()) msg << " (last rejected state: " << ode.why << ")";
        msg << "; last reported state: time " << s.time << ", mu = " << s.law.mu << ", r = " << s.r
            << ", r_s = " << s.law.r_s << ", f_t = " << s.traction_t.norm()
            << ", f_n = " << s.traction_n;
        throw CvodeFailure(msg.str());
      }
      s = report(t_out, solver.state(), index);
    }
    solver.add_counters(cv);
    t = t_end;
  }
  cv.recoverable_rhs_failures = ode.rejected;
  cv.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  stats.substeps = cv.steps;
  stats.iterations = cv.nonlinear_iterations;
  stats.cutbacks = cv.error_test_failures + cv.nonlinear_convergence_failures;
  stats.wall_seconds = cv.wall_seconds;
  if (cvode_stats) *cvode_stats = cv;
  return stats;
}

}  // namespace subslip::cvode
