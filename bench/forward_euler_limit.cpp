#include "forward_euler_limit.hpp"

#include <algorithm>
#include <cmath>
#include <iostream>

#include "report_format.hpp"
#include "subslip/contact/contact_point.hpp"
#include "subslip/crystal/crystal_kernel.hpp"
#include "subslip/crystal/elasticity.hpp"
#include "subslip/crystal/phase_builder.hpp"
#include "subslip/history/contact_history.hpp"
#include "subslip/law/subloading_friction.hpp"
#include "subslip/material_point.hpp"
#include "subslip/study/explicit_stability.hpp"

namespace subslip::bench {

namespace ct = subslip::contact;
namespace hs = subslip::history;
namespace cr = subslip::crystal;

namespace {

// ------------------------------------------------------------------------------------------
// Forward Euler stability.
//
// Forward Euler advances the traction by df_t = alpha_t (du - dt phi(r, r_s)), r = f_t/(f_n mu).
// With mu and r_s frozen (they move on the slip scales 1/kappa and 1/u_tilde, while f_t moves on
// f_n mu / alpha), a perturbation of f_t is multiplied per step by 1 - lambda dt with
//   lambda = alpha_t phi_r(r, r_s) / (f_n mu),   phi_r = d phi / d r,
// so the step is stable while dt < dt_crit = 2 / lambda. At steady sliding (r_s = 1, phi = v)
// the exponential form (3.15) gives phi_r = n / (eta_v (r_hat - r)) + n v + v / (r_hat - r).
// A crystal slip system reads the same with alpha_t -> the interaction A_aa (= G for the
// single-slip system) and f_n -> tau0; several active systems couple through A, and lambda is
// the largest eigenvalue of A diag(phi_r,a / (mu_a tau0_a)).
//
// Measured: from the implicit steady state (perturbed by 1e-6 relative), forward Euler steps of
// fixed dt; stable when the perturbation has not grown after 400 steps (an inadmissible step
// counts as unstable). Bisection on dt to 0.5 %.
// ------------------------------------------------------------------------------------------

law::LawParameters paper_law() {
  law::LawParameters p;
  p.friction = {0.097, 0.085, 0.2, 0.009};
  p.subloading = {law::SubloadingFunction::cot, 80.0};
  p.overstress = {law::OverstressForm::exponential, 950.0, 16.0, 1.8};
  return p;
}

template <class Stable>
double bisect_critical_step(double guess, Stable&& stable) {
  double lo = guess, hi = guess;
  while (!stable(lo) && lo > guess * 1e-6) lo *= 0.5;
  while (stable(hi) && hi < guess * 1e6) hi *= 2.0;
  while (hi / lo > 1.005) {
    const double mid = std::sqrt(lo * hi);
    (stable(mid) ? lo : hi) = mid;
  }
  return std::sqrt(lo * hi);
}

struct FeRow {
  double stiffness, lambda, measured, lambda_path, measured_path;
};

// The contact at steady sliding at v = 1 mm/min with stiffness alpha.
FeRow contact_fe_row(double alpha) {
  const law::LawParameters p = paper_law();
  const law::SubloadingFrictionLaw lw(p);
  const double v = 1.0, fn = 5.56;
  ct::ContactModel m;
  m.law = p;
  m.initial_law_state = {p.friction.mu_s, 0.0};
  m.stiffness = {alpha, alpha};
  m.initial_normal_traction = fn;
  ct::Segment seg;
  seg.velocity = ct::Vec2(v, 0.0);
  seg.duration = 30.0;  // 30 mm: mu and r_s at their attractors (e^-70)
  seg.normal_traction = fn;
  seg.increments = 3000;
  seg.growth = 1.004;
  ct::ContactState steady;
  double lambda_path = 0.0;
  hs::run_history(m, {seg}, hs::IntegratorOptions{}, [&](const ct::ContactState& s, int) {
    steady = s;
    if (s.law.mu > 0.0)
      lambda_path =
          std::max(lambda_path, lw.traction_relaxation_rate(alpha, s.r, s.law.r_s, s.law.mu, fn));
  });
  const auto ss = lw.steady_state(v);
  const double lambda = lw.traction_relaxation_rate(alpha, ss.r, 1.0, ss.mu, fn);
  auto stable = [&](double dt) {
    return study::forward_euler_damps_contact_perturbation(lw, m.stiffness, steady, v, dt);
  };
  const double measured = bisect_critical_step(2.0 / lambda, stable);
  // From rest over the first 0.1 mm (the peak at ~0.04 mm included), uniform steps: the largest
  // step that completes without a cutback and ends within 1 % of the overshoot-free reference.
  double measured_path = std::nan("");
  if (alpha <= 1e6) {
    ct::Segment first = seg;
    first.duration = 0.1 / v;
    first.increments = 20000;
    first.growth = 1.0;
    double ref_end = 0.0;
    hs::run_history(m, {first}, hs::IntegratorOptions{},
                    [&](const ct::ContactState& s, int) { ref_end = s.traction_ratio(); });
    auto completes = [&](double dt) {
      ct::Segment fe = first;
      fe.increments = std::max(1, static_cast<int>(std::lround(first.duration / dt)));
      hs::IntegratorOptions opt;
      opt.method = ct::Method::forward_euler;
      opt.max_cutbacks = 0;
      double end = 0.0;
      try {
        hs::run_history(m, {fe}, opt,
                        [&](const ct::ContactState& s, int) { end = s.traction_ratio(); });
      } catch (const hs::StepFailure&) {
        return false;
      }
      return std::abs(end - ref_end) < 1e-2 * ref_end;
    };
    measured_path = bisect_critical_step(2.0 / lambda_path, completes);
  }
  return {alpha, lambda, measured, lambda_path, measured_path};
}

// One slip system s = e1, m = e2 in simple shear at L12 = gamma_dot, shear modulus G, tau0 = 1:
// the crystal image of the contact. The steady state is reached with point::GrainPoint; the
// forward-Euler probe (study::forward_euler_damps_grain_perturbation) steps the same phase.
FeRow crystal_fe_row(double g_over_tau0) {
  const double tau0 = 1.0, G = g_over_tau0 * tau0, rate = 1.0;
  law::LawParameters p;
  p.friction = {1.0, 2.0, 0.0, 0.0};  // no hardening: the steady state is reached exactly
  p.subloading = {law::SubloadingFunction::cot, 200.0};
  p.overstress = {law::OverstressForm::exponential, 1e-3, 16.0, 1.6};
  const law::SubloadingFrictionLaw lw(p);
  cr::PhaseDescription d;
  d.custom_systems = {{cr::Vec3::UnitX(), cr::Vec3::UnitY()}};
  d.custom_settings = {p, tau0, 1.0};
  d.stiffness = cr::isotropic_from_G_nu(G, 0.3);
  d.kinematics = cr::Kinematics::small_strain;
  const cr::Phase<Eigen::Dynamic> ph = cr::build_phase<Eigen::Dynamic>(d).phase;
  point::GrainOptions grain_options;
  grain_options.tangent = false;
  grain_options.start = point::GrainStart::committed;  // from the last rates, one try
  const point::GrainPoint grain(d, grain_options);
  point::GrainState state = grain.initial_state(cr::Mat3::Identity());
  cr::Mat3 L = cr::Mat3::Zero();
  L(0, 1) = rate;
  // Implicit to the steady state: slip 1 in 1000 steps (r_s = 1 - e^-300).
  for (int i = 0; i < 1000; ++i) {
    point::GrainUpdate u = grain.update(state, L, 1e-3);
    if (!u.report.ok) break;
    state = std::move(u.state);
  }
  cr::GrainState<Eigen::Dynamic> s;
  s.stress = state.stress;
  s.orientation = state.orientation;
  s.mu = state.mu;
  s.r_s = state.r_s;
  s.slip = state.slip;
  s.rate = state.rate;
  const double r = cr::loading_ratio(ph, s)(0);
  const double a = ph.interaction(0, 0);
  const double lambda = lw.traction_relaxation_rate(a, r, s.r_s(0), s.mu(0), tau0);
  auto stable = [&](double dt) {
    return study::forward_euler_damps_grain_perturbation(ph, s, L, dt);
  };
  return {g_over_tau0, lambda, bisect_critical_step(2.0 / lambda, stable), std::nan(""),
          std::nan("")};
}

}  // namespace

void report_forward_euler() {
  std::cout
      << "\n## Forward Euler stability limit\n\n"
      << "Linearised estimate dt_crit = 2 / lambda, lambda = alpha_t phi_r(r, r_s) / (f_n mu) "
         "(crystal: A_aa phi_r / (mu tau0)), evaluated at the analytical steady state; measured: "
         "the largest stable fixed step from that steady state (perturbation 1e-6, 400 steps, "
         "bisection to 0.5 %).\n\n"
      << "Contact, the paper's section 5 law at v = 1 mm/min, f_n = 5.56 MPa:\n\n"
      << "| alpha [MPa/mm] | lambda_ss [1/min] | 2/lambda_ss [min] | measured dt_crit [min] | "
         "measured / estimate | from rest: 2/max(lambda) [min] | from rest: measured [min] |\n"
      << "|---|---|---|---|---|---|---|\n";
  for (double alpha : {1e5, 1e6, 1e7, 1e8}) {
    const FeRow r = contact_fe_row(alpha);
    std::cout << "| " << sci(alpha) << " | " << sci(r.lambda) << " | " << sci(2.0 / r.lambda)
              << " | " << sci(r.measured) << " | " << fmt("%.3f", r.measured * r.lambda / 2.0)
              << " | " << sci(2.0 / r.lambda_path) << " | " << sci(r.measured_path) << " |\n";
  }
  std::cout << "\nCrystal, one slip system in simple shear at 1 /s (tau0 = 1, eta_v = 1e-3 s, "
               "n = 16, r_hat = 1.6, no hardening):\n\n"
            << "| G/tau0 | lambda_ss [1/s] | 2/lambda_ss [s] | measured dt_crit [s] | "
               "measured / estimate | as strain step |\n|---|---|---|---|---|---|\n";
  for (double g : {1e2, 1e3, 1e4, 1e5}) {
    const FeRow r = crystal_fe_row(g);
    std::cout << "| " << sci(g) << " | " << sci(r.lambda) << " | " << sci(2.0 / r.lambda) << " | "
              << sci(r.measured) << " | " << fmt("%.3f", r.measured * r.lambda / 2.0) << " | "
              << sci(r.measured * 1.0) << " |\n";
  }
}

}  // namespace subslip::bench
