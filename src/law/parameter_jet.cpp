#include "subslip/law/parameter_jet.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace subslip::law {

namespace {

// The index of a constant in kLawParameters; a name that is not there fails the build.
constexpr int index_of(std::string_view name) {
  for (std::size_t k = 0; k < kLawParameters.size(); ++k)
    if (kLawParameters[k].name == name) return static_cast<int>(k);
  throw "not a law parameter";
}
constexpr int kMuS = index_of("mu_s"), kMuK = index_of("mu_k"), kKappa = index_of("kappa"),
              kXi = index_of("xi"), kUTilde = index_of("u_tilde"), kEtaV = index_of("eta_v"),
              kN = index_of("n"), kRHat = index_of("r_hat");

}  // namespace

SubloadingFrictionJet::SubloadingFrictionJet(const SubloadingFrictionLaw& law) : law_(law) {
  const LawParameters& p = law.parameters();
  const FrictionCoefficientEvolution& f = p.friction;
  const Overstress& o = p.overstress;
  friction_ = {ParameterJet(f.mu_s, kMuS), ParameterJet(f.mu_k, kMuK),
               ParameterJet(f.kappa, kKappa), ParameterJet(f.xi, kXi)};
  u_tilde_ = ParameterJet(p.subloading.u_tilde, kUTilde);
  overstress_ = {o.form, ParameterJet(o.eta_v, kEtaV), ParameterJet(o.n, kN),
                 ParameterJet(o.r_hat, kRHat)};
}

ParameterJet SubloadingFrictionJet::friction_coefficient_after(const ParameterJet& mu0,
                                                               const ParameterJet& slip,
                                                               const ParameterJet& dt) const {
  return closed_form::friction_coefficient_after(friction_, mu0, slip, dt).value;
}

ParameterJet SubloadingFrictionJet::subloading_ratio_after(const ParameterJet& r0,
                                                           const ParameterJet& slip) const {
  // The double path clamps the start to [0, 1]: at a bound the start is a constant.
  if (!(r0.a > 0.0)) return subloading_ratio_after(ParameterJet(0.0), slip, true);
  if (!(r0.a < 1.0)) return ParameterJet(1.0);
  return subloading_ratio_after(r0, slip, false);
}

ParameterJet SubloadingFrictionJet::subloading_ratio_after(const ParameterJet& r0,
                                                           const ParameterJet& slip,
                                                           bool virgin) const {
  if (!(slip.a > 0.0)) return r0;
  if (law_.parameters().subloading.function == SubloadingFunction::cot) {
    // A virgin start is cos = 1, 1 - cos = 0 (the double path's subloading_start).
    const auto start =
        virgin ? closed_form::CotStartOf<ParameterJet>{ParameterJet(1.0), ParameterJet(0.0),
                                                       ParameterJet(
                                                           std::numeric_limits<double>::infinity())}
               : closed_form::cot_subloading_start(u_tilde_, r0);
    return closed_form::cot_subloading_ratio_after(u_tilde_, r0, start.cos0, start.one_minus_cos0,
                                                   start.rate0, slip)
        .value;
  }
  // The other forms invert their slip integral H numerically. u H(r) = h(r) is free of u, so
  // h(r1) = h(r0) + u slip with h' = u / U: dr1 = (U(r1)/u) (dr0 u/U(r0) + d(u slip)).
  const double r1 = law_.subloading_ratio_after(r0.a, slip.a).value;
  if (!(r1 > r0.a) || !(r1 < 1.0)) return ParameterJet(r1);  // stopped at a bound
  const double u = u_tilde_.a;
  const double q0 = law_.subloading_rate(r0.a) / u, q1 = law_.subloading_rate(r1) / u;
  ParameterJet out(r1);
  out.v = q1 * (u_tilde_ * slip).v;
  if (!virgin) out.v += (q1 / q0) * r0.v;
  return out;
}

ParameterJet SubloadingFrictionJet::flow_residual(const ParameterJet& r, const ParameterJet& r_s,
                                                  const ParameterJet& slip,
                                                  const ParameterJet& dt) const {
  switch (overstress_.form) {
    case OverstressForm::rate_independent:
      return r - r_s;
    case OverstressForm::exponential:
      return closed_form::exponential_flow_residual(overstress_, r, r_s, slip, dt).value;
    case OverstressForm::power:
      break;
  }
  const ParameterJet y = overstress_.eta_v * (overstress_.r_hat - r) * (slip / dt);
  const ParameterJet inverse = y.a > 0.0 ? pow(y, 1.0 / overstress_.n) : ParameterJet(0.0);
  return (r - r_s) - inverse;
}

}  // namespace subslip::law
