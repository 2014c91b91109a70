// SUNDIALS CVODE (variable-order BDF) as an independent stiff-solver peer of the subslip
// integrators: the same physics written as an ODE system and handed to a general-purpose
// solver. The accuracy study uses it to cross-check its reference solutions and shows it as a
// peer curve (what a user would otherwise reach for).
//
// Optional dependency: built only when CMake finds SUNDIALS (SUBSLIP_WITH_CVODE = AUTO, the
// default, or ON). Without it available() is false and the run functions throw
// std::runtime_error saying how to get it; everything here is declared either way, so callers
// need no #ifdef.
//
// The ODE systems (paper sections 2-3):
//   contact: y = (f_t [2], mu, z, u_vp). f_n is the prescription (a known function of time),
//     the slip is v t. With phi = law.slip_rate(r, r_s), r = |f_t| / (f_n mu), t = f_t/|f_t|:
//       df_t/dt = alpha_t (v - phi t)            (3.15)
//       dmu/dt  = kappa (1 - mu/mu_k) phi + xi (1 - mu/mu_s)   (3.4)
//       du_vp/dt = phi.
//   crystal, per grain: lattice-frame stress [6], orientation g [9], z [N], mu [N], signed slip
//     [N]; stress rate C (D - sum gdot_a P_a) in lattice components, dg/dt = -[omega]x g with
//     the lattice spin omega = W - W_p, gdot_a = phi(r_a, r_s,a) sign(tau_a) (the rates of
//     crystal::grain_rates, shared with forward Euler). Plus F [9] (dF/dt = L F) and the
//     integral of sym(L) [9] for the macro output. Mixed control: the slip rates do not depend
//     on L and the stress rate is affine in L, so at every right-hand-side evaluation the free
//     components of L solve a small linear system that makes the homogenised stress rate of the
//     free components equal the prescribed one, (target - start) / duration of the segment.
//   The subloading ratio is carried as z = 1 - exp(-k H(r_s)), H(r_s) = int_0^r_s dr / U(r) the
//   slip needed to bring r_s from 0 (law.subloading_slip_integral), k = pi u_tilde / 2 for the
//   cot form (then z = 1 - cos(pi r_s / 2)) and u_tilde otherwise. While sliding (r > r_s),
//   dz/dt = k (1 - z) phi: linear, regular at r_s = 0 where U = dr_s/du_vp is infinite (r_s
//   itself grows like sqrt(u_vp) there) and at r_s = 1. When r <= r_s (no viscoplastic
//   sliding) r_s follows r down, (3.12): dz/dt = dz/dr_s min(dr/dt, 0). Reported r_s is
//   min(r_s(z), r), as in the other integrators.
//
// Every segment is one CVODE interval (re-initialised at the segment start, where the
// prescribed velocity jumps; the stop time is the segment end so no step crosses it). Output
// values between CVODE steps are CVODE's own interpolation (the BDF polynomial, accurate to the
// tolerance). Outside the admissible set (r >= r_hat, mu <= 0, f_n <= 0, a non-finite state)
// the right-hand side returns a recoverable error and CVODE retries with a smaller step; when
// it cannot continue the run throws CvodeFailure naming time, grain, slip system and state.
//
// Not applicable: the rate-independent overstress form (section 2) has no ODE form (its slip
// rate is set by the consistency condition, not by the state): std::invalid_argument. An
// opening contact (f_n <= 0 while loaded) is not supported either (std::invalid_argument).
#pragma once

#include <stdexcept>
#include <vector>

#include "subslip/contact/contact_point.hpp"
#include "subslip/crystal/aggregate.hpp"
#include "subslip/crystal/phase_builder.hpp"
#include "subslip/crystal/rotation.hpp"
#include "subslip/history/contact_history.hpp"

namespace subslip::cvode {

// True when this build has the CVODE peer (SUBSLIP_HAVE_CVODE).
bool available();

enum class LinearSolver {
  automatic,  // dense for a contact and a single crystal, Krylov for several grains (measured
              // with 4 FCC grains, 222 unknowns: dense 6-9 s, Krylov 0.7-1 s)
  dense,      // SUNDenseMatrix + SUNLinSol_Dense, difference-quotient Jacobian
  krylov,     // SPGMR, matrix-free, block-diagonal (per grain) preconditioner (crystal only)
};

struct CvodeOptions {
  double rtol = 1e-8;         // relative tolerance
  double atol_scale = 1e-10;  // absolute tolerance of each component: atol_scale x its natural
                              // scale (tractions/stresses: the yield scale f_n mu_s or tau0 mu;
                              // ratios, z, orientation, F: 1; slips: the elastic slip at the
                              // yield scale)
  int max_steps = 10000000;   // CVODE steps per segment
  int max_order = 5;          // BDF order limit (1..5)
  // Newton iteration of each BDF step. Close to the rate-independent limit (eta_v x slip rate
  // small) r - r_s falls below the tolerance and every loaded slip system sits on the kink of
  // the Macaulay bracket <r - r_s>, where a Newton matrix from one side is wrong on the other.
  // CVODE's defaults (3 iterations, 10 convergence and 7 error-test failures per step, safety
  // factor 0.1 on the convergence test) then either stop the run or accept stalled iterations
  // (measured: errors of 10-100x the tolerance on FCC crystals, and a 3-grain reversal whose
  // dense and Krylov runs differed by 1e-4 at 0.01); these let it through, correctly. The
  // Krylov solver evaluates J v at every iterate, so it tolerates 0.01; its linear tolerance
  // scales with the factor, and at 0.001 it needs 20x more steps.
  int max_nonlinear_iterations = 10;
  int max_convergence_failures = 1000;
  int max_error_test_failures = 100;
  double nonlinear_convergence_coefficient = 0.0;  // 0: 0.001 dense, 0.01 Krylov
  int krylov_dimension = 20;  // GMRES subspace (CVODE's default 5 stalls on a single crystal)
  double initial_step = 0.0;  // 0: CVODE's own estimate
  LinearSolver linear_solver = LinearSolver::automatic;
  // Also report the state after every internal CVODE step (dense output for a reference path);
  // the output points of the history are reported in any case, in time order, each once.
  bool report_every_step = false;
};

// CVODE's own counters, summed over the segments.
struct CvodeStats {
  long steps = 0;
  long rhs_evaluations = 0;       // by the integrator (incl. difference-quotient Jacobians)
  long jacobian_evaluations = 0;  // dense: Jacobian evaluations; Krylov: preconditioner setups
                                  // that recomputed the per-grain blocks
  long nonlinear_iterations = 0;
  long linear_iterations = 0;  // Krylov only
  long error_test_failures = 0;
  long nonlinear_convergence_failures = 0;
  long recoverable_rhs_failures = 0;  // evaluations that stepped outside the admissible set
  long preconditioner_solves = 0;     // Krylov only
  int last_order = 0;
  double wall_seconds = 0.0;
};

struct CvodeFailure : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// ----- contact --------------------------------------------------------------------------------

// Runs a contact history with CVODE. on_output(state, segment) is called for the initial state
// (segment -1) and at the end of every output increment of every segment: the same points as
// history::run_history (and, with report_every_step, after every CVODE step as well). The
// reported vp_rate is the instantaneous viscoplastic sliding rate phi at that point.
// RunStats: increments as run_history counts them, substeps = CVODE steps, iterations =
// nonlinear iterations, cutbacks = error-test + convergence failures.
history::RunStats run_contact_history(const contact::ContactModel& model,
                                      const std::vector<contact::Segment>& segments,
                                      const CvodeOptions& options,
                                      const history::OutputCallback& on_output,
                                      CvodeStats* cvode_stats = nullptr);

// ----- crystal --------------------------------------------------------------------------------

// Runs a Taylor aggregate (one grain: a single crystal) with CVODE through the same observer
// interface as crystal::Aggregate::run, at the same output points (initial state with segment
// -1, then every output increment). MacroState: velocity_gradient is L at that instant (free
// components solved), deformation_gradient from dF/dt = L F, strain ln V (finite rotation) or
// the integral of sym(L) (small strain), stress the weighted average. GrainFields: slip_rate is
// the instantaneous gdot, subloading_ratio min(r_s, r).
// AggregateStats: increments as Aggregate::run counts them, substeps = CVODE steps,
// grain_steps = steps x grains, grain_solves = right-hand-side evaluations x grains,
// newton_iterations = nonlinear iterations, cutbacks = error-test + convergence failures.
crystal::AggregateStats run_taylor_aggregate(const crystal::PhaseDescription& phase,
                                             const std::vector<crystal::Orientation>& grains,
                                             const std::vector<crystal::LoadSegment>& segments,
                                             const CvodeOptions& options,
                                             const crystal::MacroObserver& observe,
                                             CvodeStats* cvode_stats = nullptr);

}  // namespace subslip::cvode
