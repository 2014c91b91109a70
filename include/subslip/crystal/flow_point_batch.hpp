#pragma once
// Every slip system's implicit flow rule at one trial point, evaluated as a structure of arrays
// in SIMD batches (xsimd, the widest instruction set the build targets): the grain solver's
// evaluations spend most of their time in the law's transcendentals (expm1, asin or acos,
// log1p per system), which one batch computes for 2 (SSE2), 4 (AVX2) or 8 (AVX-512) systems at
// once. The formulas are the law's own (law/closed_form.hpp); only laws whose updates are in
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
// G = +inf where r >= r_hat or mu <= 0 (outside the flow rule's domain).
struct FlowBatchOutput {
  alignas(64) FlowBatchArray g, g_slip, g_r, r, mu_slope, mu, r_s;
};

// Whether the build's batches are wide enough to pay: 4 or 8 doubles (AVX2, AVX-512; a build
// with -DSUBSLIP_NATIVE=ON on such a machine). With SSE2's 2 (the portable build) the batched
// transcendentals measured slower than glibc's scalar ones (which select FMA code at run time):
// the solver then evaluates system by system.
bool flow_batches_pay();

// Whether the first `count` systems share one law whose flow points have the batched closed form.
bool has_batched_flow_points(const std::vector<law::SubloadingFrictionLaw>& laws, int count);

// Zeroes the lanes after the first `count` up to the widest batch, which batched_flow_points
// computes on and does not report (so that they hold numbers, not whatever memory was there).
void clear_batch_padding(FlowBatchInput& in, int count);

// Fills `out` for systems 0 ... count - 1 (count <= kMaxSlipSystems), all of the law `p`;
// `latent_self` is q, the weight of a system's own slip in its hardening.
void batched_flow_points(const law::LawParameters& p, double dt, double latent_self, int count,
                         const FlowBatchInput& in, FlowBatchOutput& out);

}  // namespace subslip::crystal::detail
