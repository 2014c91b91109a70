#include "subslip/study/explicit_stability.hpp"

#include <cmath>

namespace subslip::study {

bool forward_euler_damps_contact_perturbation(const law::SubloadingFrictionLaw& law,
                                              const contact::ContactStiffness& stiffness,
                                              const contact::ContactState& steady, double speed,
                                              double dt, PerturbationProbe probe) {
  contact::ContactState s = steady;
  s.traction_t *= 1.0 + probe.perturbation;
  s.r *= 1.0 + probe.perturbation;
  const double d0 = std::abs(s.r - steady.r);
  for (int i = 0; i < probe.steps; ++i) {
    const auto a =
        contact::forward_euler_step(law, stiffness, s, contact::Vec2(speed * dt, 0.0), s.traction_n,
                                    dt, integrators::ExplicitStability::unchecked);
    if (!a.ok) return false;
    s = a.state;
  }
  return std::abs(s.r - steady.r) < d0;
}

bool forward_euler_damps_grain_perturbation(const crystal::Phase<Eigen::Dynamic>& phase,
                                            const crystal::GrainState<Eigen::Dynamic>& steady,
                                            const crystal::Mat3& L, double dt,
                                            PerturbationProbe probe) {
  const double r = crystal::loading_ratio(phase, steady)(0);
  crystal::GrainState<Eigen::Dynamic> x = steady;
  x.stress *= 1.0 + probe.perturbation;
  const double d0 = std::abs(crystal::loading_ratio(phase, x)(0) - r);
  for (int i = 0; i < probe.steps; ++i) {
    crystal::GrainState<Eigen::Dynamic> next = x;
    if (!crystal::explicit_grain_step(phase, x, L, dt, next, nullptr,
                                      integrators::ExplicitStability::unchecked)
             .ok)
      return false;
    x = next;
  }
  return std::abs(crystal::loading_ratio(phase, x)(0) - r) < d0;
}

}  // namespace subslip::study
