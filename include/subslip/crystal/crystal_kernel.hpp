// The crystal batch kernel: the subloading-overstress law on every slip system of a grain.
//
// Composition (in the spirit of ExaCMech: slip geometry x kinetics x elasticity): a Phase<N>
// holds the slip geometry and elasticity as per-phase constant matrices in the LATTICE frame and
// one law object per slip system; N, the slip count, is a template parameter so that the hot
// loop works on fixed-size Eigen vectors and matrices (Eigen::Dynamic with a fixed maximum is
// the fallback for unusual counts: still no heap allocation per grain-step).
//
// Why the lattice frame: the stress is kept as its lattice-frame components. Then the Schmid
// tensors P_a, the products C:P_a and the interaction matrix A_ab = P_a:C:P_b are constants of
// the phase, the resolved shear stress is linear in the slip increments,
//   tau = tau_trial - A dgamma,
// and a superposed rigid rotation only changes the orientation, never the lattice stress: the
// stress rate is the corotational rate with the lattice spin, which keeps stress invariants
// unchanged under rigid rotation (objective, no spurious shear oscillation).
//
// Crystal reading of the law (per slip system a; the law itself is in law/):
//   r_a = |tau_a| / (mu_a f_n,a),  f_n,a = tau0_a (or tau0_a + compressive normal stress on the
//   slip plane in the pressure-sensitive reading), CRSS g_a = mu_a tau0_a,
//   gdot_a = phi(r_a, r_s,a) sign(tau_a),
//   mu_a driven by the effective slip sum_b q_ab |dgamma_b| (q = identity by default).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "subslip/crystal/elasticity.hpp"
#include "subslip/integrators/step_control.hpp"
#include "subslip/law/subloading_friction.hpp"

namespace subslip::crystal {

inline constexpr int kMaxSlipSystems = 48;

// The slip counts the kernel is compiled for with fixed sizes: 12 (FCC, BCC {110}), 24 (HCP) and
// 48 (BCC); every other count, the single-slip check's one system included, runs with
// Eigen::Dynamic
// (a fixed capacity of kMaxSlipSystems: still no allocation per grain-step). Every file that
// instantiates the kernel's templates applies its macro X to each entry of this one list, and
// visit_phase (phase_builder.hpp) picks among the same counts. Each count compiles the whole
// grain solver again: that is what the list costs the build.
#define SUBSLIP_FOR_EACH_SLIP_COUNT(X) X(12) X(24) X(48) X(Eigen::Dynamic)

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Vec6 = MandelVector;
using Mat6 = MandelMatrix;

// Fixed-size types for N slip systems (N = Eigen::Dynamic: runtime size up to kMaxSlipSystems).
template <int N>
struct SlipTypes {
  static constexpr int MaxN = N == Eigen::Dynamic ? kMaxSlipSystems : N;
  using VecN = Eigen::Matrix<double, N, 1, 0, MaxN, 1>;
  using MatNN = Eigen::Matrix<double, N, N, 0, MaxN, MaxN>;
  using Mat6N = Eigen::Matrix<double, 6, N, 0, 6, MaxN>;
  using Mat3N = Eigen::Matrix<double, 3, N, 0, 3, MaxN>;
  using MatN6 = Eigen::Matrix<double, N, 6, 0, MaxN, 6>;
};

enum class Kinematics {
  finite_rotation,  // small elastic strain, finite lattice rotation (texture evolves)
  small_strain,     // infinitesimal: D = sym(L), no rotation of the lattice
};

// Per-phase constants, lattice frame, Mandel notation (11, 22, 33, sqrt2*23, sqrt2*13, sqrt2*12).
template <int N>
struct Phase {
  using T = SlipTypes<N>;
  int slip_count = N == Eigen::Dynamic ? 0 : N;
  Mat6 stiffness;              // C
  Mat6 compliance;             // C^-1
  typename T::Mat6N schmid;    // P_a = sym(s_a (x) m_a)
  typename T::Mat6N c_schmid;  // C P_a
  // The lower triangle of P_a P_a^T (column by column: 11, 21, ..., 61, 22, 32, ..., 66), so that
  // the implicit step's C^-1 + P diag(d) P^T is one product of this with d; three rows of zeros
  // after the 21, so that a column is whole batches of 4 or 8 (21 would be pairs and one).
  static constexpr int kDyadRows = 24;
  Eigen::Matrix<double, kDyadRows, N, 0, kDyadRows, T::MaxN> schmid_dyads;
  typename T::MatNN interaction;         // A_ab = P_a : C : P_b
  typename T::Mat6N plane_normal_dyad;   // M_a = m_a (x) m_a (pressure-sensitive reading)
  typename T::Mat6N c_normal_dyad;       // C M_a
  typename T::MatNN normal_interaction;  // M_a : C : P_b
  typename T::Mat3N slip_spin;  // axial vector of skew(s_a (x) m_a): lattice spin per unit slip
  typename T::VecN tau0;        // reference stress per system (plays f_n)
  typename T::MatNN latent;     // q_ab (used only when has_latent)
  bool has_latent = false;
  // q = latent_self I + latent_factor latent_mix^T with as few columns as q allows (1 for a
  // latent ratio, planes + 1 for coplanar values): set by assemble(). The implicit step carries
  // latent_mix^T |dgamma| (latent_rank numbers) as unknowns, so its cost grows with the rank of
  // the latent coupling, not with the slip count.
  double latent_self = 1.0;
  int latent_rank = 0;
  typename T::MatNN latent_factor, latent_mix;  // first latent_rank columns used
  bool pressure_sensitive = false;
  Kinematics kinematics = Kinematics::finite_rotation;
  std::vector<law::SubloadingFrictionLaw> laws;  // one per slip system
  // Whether the implicit step evaluates the flow points in SIMD batches (one law with closed-form
  // updates for all systems, batches wide enough to pay: flow_point_batch.hpp). Set by
  // assemble() from `laws`, which are assigned first.
  bool batched_flow_points = false;
  // Each system's bound on the loading ratio r (set by assemble() from `laws`): r < r_hat under
  // an overstress form, 1 under the rate-independent form (whose steps may end within the flow
  // rule's tolerance above it). The end state's quick admissibility test reads it.
  typename T::VecN ratio_limit;

  // Builds the derived matrices from the slip directions/normals (lattice frame, unit vectors)
  // and the lattice-frame stiffness (after the laws, tau0 and the latent settings are set).
  void assemble(const std::vector<Vec3>& s, const std::vector<Vec3>& m, const Mat6& c);
};

template <int N>
struct GrainState {
  using T = SlipTypes<N>;
  Vec6 stress;            // Cauchy stress, lattice frame (Mandel)
  Mat3 orientation;       // g: v_crystal = g v_sample (passive, Rowenhorst P = -1)
  typename T::VecN mu;    // friction coefficient per system (CRSS = mu tau0)
  typename T::VecN r_s;   // subloading ratio per system
  typename T::VecN slip;  // accumulated signed slip per system
  typename T::VecN rate;  // slip rate of the last step (signed), warm start and output

  void reset(int n, const Mat3& g, const typename T::VecN& mu0);
  Vec6 sample_stress() const;
};

// Strain directions (sample frame, Mandel, 6 x k with k <= 6) along which a step's tangents are
// taken.
using StrainDirections = Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, 6>;

struct GrainStepOptions {
  double tolerance = 1e-12;  // on the flow residual, traction-ratio units
  int max_iterations = 60;
  // The tangents' columns: all six unit directions by default. Mixed control asks for its free
  // components' alone (their k columns cost a fraction of the six: the condensed system is
  // solved for k right-hand sides and only k columns are rotated to the sample frame).
  StrainDirections tangent_directions = Mat6::Identity();
  // Whether a semismooth step that Newton's iteration does not resolve from its start goes on
  // by continuation in the strain increment (semismooth_grain_step.cpp): a caller that will try
  // another start first turns it off for the first try.
  bool continuation = true;
};

// The flow-rule residual a grain step's end state is admitted with: the step's tolerance, but
// not below what double precision resolves of r (a few ulp of 1). A rate-independent system
// carries r = 1 to this residual where it is saturated (r_s = 1).
inline double admitted_flow_residual(const GrainStepOptions& opt) {
  return std::max(opt.tolerance, 16.0 * std::numeric_limits<double>::epsilon());
}

struct GrainStepReport {
  bool ok = false;
  int iterations = 0;
  int system = -1;  // the slip system that failed, when known
  const char* why = "";
};

// d sigma_sample(n+1) / d (D_sample dt) E, Mandel, when requested: 6 x k, E the options'
// tangent_directions (the identity by default: the full 6 x 6 tangent).
using Tangent = Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, 6>;

// d dgamma(n+1) / d (D_sample dt) E: how the step's slips follow its strain increment, when
// requested with the tangent (a mixed-control iteration starts the next solve of the same step
// from the slips it predicts); N x k.
template <int N>
using SlipTangent = Eigen::Matrix<double, N, Eigen::Dynamic, 0, SlipTypes<N>::MaxN, 6>;

// One implicit step of one grain: velocity gradient L (sample frame, constant over dt). The
// Newton iteration starts from the slip rates `start_rate` where their signs agree with the
// trial shears (default: s0.rate, the last step's): a mixed-control iteration passes the rates
// it predicts at a nearby L of the same step.
template <int N>
GrainStepReport implicit_grain_step(const Phase<N>& ph, const GrainState<N>& s0, const Mat3& L,
                                    double dt, const GrainStepOptions& opt, GrainState<N>& s1,
                                    Tangent* tangent,
                                    const typename SlipTypes<N>::VecN* start_rate = nullptr,
                                    SlipTangent<N>* slip_tangent = nullptr);

// One forward-Euler step (paper section 2f, method 2, applied per slip system). Refused (not ok,
// naming the system) when dt is above a slip system's stability limit 2/lambda, lambda =
// A_aa phi_r / (mu f_n), unless `stability` is unchecked. Its tangent (the elastic one, rotated)
// is the full 6 x 6.
template <int N>
GrainStepReport explicit_grain_step(const Phase<N>& ph, const GrainState<N>& s0, const Mat3& L,
                                    double dt, GrainState<N>& s1, Tangent* tangent,
                                    integrators::ExplicitStability stability =
                                        integrators::ExplicitStability::refuse_unstable_steps);

// The rates of one grain: the physics that forward Euler steps and the CVODE peer integrates.
// Split in two because the slip rates depend on the state alone while everything else is affine
// in the velocity gradient L (mixed control solves for the free components of L in between).
template <int N>
struct SlipRates {
  using VecN = typename SlipTypes<N>::VecN;
  VecN tau;   // resolved shear stress tau_a = sigma : P_a
  VecN fn;    // normal traction of each system: tau0 (or + the compressive plane stress)
  VecN r;     // dynamic loading ratio |tau_a| / (mu_a fn_a)
  VecN rate;  // signed slip rate phi(r_a, r_s,a) sign(tau_a); infinite for r_a >= r_hat
};

template <int N>
struct GrainRates {
  Vec6 strain_rate;   // D, lattice components (Mandel)
  Vec3 spin;          // W, lattice components (axial vector)
  Vec6 stress_rate;   // lattice components: C (D - sum_a gdot_a P_a), the corotational rate
  Vec3 lattice_spin;  // omega = W - sum_a gdot_a W_a: dg/dt = -[omega]x g (0 for small strain)
  typename SlipTypes<N>::VecN mu_rate;  // (3.4): kappa (1 - mu/mu_k) q|gdot| + xi (1 - mu/mu_s)
};

// The slip rates of a state. Not defined for the rate-independent form (its rows are 0).
template <int N>
void slip_rates(const Phase<N>& ph, const GrainState<N>& s, SlipRates<N>& out);

// The other rates at a state under L (sample frame), given its slip rates.
template <int N>
void grain_rates(const Phase<N>& ph, const GrainState<N>& s, const SlipRates<N>& slip,
                 const Mat3& L, GrainRates<N>& out);

// Makes a combination of implicit steps' end states (an extrapolated step) a state of the law:
// r_s restored to [0, r] (and taken from `finest`, the best single solution, where it reached 1
// and the finest did not). The combination leaves the admissible set only by the order of its
// error. The report is not ok (naming the system) where the state is still inadmissible
// (r >= r_hat, mu <= 0, non-finite; a rate-independent system's r above 1 by more than
// `flow_residual`, what the solutions' own steps admit: admitted_flow_residual): the step is
// then redone shorter.
template <int N>
GrainStepReport restore_extrapolated_state(const Phase<N>& ph, const GrainState<N>& finest,
                                           GrainState<N>& s, double flow_residual);

// Dynamic loading ratio r_a = |tau_a| / (mu_a f_n,a) of a state, per system.
template <int N>
typename SlipTypes<N>::VecN loading_ratio(const Phase<N>& ph, const GrainState<N>& s);

// Normal traction f_n,a of a state, per system: tau0_a, or with the pressure-sensitive reading
// tau0_a - M_a : sigma (the plane is open where f_n,a <= 0).
template <int N>
typename SlipTypes<N>::VecN normal_traction(const Phase<N>& ph, const GrainState<N>& s);

// The yield scale of each system of a state, the unit of the error estimates of the adaptive
// integrators: the CRSS mu_a tau0_a, or with the pressure-sensitive reading the plane's yield
// traction mu_a f_n,a where its compression raises it above that (as a contact's estimate is in
// units of its yield traction f_n mu); never below the CRSS, which is the yield of the plane
// without normal stress, so that an estimate keeps a finite unit as a plane opens.
template <int N>
typename SlipTypes<N>::VecN yield_scale(const Phase<N>& ph, const GrainState<N>& s);

}  // namespace subslip::crystal
