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
template <class J>
struct FrictionJetOf {
  J mu_s, mu_k, kappa, xi;
};
template <class J>
struct OverstressJetOf {
  OverstressForm form;
  J eta_v, n, r_hat;
};

// The law with every constant seeded as its own variable: d(constant k)/d(constant j) = delta_kj
// for the first kParameterCount derivatives of the jet J (a grain's jets carry more after them,
// src/crystal/grain_sensitivity.cpp). Without `seeded` the constants are constants: the jets
// then differentiate with respect to whatever the caller seeds (a grain's slips).
template <class J>
class BasicSubloadingFrictionJet {
 public:
  explicit BasicSubloadingFrictionJet(const SubloadingFrictionLaw& law, bool seeded = true);

  // mu after a slip over dt (closed_form::friction_coefficient_after, regular where the double
  // path returns early: no slip and no recovery time, or kappa = xi = 0).
  J friction_coefficient_after(const J& mu0, const J& slip, const J& dt) const;
  // r_s after a slip from r0 (subloading_ratio_after). The cot form differentiates its closed
  // form; the others differentiate H(r1) = H(r0) + slip implicitly at the double path's root.
  J subloading_ratio_after(const J& r0, const J& slip) const;
  // The flow residual G(r, r_s, slip, dt) (flow_residual), where it is admissible (r < r_hat).
  J flow_residual(const J& r, const J& r_s, const J& slip, const J& dt) const;

 private:
  // From a start r0 in (0, 1), or from a virgin start (r0 = 0).
  J subloading_ratio_after(const J& r0, const J& slip, bool virgin) const;

  const SubloadingFrictionLaw& law_;
  FrictionJetOf<J> friction_;
  J u_tilde_;
  OverstressJetOf<J> overstress_;
};

using SubloadingFrictionJet = BasicSubloadingFrictionJet<ParameterJet>;
// A grain's jets: the law's constants, then tau0 and the initial friction coefficient.
using GrainParameterJet = ceres::Jet<double, kParameterCount + 2>;
extern template class BasicSubloadingFrictionJet<ParameterJet>;
extern template class BasicSubloadingFrictionJet<GrainParameterJet>;

}  // namespace subslip::law
