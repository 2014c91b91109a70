// The subloading-overstress friction law of Hashiguchi et al. (2016), Proc. R. Soc. A 472:20160212.
//
// This is the one place where the physics of the law lives. It knows nothing about contacts,
// crystals, files or integrators: given the traction ratio r = f(f)/mu (dynamic loading ratio),
// the state (mu, r_s) and an amount of viscoplastic slip, it gives rates, exact updates and the
// partial derivatives an implicit solver needs. The same object serves one frictional contact
// (slip = sliding distance) and every slip system of a crystal (slip = shear on that system).
//
// Equation numbers refer to the paper.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <string_view>

namespace subslip::law {

// U(r) of the subloading evolution dr_s = U(r_s) |du_vp| (2.25, 3.11).
enum class SubloadingFunction {
  cot,  // U = u_tilde cot(pi r / 2)        (2.27), the paper's choice; closed-form integral (2.28)
  neg_log,     // U = -u_tilde ln r                (2.29)_1
  reciprocal,  // U = u_tilde (1/r - 1)            (2.29)_2
};

// Viscoplastic slip rate as a function of the overstress r - r_s.
enum class OverstressForm {
  exponential,       // (e^{n(r-r_s)} - 1) / (eta_v (r_hat - r))   (3.15), the default
  power,             // <r - r_s>^n / (eta_v (r_hat - r))          (3.10)
  rate_independent,  // subloading-friction model of section 2: r = r_s while sliding (2.42-2.47)
};

std::string_view to_string(SubloadingFunction f);
std::string_view to_string(OverstressForm f);

// Evolution of the friction coefficient (2.32, 3.4):
//   dmu = kappa (1 - mu/mu_k) |du_vp| + xi (1 - mu/mu_s) dt.
// mu_k < mu_s softens by sliding (friction); mu_k > mu_s hardens by slip toward mu_k (crystals).
struct FrictionCoefficientEvolution {
  double mu_s = 0.097;  // static friction coefficient: target of recovery with time
  double mu_k = 0.085;  // kinetic friction coefficient: target of sliding
  double kappa = 1.0;   // sliding softening (or hardening) rate [1/slip unit]
  double xi = 0.005;    // recovery (creep-hardening) rate [1/time unit]
  bool operator==(const FrictionCoefficientEvolution&) const = default;
};

struct SubloadingEvolution {
  SubloadingFunction function = SubloadingFunction::cot;
  double u_tilde = 80.0;  // [1/slip unit]
  bool operator==(const SubloadingEvolution&) const = default;
};

struct Overstress {
  OverstressForm form = OverstressForm::exponential;
  double eta_v = 1000.0;  // viscoplastic coefficient [time/slip unit]
  double n = 16.0;        // exponent
  double r_hat = 1.6;     // limit dynamic loading ratio (> 1)
  bool operator==(const Overstress&) const = default;
};

struct LawParameters {
  FrictionCoefficientEvolution friction;
  SubloadingEvolution subloading;
  Overstress overstress;
  bool operator==(const LawParameters&) const = default;
};

// The state the law carries from step to step.
struct LawState {
  double mu = 0.097;  // friction coefficient (crystal: CRSS / tau0)
  double r_s = 0.0;   // subloading ratio, 0 <= r_s <= 1
};

// A value with its derivative with respect to the slip increment of the step.
struct ValueAndSlope {
  double value;
  double d_slip;
};

// The flow rule written as a residual that vanishes on the solution of an implicit step:
//   G(r, r_s, ds, dt) = (r - r_s) - g^{-1}(eta_v (r_hat - r) ds / dt)
// where g is the overstress function. It is in units of a traction ratio (O(1)), is monotone
// in each argument and stays finite as ds -> 0 for the exponential form; this is what makes a
// Newton iteration on it well conditioned where the forward form ds = dt phi(r, r_s) is not.
// admissible == false means r >= r_hat: no finite slip rate satisfies the flow rule, and the
// caller must take more slip (G is then reported as +infinity).
struct FlowResidual {
  double value;
  double d_r;
  double d_rs;
  double d_slip;
  bool admissible;
};

class SubloadingFrictionLaw {
 public:
  explicit SubloadingFrictionLaw(const LawParameters& p);

  const LawParameters& parameters() const { return p_; }
  bool is_rate_independent() const {
    return p_.overstress.form == OverstressForm::rate_independent;
  }

  // U(r): rate of change of the subloading ratio per unit viscoplastic slip.
  double subloading_rate(double r) const;

  // Viscoplastic slip rate phi(r, r_s) >= 0 (forward form, for explicit integration).
  // Returns +infinity for r >= r_hat. Not defined for the rate-independent form (returns 0).
  double slip_rate(double r, double r_s) const;
  // d phi / d r at (r, r_s), for explicit stability estimates.
  double slip_rate_slope(double r, double r_s) const;
  // The rate at which a perturbation of the traction relaxes while sliding under an elastic
  // stiffness k (contact: alpha_t; slip system: A_aa = P_a : C : P_a) at friction coefficient mu
  // and normal traction f_n (slip system: tau0): lambda = k phi_r / (mu f_n). Forward Euler
  // multiplies the perturbation by 1 - lambda dt per step: stable for dt <= 2/lambda.
  double traction_relaxation_rate(double stiffness, double r, double r_s, double mu,
                                  double normal_traction) const {
    return stiffness * slip_rate_slope(r, r_s) / (mu * normal_traction);
  }

  // Exact integral of dr_s = U(r_s) ds from r_s0 over a slip ds >= 0 (2.28 for cot; the other
  // two forms are integrated exactly too, by inverting their closed-form integrals). The slope is
  // U(r_s1). Regular at r_s0 = 0.
  ValueAndSlope subloading_ratio_after(double r_s0, double slip) const;

  // The same update split in two: what depends only on r_s0 is prepared once per step, so an
  // implicit solver that evaluates many trial slips pays for it once.
  struct SubloadingStart {
    double r0;
    double cos0;            // cot form: cos(pi r0/2)
    double one_minus_cos0;  // cot form: 1 - cos(pi r0/2), kept accurate for small r0
    double integral0;       // other forms: the slip integral H(r0)
    double rate0;           // U(r0), the slope at zero slip
  };
  SubloadingStart subloading_start(double r_s0) const;
  ValueAndSlope subloading_ratio_after(const SubloadingStart& start, double slip) const;

  // Exact integral of the mu evolution over a step of length dt with slip ds at constant rate.
  // `slip` is the effective slip driving mu (crystal: sum_b q_ab |dgamma_b|).
  ValueAndSlope friction_coefficient_after(double mu0, double slip, double dt) const;

  // The implicit flow residual (see FlowResidual). slip >= 0, dt > 0.
  FlowResidual flow_residual(double r, double r_s, double slip, double dt) const;

  // The exponent p of the unknown z = ds^(1/p) in which implicit solvers should iterate: with
  // the power overstress the flow residual behaves like -ds^(1/n) near ds = 0 (infinite slope,
  // roots as small as 1e-70), but is smooth and well scaled in z = ds^(1/n). p = 1 otherwise.
  double slip_exponent() const {
    return p_.overstress.form == OverstressForm::power ? std::max(p_.overstress.n, 1.0) : 1.0;
  }

  // |dG/dz| of the flow residual's overstress term at zero slip over a step dt from loading
  // ratio r (z = ds^(1/p), see slip_exponent): eta_v (r_hat - r)/(n dt) for the exponential
  // form, (eta_v (r_hat - r)/dt)^(1/n) for the power form with n >= 1, 0 where that slope
  // vanishes (power form with n < 1) or there is no overstress. For small steps of a viscous
  // law it dwarfs the elastic response of r to slip: the scale of the flow rule in z.
  double viscous_slope_at_zero_slip(double r, double dt) const;

  // The accumulated slip needed to bring r_s from 0 to r_s (the integral of 1/U): the inverse
  // of subloading_ratio_after. Monotone increasing, infinite at r_s = 1.
  double subloading_slip_integral(double r_s) const;

  // The steady state at a constant viscoplastic slip rate v (analytical, paper section 3b):
  // r_s -> 1, mu from kappa (1 - mu/mu_k) v + xi (1 - mu/mu_s) = 0, r from phi(r, 1) = v.
  struct SteadyState {
    double mu;
    double r;
    double ratio;  // r * mu = f_t / f_n
  };
  SteadyState steady_state(double slip_rate) const;

  // The plastic moduli of the rate-independent model (2.41).
  double plastic_modulus(double r, double mu) const;  // m^p
  double creep_modulus(double r, double mu) const;    // m^c

 private:
  double subloading_inverse_integral(double h) const;

  LawParameters p_;
};

}  // namespace subslip::law
