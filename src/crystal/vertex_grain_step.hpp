// The grain step of the rate-independent form without hardening of mu (kappa = 0): the
// stress of the step as the minimiser of a convex function over the yield polytope, solved by
// sequential quadratic programming with a dual active-set method (Goldfarb and Idnani 1983) for
// each quadratic subproblem. docs/grain_step.md ("The rate-independent step on the yield
// polytope") gives the formulation and why it converges where Newton on per-system flow rules
// does not: near saturation (r_s -> 1) a system's hardening vanishes in double precision, the
// slip of a vertex with more active systems than independent Schmid tensors is not determined,
// and only complementarity with the stress (not a flow-rule slope) decides which systems slip.
// Where the slip among saturated systems is left open, the step takes its least-norm split
// ("The least-norm split at a saturated vertex"), a function of the loading.
// Internal to src/crystal/.
#pragma once

#include "subslip/crystal/crystal_kernel.hpp"

namespace subslip::crystal::detail {

// Whether the vertex step's formulation holds for the phase: every system rate-independent with
// mu independent of slip (kappa = 0; recovery in time is allowed), no plane pressure.
template <int N>
bool vertex_step_applies(const Phase<N>& ph);

template <int N>
GrainStepReport vertex_grain_step(const Phase<N>& ph, const GrainState<N>& s0, const Mat3& L,
                                  double dt, const GrainStepOptions& opt, GrainState<N>& s1,
                                  Tangent* tangent, SlipTangent<N>* slip_tangent = nullptr);

}  // namespace subslip::crystal::detail
