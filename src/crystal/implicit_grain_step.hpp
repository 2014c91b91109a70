// The implicit grain step: backward Euler of one grain over a step. solve_grain_step (below)
// chooses the formulation by the phase's laws; its rule and each formulation's argument for
// convergence are in docs/grain_step.md.
//
// The stress-space solve (stress_space_solve, below) is the globally convergent formulation of
// the phases with a growing resistance and no plane pressure. Unknowns: the lattice stress sigma
// (6 numbers), plus, with a latent matrix, its latent drives (latent-rank numbers). For a given
// stress every slip system's slip increment is the root of its own scalar flow rule at its
// resolved shear tau_a = P_a : sigma, so the outer residual
//   R(sigma) = sigma - sigma_trial + sum_a C P_a dgamma_a(sigma)
// has a Jacobian I + sum_a C P_a (d dgamma_a / d sigma) whose size does not grow with the slip
// count and which stays regular where the slips themselves are not determined (the Taylor
// ambiguity of FCC and BCC). Newton on the slips (StressSolver::slip_newton) solves the same
// equations in the slips; it takes most steps from the continued rates, and takes over from the
// stress-space solve at its first iterate from which it converges.
//
// Internal to src/crystal/: the template is instantiated once per slip count, each in its own
// translation unit (implicit_grain_step_<N>.cpp), so that a rebuild compiles them in parallel;
// a portable build compiles those of 12, 24 and 48 systems for AVX2 and AVX-512 too
// (grain_step_isa.hpp).
#pragma once

#include "grain_step_isa.hpp"
#include "semismooth_grain_step.hpp"
#include "stress_solver_slips.hpp"
#include "vertex_grain_step.hpp"

namespace subslip::crystal {

using namespace implicit_detail;

// The stress-space solve (see the file comment and docs/grain_step.md): Newton on sigma (and
// the extra unknowns) with each system's slip from its own flow rule, globalised by a line
// search on the convex potential. Returns whether it converged; `it` is its last iterate.
// `local(it)` is offered every iterate the line search accepts: where it returns true (it has
// solved the step from there, see solve_grain_step), the solve ends there, successfully.
template <int N, class Local>
bool stress_space_solve(StressSolver<N>& solver, const Phase<N>& ph, const GrainState<N>& s0,
                        const Vec6& trial, const typename SlipTypes<N>::VecN& previous_slip,
                        const GrainStepOptions& opt, typename StressSolver<N>::Iterate& it,
                        GrainStepReport& rep, Local&& local) {
  using VecY = typename StressSolver<N>::VecY;
  const int n = ph.slip_count;
  Vec6 predicted = trial;
  predicted.noalias() -= ph.c_schmid * previous_slip;
  typename StressSolver<N>::Iterate trial_point;
  // Starts: the last step's slip rate continued, the elastic trial and the start stress; the
  // iteration begins from the one with the smallest residual (a nearly rate-independent law can
  // put the trial just inside the domain with slips of 1e8, and the start stress is always
  // inside it).
  const VecY y = solver.extras_for(previous_slip);
  solver.evaluate(predicted, y, it);
  if (!(std::sqrt(2.0 * it.merit) <= solver.residual_tolerance())) {
    for (const Vec6* start : {&trial, &s0.stress}) {
      if (*start == predicted) continue;  // (no slip in the last step: the trial itself)
      solver.evaluate(*start, y, trial_point);
      if (trial_point.merit < it.merit) std::swap(it, trial_point);
    }
  }
  // The extra unknowns consistent with the chosen start's slips (without a latent matrix there
  // are none, and the start stands as evaluated).
  if (solver.extras() > 0) {
    it.y = solver.extras_for(it.dgamma);
    solver.evaluate(it.sigma, it.y, it);
  }
  if (!std::isfinite(it.merit)) {
    rep.why = "no admissible start (r >= r_hat)";
    rep.system = it.bad_system;
    return false;
  }
  solver.remember(it);

  // Newton on sigma (and the extras) with a backtracking line search on Phi or 1/2 |R|^2.
  bool converged = false;
  bool at_floor = false;  // the line search found no decrease within the residual's floor
  for (int iterations = 0; iterations < opt.max_iterations;) {
    const double residual = std::max(it.r_sigma.cwiseAbs().maxCoeff(),
                                     it.r_y.size() ? it.r_y.cwiseAbs().maxCoeff() : 0.0);
    Vec6 d_sigma;
    VecY d_y;
    const bool have_step = solver.newton_correction(it, d_sigma, d_y);
    // Converged when the residual is within tolerance, or when the correction no longer changes
    // the stress in floating point (the scalar roots' rounding sets the residual's floor).
    const bool stagnant =
        have_step && d_sigma.cwiseAbs().maxCoeff() <= 4.0 * kEps * solver.stress_scale() &&
        (d_y.size() == 0 || d_y.cwiseAbs().maxCoeff() <= 4.0 * kEps * solver.stress_scale());
    // Where slip_newton() resolves the slips afterwards, R at its floor is as good as it gets.
    const bool floor_reached = at_floor || residual <= solver.residual_floor(it);
    if (residual <= solver.residual_tolerance() || stagnant || floor_reached) {
      converged = true;
      break;
    }
    if (!have_step) break;
    ++iterations;
    ++rep.iterations;
    double alpha = 1.0;
    bool accepted = false;
    // Sufficient decrease (Armijo, c = 1e-4): of Phi where R has a potential, judged from its
    // slopes by the trapezoidal rule, Phi(alpha) - Phi(0) ~ alpha (s(0) + s(alpha)) / 2, exact for
    // a quadratic Phi, so a full Newton step is taken near the solution; of 1/2 |R|^2 otherwise.
    const bool on_potential = solver.has_potential();
    const double slope0 = on_potential ? solver.potential_slope(it, d_sigma) : 0.0;
    const double step_size = d_sigma.cwiseAbs().maxCoeff();
    const double stress_size = it.sigma.cwiseAbs().maxCoeff();
    // Halving until the step no longer moves the stress in floating point.
    for (; !accepted && alpha * step_size > kEps * stress_size; alpha *= 0.5) {
      solver.evaluate(it.sigma + alpha * d_sigma, it.y + alpha * d_y, trial_point);
      accepted = on_potential
                     ? std::isfinite(trial_point.merit) &&
                           solver.potential_slope(trial_point, d_sigma) <= -(1.0 - 2e-4) * slope0
                     : trial_point.merit <= (1.0 - 2e-4 * alpha) * it.merit;
      if (accepted) break;
    }
    if (!accepted && residual <= solver.residual_floor(it)) {
      // R is at the resolution of the scalar roots: no stress does better (slip_newton() below
      // resolves the slips).
      at_floor = true;
      continue;
    }
    if (!accepted) break;
    std::swap(it, trial_point);
    solver.remember(it);
    if (local(it)) return true;
  }
  if (!converged) {
    rep.why = "stress iteration did not converge";
    rep.system = it.bad_system;
    if (rep.system < 0 && n > 0) it.slip.maxCoeff(&rep.system);
    return false;
  }
  return true;
}

// Whether every system's resistance grows with slip under an overstress form, from s0: kappa > 0
// with mu_s <= mu_k and mu < mu_k (slip drives mu towards mu_k, recovery towards mu_s); the
// rate-independent form's slip response is unbounded at r_s = 1. Newton on the slips needs this
// (its slopes are then bounded away from zero), and so does the stress-space solve.
template <int N>
bool resistance_grows_with_slip(const Phase<N>& ph, const GrainState<N>& s0) {
  for (int a = 0; a < ph.slip_count; ++a) {
    const auto& law = ph.laws[static_cast<size_t>(a)];
    const auto& f = law.parameters().friction;
    if (law.is_rate_independent() || !(f.kappa > 0.0) || f.mu_s > f.mu_k || !(s0.mu(a) < f.mu_k))
      return false;
  }
  return true;
}

// The formulations of the grain step (docs/grain_step.md, "Which formulation takes which step").
enum class GrainFormulation {
  // The rate-independent form with kappa = 0 on every system: a convex program over the held
  // systems' faces of the yield polytope (vertex_grain_step.cpp).
  yield_polytope,
  // A resistance that grows with slip on every system and no plane pressure: the flow rules in
  // the slips, globalised by the stress-space potential (flow_rule_step, below).
  flow_rules,
  // Everything else (plane pressure, softening, no hardening, the rate-independent form with
  // hardening): Newton on the signed slips with a residual continuous through zero slip
  // (semismooth_grain_step.cpp).
  signed_slips,
};

// The rule: the first formulation whose argument covers the phase and the step's start.
template <int N>
GrainFormulation grain_formulation(const Phase<N>& ph, const GrainState<N>& s0) {
  if (vertex_step_applies(ph)) return GrainFormulation::yield_polytope;
  if (!ph.pressure_sensitive && resistance_grows_with_slip(ph, s0))
    return GrainFormulation::flow_rules;
  return GrainFormulation::signed_slips;
}

// The step of the flow-rule formulation: Newton on the slips from the step's start slips; where
// it does not converge, the stress-space solve (with Newton on the slips offered every iterate
// it accepts, and polishing its slips after it). Without a latent matrix the stress-space solve
// takes every such step; with one only a step that starts from no slip at all (the virgin step,
// an elastic unloading): its line search on 1/2 |R|^2 has no convexity argument, and Newton on
// the slips cannot start there (dr_s/d slip is infinite at r_s = 0). Returns whether the step is
// resolved: `rep` then reports its end state (admissible or not). Where it is not, the caller
// hands the step on, and rep.iterations counts what this one spent.
template <int N>
bool flow_rule_step(const Phase<N>& ph, const GrainState<N>& s0, const Mat3& L, double dt,
                    const GrainStepOptions& opt, GrainState<N>& s1, Tangent* tangent,
                    const typename SlipTypes<N>::VecN* start_rate, SlipTangent<N>* slip_tangent,
                    GrainStepReport& rep) {
  using Solver = StressSolver<N>;
  using VecN = typename SlipTypes<N>::VecN;
  using Iterate = typename Solver::Iterate;
  const int n = ph.slip_count;
  const VecN previous_slip = (start_rate != nullptr ? *start_rate : s0.rate) * dt;
  const bool stress_space = !ph.has_latent || (previous_slip.array() == 0.0).all();
  const StepKinematics kin = step_kinematics(s0.orientation, L, dt, ph.kinematics);
  const Vec6 trial = s0.stress + ph.stiffness * kin.strain_increment;
  Solver solver(ph, s0, trial, dt, opt);

  // Most steps of a loading path: Newton on the slips from the last step's slip rate continued
  // converges from there. Where it does not (the first step, a change of the active set, a
  // large step), the stress-space solve, then Newton on the slips from its result.
  typename Solver::SlipPoint point;
  rep.iterations = 0;
  if (!(solver.slip_newton(previous_slip, VecN::Zero(n), point, rep.iterations, false) &&
        point.converged)) {
    if (!stress_space) return false;
    Iterate it;
    // Newton on the slips takes over from the stress iteration at the first iterate from which
    // it converges (its own test: every full step halves the largest flow-rule residual, else
    // it stops at once): each of its evaluations is one batch of flow points, where each of the
    // stress iteration's is a scalar root per system.
    bool handed_over = false;
    auto hand_over = [&](const Iterate& at) {
      handed_over = solver.slip_newton(solver.corrected_slips(at), VecN::Zero(n), point,
                                       rep.iterations, false) &&
                    point.converged;
      return handed_over;
    };
    if (!stress_space_solve(solver, ph, s0, trial, previous_slip, opt, it, rep, hand_over))
      return false;
    // The stress iterate fixes each slip only to |dG/d ds|^-1 times G's rounding, coarse where
    // the law is nearly rate-independent; a step ending there would make the grain's response
    // jump between neighbouring loadings. So the slips are resolved from it, or the step is
    // unresolved.
    if (!handed_over && !(solver.slip_newton(solver.corrected_slips(it), VecN::Zero(n), point,
                                             rep.iterations, true) &&
                          point.converged))
      return false;
  }

  // The end state: the converged slip point (see StressSolver::slip_newton).
  const VecN& dgamma = point.dgamma;
  s1.stress = point.sigma;
  s1.slip = s0.slip + dgamma;
  s1.rate = dgamma / dt;
  s1.mu = point.mu;
  const VecN fn1 = normal_traction(ph, s1.stress);  // tau0 exactly: no plane pressure here
  // r through the kernel's own definition (crystal_kernel.cpp), not inline: whatever instruction
  // set this step is compiled for (grain_step_isa.hpp), every later reading of the state then
  // finds r_s <= r to the bit.
  const VecN r1 = loading_ratio(ph, s1);
  // (3.12): r_s follows r down where no slip occurs.
  s1.r_s = point.r_s.cwiseMin(r1);
  s1.orientation = orientation_after_plastic_spin(ph, kin.spun_orientation, dgamma);
  // A flow rule converged to its tolerance, or to its rounding (StressSolver::within_floor).
  if (!admissible_state(ph, s1, r1, fn1, rep, OpenPlanes::resolved, admitted_flow_residual(opt)))
    return true;

  if (tangent) {
    Tangent d_sigma;
    SlipTangent<N> d_dgamma;
    solver.slip_sensitivities(
        point, lattice_directions(opt.tangent_directions, kin.mid_orientation), d_sigma, d_dgamma);
    *tangent = sample_tangent(ph, s1, d_sigma, d_dgamma);
    if (slip_tangent) *slip_tangent = d_dgamma;
  }
  rep.ok = true;
  return true;
}

// The grain step (implicit_grain_step, below), compiled for the instruction set of the
// translation unit that instantiates it: the formulation of the rule (grain_formulation), and
// the signed-slip formulation for a step the polytope or the flow rules leave unresolved. That
// hand-over is the one place where a second formulation takes a step; docs/grain_step.md
// measures where it happens.
template <int N>
GrainStepReport solve_grain_step(const Phase<N>& ph, const GrainState<N>& s0, const Mat3& L,
                                 double dt, const GrainStepOptions& opt, GrainState<N>& s1,
                                 Tangent* tangent, const typename SlipTypes<N>::VecN* start_rate,
                                 SlipTangent<N>* slip_tangent) {
  int spent = 0;
  switch (grain_formulation(ph, s0)) {
    case GrainFormulation::yield_polytope: {
      const GrainStepReport r = vertex_grain_step(ph, s0, L, dt, opt, s1, tangent, slip_tangent);
      if (r.ok) return r;
      spent = r.iterations;
      break;
    }
    case GrainFormulation::flow_rules: {
      GrainStepReport r;
      if (flow_rule_step(ph, s0, L, dt, opt, s1, tangent, start_rate, slip_tangent, r)) return r;
      spent = r.iterations;
      break;
    }
    case GrainFormulation::signed_slips:
      break;
  }
  GrainStepReport r =
      semismooth_grain_step(ph, s0, L, dt, opt, s1, tangent, start_rate, slip_tangent);
  r.iterations += spent;
  return r;
}

#ifdef SUBSLIP_GRAIN_STEP_ISA
// This translation unit compiled for AVX2 or AVX-512 (grain_step_isa.hpp): the step under its
// own name, isa_avx2:: or isa_avx512::implicit_grain_step<N>.
namespace SUBSLIP_GRAIN_STEP_ISA {
template <int N>
GrainStepReport implicit_grain_step(const Phase<N>& ph, const GrainState<N>& s0, const Mat3& L,
                                    double dt, const GrainStepOptions& opt, GrainState<N>& s1,
                                    Tangent* tangent, const typename SlipTypes<N>::VecN* start_rate,
                                    SlipTangent<N>* slip_tangent) {
  return solve_grain_step(ph, s0, L, dt, opt, s1, tangent, start_rate, slip_tangent);
}
}  // namespace SUBSLIP_GRAIN_STEP_ISA
#else
// The step of the build's own instruction set; for the slip counts compiled for wider ones too,
// the one wide step of a host build, or the widest the machine runs and the run allows (the flow
// batches' level: one choice for both, which MPI ranks agree on) where the portable step is
// compiled beside them (grain_step_isa.hpp).
template <int N>
GrainStepReport implicit_grain_step(const Phase<N>& ph, const GrainState<N>& s0, const Mat3& L,
                                    double dt, const GrainStepOptions& opt, GrainState<N>& s1,
                                    Tangent* tangent, const typename SlipTypes<N>::VecN* start_rate,
                                    SlipTangent<N>* slip_tangent) {
#if SUBSLIP_GRAIN_STEP_ISAS  // (the wide steps are declared only in builds that have them)
  if constexpr (has_isa_grain_steps(N)) {
#if !SUBSLIP_GRAIN_STEP_PORTABLE && SUBSLIP_GRAIN_STEP_AVX512
    return isa_avx512::implicit_grain_step(ph, s0, L, dt, opt, s1, tangent, start_rate,
                                           slip_tangent);
#elif !SUBSLIP_GRAIN_STEP_PORTABLE
    return isa_avx2::implicit_grain_step(ph, s0, L, dt, opt, s1, tangent, start_rate, slip_tangent);
#else
    switch (detail::flow_batch_level()) {
      case 2:
        return isa_avx512::implicit_grain_step(ph, s0, L, dt, opt, s1, tangent, start_rate,
                                               slip_tangent);
      case 1:
        return isa_avx2::implicit_grain_step(ph, s0, L, dt, opt, s1, tangent, start_rate,
                                             slip_tangent);
      default:
        return solve_grain_step(ph, s0, L, dt, opt, s1, tangent, start_rate, slip_tangent);
    }
#endif
  } else {
    return solve_grain_step(ph, s0, L, dt, opt, s1, tangent, start_rate, slip_tangent);
  }
#else
  return solve_grain_step(ph, s0, L, dt, opt, s1, tangent, start_rate, slip_tangent);
#endif
}
#endif

}  // namespace subslip::crystal
