#pragma once
// Empirical stability of forward Euler at a state: whether repeated steps of dt damp a small
// perturbation of it. This is the measurement behind the linearised limit dt < 2/lambda that the
// extreme-case report prints and the tests check. Every step is taken
// (ExplicitStability::unchecked), including steps above the limit that a run would refuse.

#include "subslip/contact/contact_point.hpp"
#include "subslip/crystal/crystal_kernel.hpp"
#include "subslip/law/subloading_friction.hpp"

namespace subslip::study {

struct PerturbationProbe {
  int steps = 400;             // forward Euler steps taken from the perturbed state
  double perturbation = 1e-6;  // relative size of the perturbation of the traction / stress
};

// Contact sliding at `speed` along x: the tangential traction and r of `steady` are scaled by
// 1 + perturbation; true when r is closer to steady's after the steps (none failed).
bool forward_euler_damps_contact_perturbation(const law::SubloadingFrictionLaw& law,
                                              const contact::ContactStiffness& stiffness,
                                              const contact::ContactState& steady, double speed,
                                              double dt, PerturbationProbe probe = {});

// One slip system under the velocity gradient L: the stress of `steady` is scaled by
// 1 + perturbation; true when its loading ratio is closer to steady's after the steps.
bool forward_euler_damps_grain_perturbation(const crystal::Phase<Eigen::Dynamic>& phase,
                                            const crystal::GrainState<Eigen::Dynamic>& steady,
                                            const crystal::Mat3& L, double dt,
                                            PerturbationProbe probe = {});

}  // namespace subslip::study
