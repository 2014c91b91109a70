// The grain step for laws outside the stress-space solver's assumptions (implicit_grain_step.hpp,
// docs/grain_step.md): a semismooth Newton iteration on the signed slips, each system's residual
// continuous through zero slip (docs/grain_step.md, "The semismooth step on signed slips"), with
// the merit 1/2 |rows|^2. It is kept
// for what the stress-space formulation does not cover: friction coefficients that soften with
// slip (mu above mu_k, or mu_k below mu_s), where a system's slip at a held shear need not exist,
// pressure-sensitive planes, and the rate-independent form, whose slip response to the shear is
// unbounded at r_s = 1. Where Newton's iteration from the warm start does not converge, the same
// step is solved by continuation in its strain increment (GrainStepOptions::continuation;
// docs/grain_step.md, "Continuation in the strain increment"). Internal to src/crystal/.
#pragma once

#include "subslip/crystal/crystal_kernel.hpp"

namespace subslip::crystal::detail {

template <int N>
GrainStepReport semismooth_grain_step(const Phase<N>& ph, const GrainState<N>& s0, const Mat3& L,
                                      double dt, const GrainStepOptions& opt, GrainState<N>& s1,
                                      Tangent* tangent,
                                      const typename SlipTypes<N>::VecN* start_rate,
                                      SlipTangent<N>* slip_tangent = nullptr);

}  // namespace subslip::crystal::detail
