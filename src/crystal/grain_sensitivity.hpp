// The forward sensitivities of an implicit grain step (point::GrainPoint's update with a
// GrainSensitivity): the step replayed in automatic-differentiation scalars of the law's
// constants, the converged slips differentiated through the step's own equations instead of
// iterated again. Compiled apart from the grain step: the double path does not include it.
// Internal to src/crystal/.
#pragma once

#include "subslip/crystal/crystal_kernel.hpp"
#include "subslip/crystal/grain_sensitivity.hpp"

namespace subslip::crystal {

// The sensitivities of a virgin state of n systems: zero, but for mu, whose start is the
// phase's initial_mu or, where the phase starts from mu_s, mu_s.
GrainSensitivity initial_grain_sensitivity(int n, bool initial_mu_is_mu_s);

// The sensitivities after the converged implicit step from s0 (sensitivities `d`) under L over
// dt to s1, into `d`; under mixed control (`mixed` with directions) through the free components'
// own change as well (MixedControlSensitivity). The phase's systems share one law and one tau0
// and no plane pressure (the caller checks). Throws std::runtime_error where the step's
// equations are singular in its slips, or the held stresses in the free components (no
// sensitivity exists there).
template <int N>
void carry_grain_sensitivity(const Phase<N>& ph, const GrainState<N>& s0, const Mat3& L, double dt,
                             const GrainState<N>& s1, GrainSensitivity& d,
                             MixedControlSensitivity* mixed = nullptr);

// The step's end state written from its signed slips dgamma (as carry_grain_sensitivity
// differentiates it), and each slipping system's flow residual there (0 where dgamma_a = 0).
template <int N>
struct ReplayedStep {
  GrainState<N> state;
  typename SlipTypes<N>::VecN residual;
};
template <int N>
ReplayedStep<N> replayed_grain_step(const Phase<N>& ph, const GrainState<N>& s0, const Mat3& L,
                                    double dt, const typename SlipTypes<N>::VecN& dgamma);

}  // namespace subslip::crystal
