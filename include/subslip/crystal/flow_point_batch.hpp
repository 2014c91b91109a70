#pragma once
// Every slip system's implicit flow rule at one trial point, evaluated as a structure of arrays
// in SIMD batches (xsimd): the grain solver's evaluations spend most of their time in the law's
// transcendentals (expm1, asin, log1p per system), which one batch computes for 4 (AVX2) or 8
// (AVX-512) systems at once, with the widest instruction set the machine has, chosen at run
// time. The formulas are the law's own (law/closed_form.hpp); only laws whose updates are in
// closed form are batched (cot subloading, exponential overstress: the paper's law), the others
// keep the system-by-system path.

#include <array>
#include <vector>

#include "subslip/crystal/crystal_kernel.hpp"
#include "subslip/law/subloading_friction.hpp"

namespace subslip::crystal::detail {

// Room for the largest slip count, rounded up to the widest batch (8 doubles).
inline constexpr int kFlowBatchCapacity = (kMaxSlipSystems + 7) / 8 * 8;
using FlowBatchArray = std::array<double, kFlowBatchCapacity>;

// Per system: the state at the start of the step and the trial point (slip = z^2, z = ds^(1/2)).
struct FlowBatchInput {
  alignas(64) FlowBatchArray mu0;        // mu at the start of the step
  alignas(64) FlowBatchArray slip;       // |ds| of the system
  alignas(64) FlowBatchArray effective;  // q |ds| + the latent drive: the slip that hardens it
  alignas(64) FlowBatchArray r0, cos0, one_minus_cos0, rate0;  // its subloading start
  alignas(64) FlowBatchArray shear;                            // |tau|
  alignas(64) FlowBatchArray normal;                           // f_n
};

// Per system: G, dG/d ds, dG/dr, r = |tau|/(mu f_n), d mu / d(effective slip), mu, r_s.
// G = +inf where r >= r_hat or mu <= 0 (outside the flow rule's domain). And the coefficients of
// its slip's Newton linearisation without the shear's sign s (StressSolver::SlipPoint: w = s
// newton_w, d = newton_d, l = s newton_l), each divided by -dG/d ds: meaningful where
// dG/d ds < 0 and finite.
struct FlowBatchOutput {
  alignas(64) FlowBatchArray g, g_slip, g_r, r, mu_slope, mu, r_s;
  alignas(64) FlowBatchArray newton_w;  // G / (-dG/d ds)
  alignas(64) FlowBatchArray newton_d;  // dG/dr / (mu f_n) / (-dG/d ds)
  alignas(64) FlowBatchArray newton_l;  // dG/dr (-r/mu) d mu/d(effective slip) / (-dG/d ds)
};

// Every system's cot subloading start (law::SubloadingFrictionLaw::subloading_start) from its
// r0 in [0, 1]: cos(pi r0/2), 1 - cos(pi r0/2), U(r0). The lanes after the systems hold r0 = 0.
struct SubloadingStartBatch {
  alignas(64) FlowBatchArray r0{}, cos0, one_minus_cos0, rate0;
};

// The instruction sets a batch can use: the build's own (SSE2 in the portable build; what the
// machine has in a -DSUBSLIP_NATIVE=ON one) and, in an x86-64 build, AVX2 with FMA (4 doubles)
// and AVX-512 (8 doubles), compiled apart and chosen at run time: the widest the machine has.
enum class FlowBatchIsa { build, avx2, avx512 };
bool flow_batch_isa_available(FlowBatchIsa isa);
// Doubles per batch of the chosen instruction set.
int flow_batch_width();
// Whether the chosen batches are wide enough to pay: 4 or 8 doubles. With SSE2's 2 (a machine
// without AVX2) the batched transcendentals measured slower than glibc's scalar ones (which
// select FMA code at run time): the solver then evaluates system by system.
bool flow_batches_pay();
// The level of the batches the solver takes: 0 none (system by system), 1 four doubles (AVX2),
// 2 eight (AVX-512).
int flow_batch_level();
// From here on the solver takes batches of at most this level (phases assembled later follow
// it): what the MPI ranks of one run agree on, the least level among them, so that every rank
// computes with the same kernels (results of different kernels differ by round-off).
void limit_flow_batches(int level);
// The chosen kernels' instruction set as results record it: "avx512", "avx2", or "none" where
// batches do not pay (the system-by-system path).
const char* flow_batch_isa_name();
// The instruction set the grain step of 12, 24 and 48 slip systems runs in, as --version says:
// a host build's one set ("avx512" or "avx2"); in a build with both beside the portable step,
// the batches' ("avx512", "avx2", or "baseline": the build's x86-64 code); in any other build the
// build's own code ("native" or "baseline").
const char* grain_step_isa_name();
// Throws std::runtime_error, saying how to build for it, where this machine does not run the
// instruction set that a host build compiled its grain step of 12, 24 and 48 systems for (the
// binary was built on another machine).
void require_grain_step_isa();
// Whether the first `count` systems share one law whose flow points have the batched closed form.
bool has_batched_flow_points(const std::vector<law::SubloadingFrictionLaw>& laws, int count);

// Zeroes the lanes after the first `count` up to the end of the chosen kernel's last batch,
// which batched_flow_points computes on and does not report (so that they hold numbers, not
// whatever memory was there).
void clear_batch_padding(FlowBatchInput& in, int count);

// Fills the starts of systems 0 ... count - 1 from their r0, for the cot subloading function of
// u_tilde, with the chosen instruction set or a given (available) one.
void batched_subloading_starts(double u_tilde, int count, SubloadingStartBatch& s);
void batched_subloading_starts(double u_tilde, int count, SubloadingStartBatch& s,
                               FlowBatchIsa isa);
// Fills `out` for systems 0 ... count - 1 (count <= kMaxSlipSystems), all of the law `p`;
// `latent_self` is q, the weight of a system's own slip in its hardening.
void batched_flow_points(const law::LawParameters& p, double dt, double latent_self, int count,
                         const FlowBatchInput& in, FlowBatchOutput& out);
// The same with a given (available) instruction set.
void batched_flow_points(const law::LawParameters& p, double dt, double latent_self, int count,
                         const FlowBatchInput& in, FlowBatchOutput& out, FlowBatchIsa isa);

}  // namespace subslip::crystal::detail
