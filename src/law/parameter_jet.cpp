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

template <class J>
BasicSubloadingFrictionJet<J>::BasicSubloadingFrictionJet(const SubloadingFrictionLaw& law,
                                                          bool seeded)
    : law_(law) {
  const LawParameters& p = law.parameters();
  const FrictionCoefficientEvolution& f = p.friction;
  const Overstress& o = p.overstress;
  auto constant = [&](double value, int k) { return seeded ? J(value, k) : J(value); };
  friction_ = {constant(f.mu_s, kMuS), constant(f.mu_k, kMuK), constant(f.kappa, kKappa),
               constant(f.xi, kXi)};
  u_tilde_ = constant(p.subloading.u_tilde, kUTilde);
  overstress_ = {o.form, constant(o.eta_v, kEtaV), constant(o.n, kN), constant(o.r_hat, kRHat)};
}

template <class J>
J BasicSubloadingFrictionJet<J>::friction_coefficient_after(const J& mu0, const J& slip,
                                                            const J& dt) const {
  return closed_form::friction_coefficient_after(friction_, mu0, slip, dt).value;
}

template <class J>
J BasicSubloadingFrictionJet<J>::subloading_ratio_after(const J& r0, const J& slip) const {
  // The double path clamps the start to [0, 1]: at a bound the start is a constant.
  if (!(r0.a > 0.0)) return subloading_ratio_after(J(0.0), slip, true);
  if (!(r0.a < 1.0)) return J(1.0);
  return subloading_ratio_after(r0, slip, false);
}

template <class J>
J BasicSubloadingFrictionJet<J>::subloading_ratio_after(const J& r0, const J& slip,
                                                        bool virgin) const {
  if (!(slip.a > 0.0)) return r0;
  if (law_.parameters().subloading.function == SubloadingFunction::cot) {
    // A virgin start is cos = 1, 1 - cos = 0 (the double path's subloading_start).
    const auto start =
        virgin
            ? closed_form::CotStartOf<J>{J(1.0), J(0.0), J(std::numeric_limits<double>::infinity())}
            : closed_form::cot_subloading_start(u_tilde_, r0);
    return closed_form::cot_subloading_ratio_after(u_tilde_, r0, start.cos0, start.one_minus_cos0,
                                                   start.rate0, slip)
        .value;
  }
  // The other forms invert their slip integral H numerically. u H(r) = h(r) is free of u, so
  // h(r1) = h(r0) + u slip with h' = u / U: dr1 = (U(r1)/u) (dr0 u/U(r0) + d(u slip)).
  const double r1 = law_.subloading_ratio_after(r0.a, slip.a).value;
  if (!(r1 > r0.a) || !(r1 < 1.0)) return J(r1);  // stopped at a bound
  const double u = u_tilde_.a;
  const double q0 = law_.subloading_rate(r0.a) / u, q1 = law_.subloading_rate(r1) / u;
  J out(r1);
  out.v = q1 * (u_tilde_ * slip).v;
  if (!virgin) out.v += (q1 / q0) * r0.v;
  return out;
}

template <class J>
J BasicSubloadingFrictionJet<J>::flow_residual(const J& r, const J& r_s, const J& slip,
                                               const J& dt) const {
  switch (overstress_.form) {
    case OverstressForm::rate_independent:
      return r - r_s;
    case OverstressForm::exponential:
      return closed_form::exponential_flow_residual(overstress_, r, r_s, slip, dt).value;
    case OverstressForm::power:
      break;
  }
  const J y = overstress_.eta_v * (overstress_.r_hat - r) * (slip / dt);
  const J inverse = y.a > 0.0 ? pow(y, 1.0 / overstress_.n) : J(0.0);
  return (r - r_s) - inverse;
}

template class BasicSubloadingFrictionJet<ParameterJet>;
template class BasicSubloadingFrictionJet<GrainParameterJet>;

}  // namespace subslip::law
