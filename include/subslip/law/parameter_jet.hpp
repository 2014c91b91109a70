// The law's step updates as functions of its constants: forward-mode automatic differentiation
// (Ceres' Jet) through the same closed forms the double path takes (closed_form.hpp), for the
// sensitivities of an implicit step (contact/contact_point.hpp). A ParameterJet carries a value
// and its derivatives with respect to the eight constants of kLawParameters, in that table's
// order. Only the differentiated paths include this header: the double path compiles as before.
#pragma once

#include <ceres/jet.h>

#include <Eigen/Core>
#include <cstddef>

#include "subslip/law/closed_form.hpp"
#include "subslip/law/parameter_table.hpp"
#include "subslip/law/subloading_friction.hpp"

namespace subslip::law {

using ParameterJet = ceres::Jet<double, kParameterCount>;

// A jet of value x and gradient g.
inline ParameterJet make_jet(double x, const ParameterGradient& g) {
  ParameterJet j(x);
  j.v = g.transpose();
  return j;
}
inline ParameterGradient gradient(const ParameterJet& j) {
  return j.v.transpose();
}

// The members the closed forms read, as jets (closed_form.hpp takes any struct of these names).
struct FrictionJet {
  ParameterJet mu_s, mu_k, kappa, xi;
};
struct OverstressJet {
  OverstressForm form;
  ParameterJet eta_v, n, r_hat;
};

// The law with every constant seeded as its own variable: d(constant k)/d(constant j) = delta_kj.
class SubloadingFrictionJet {
 public:
  explicit SubloadingFrictionJet(const SubloadingFrictionLaw& law);

  // mu after a slip over dt (closed_form::friction_coefficient_after, regular where the double
  // path returns early: no slip and no recovery time, or kappa = xi = 0).
  ParameterJet friction_coefficient_after(const ParameterJet& mu0, const ParameterJet& slip,
                                          const ParameterJet& dt) const;
  // r_s after a slip from r0 (subloading_ratio_after). The cot form differentiates its closed
  // form; the others differentiate H(r1) = H(r0) + slip implicitly at the double path's root.
  ParameterJet subloading_ratio_after(const ParameterJet& r0, const ParameterJet& slip) const;
  // The flow residual G(r, r_s, slip, dt) (flow_residual), where it is admissible (r < r_hat).
  ParameterJet flow_residual(const ParameterJet& r, const ParameterJet& r_s,
                             const ParameterJet& slip, const ParameterJet& dt) const;

 private:
  // From a start r0 in (0, 1), or from a virgin start (r0 = 0).
  ParameterJet subloading_ratio_after(const ParameterJet& r0, const ParameterJet& slip,
                                      bool virgin) const;

  const SubloadingFrictionLaw& law_;
  FrictionJet friction_;
  ParameterJet u_tilde_;
  OverstressJet overstress_;
};

}  // namespace subslip::law
