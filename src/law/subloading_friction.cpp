#include "subslip/law/subloading_friction.hpp"

#include <algorithm>
#include <array>
#include <numbers>
#include <stdexcept>

#include "subslip/integrators/scalar_root.hpp"

namespace subslip::law {

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kInf = std::numeric_limits<double>::infinity();

// (1 - e^{-b}) / b and its derivative, regular at b = 0.
struct Phi1 {
  double value;
  double slope;
};
Phi1 phi1(double b) {
  // The series sum_k (-b)^k / (k+1)! to k = 9 has a truncation error below b^10/11! < 3e-20 for
  // |b| < 1/16 (its slope: below 4e-18): below the rounding of the closed form, which also
  // pays an expm1. Implicit steps evaluate mu here for every system and trial slip, with b the
  // slip of one small step times kappa/mu_k.
  if (std::abs(b) < 0.0625) {
    double value = 0.0, slope = 0.0;
    // Horner from the highest term: c_k = (-1)^k/(k+1)!, slope = sum k c_k b^(k-1).
    constexpr std::array<double, 10> c = {1.0,          -1.0 / 2,      1.0 / 6,    -1.0 / 24,
                                          1.0 / 120,    -1.0 / 720,    1.0 / 5040, -1.0 / 40320,
                                          1.0 / 362880, -1.0 / 3628800};
    for (int k = 9; k >= 0; --k) value = value * b + c[static_cast<size_t>(k)];
    for (int k = 9; k >= 1; --k) slope = slope * b + k * c[static_cast<size_t>(k)];
    return {value, slope};
  }
  const double one_minus_exp = -std::expm1(-b);
  return {one_minus_exp / b, ((1.0 - one_minus_exp) * b - one_minus_exp) / (b * b)};
}

}  // namespace

std::string_view to_string(SubloadingFunction f) {
  switch (f) {
    case SubloadingFunction::cot:
      return "cot";
    case SubloadingFunction::neg_log:
      return "neg_log";
    case SubloadingFunction::reciprocal:
      return "reciprocal";
  }
  return "?";
}

std::string_view to_string(OverstressForm f) {
  switch (f) {
    case OverstressForm::exponential:
      return "exponential";
    case OverstressForm::power:
      return "power";
    case OverstressForm::rate_independent:
      return "rate_independent";
  }
  return "?";
}

SubloadingFrictionLaw::SubloadingFrictionLaw(const LawParameters& p) : p_(p) {
  // Range checks with the parameter's name: scene validation reports file and line before
  // this, so these only guard programmatic use.
  auto require = [](bool ok, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("law parameter out of range: ") + what);
  };
  require(p.friction.mu_s > 0.0, "mu_s > 0");
  require(p.friction.mu_k > 0.0, "mu_k > 0");
  require(p.friction.kappa >= 0.0, "kappa >= 0");
  require(p.friction.xi >= 0.0, "xi >= 0");
  require(p.subloading.u_tilde > 0.0, "u_tilde > 0");
  if (!is_rate_independent()) {
    require(p.overstress.eta_v > 0.0, "eta_v > 0");
    require(p.overstress.n > 0.0, "n > 0");
    require(p.overstress.r_hat > 1.0, "r_hat > 1");
  }
}

double SubloadingFrictionLaw::subloading_rate(double r) const {
  const double u = p_.subloading.u_tilde;
  if (r <= 0.0) return kInf;
  switch (p_.subloading.function) {
    case SubloadingFunction::cot:
      return u / std::tan(0.5 * kPi * r);
    case SubloadingFunction::neg_log:
      return -u * std::log(r);
    case SubloadingFunction::reciprocal:
      return u * (1.0 / r - 1.0);
  }
  return 0.0;
}

double SubloadingFrictionLaw::slip_rate(double r, double r_s) const {
  const auto& o = p_.overstress;
  if (is_rate_independent() || r <= r_s) return 0.0;
  if (r >= o.r_hat) return kInf;
  const double x = r - r_s;
  const double g = (o.form == OverstressForm::exponential) ? std::expm1(o.n * x) : std::pow(x, o.n);
  return g / (o.eta_v * (o.r_hat - r));
}

double SubloadingFrictionLaw::slip_rate_slope(double r, double r_s) const {
  const auto& o = p_.overstress;
  if (is_rate_independent() || r <= r_s) return 0.0;
  if (r >= o.r_hat) return kInf;
  const double x = r - r_s;
  const double gap = o.r_hat - r;
  double g, dg;
  if (o.form == OverstressForm::exponential) {
    g = std::expm1(o.n * x);
    dg = o.n * (g + 1.0);
  } else {
    g = std::pow(x, o.n);
    dg = o.n * std::pow(x, o.n - 1.0);
  }
  return (dg * gap + g) / (o.eta_v * gap * gap);
}

double SubloadingFrictionLaw::subloading_slip_integral(double r) const {
  const double u = p_.subloading.u_tilde;
  if (r <= 0.0) return 0.0;
  if (r >= 1.0) return kInf;
  switch (p_.subloading.function) {
    case SubloadingFunction::cot:
      // ds = tan(pi r/2) dr / u  =>  s = -(2/(pi u)) ln cos(pi r/2). The cosine keeps its
      // digits as 1 - 2 sin^2(pi r/4) (through log1p) for small r, and as a sine of the
      // distance to 1 for r -> 1.
      if (r < 0.5) {
        const double h = std::sin(0.25 * kPi * r);
        return -2.0 / (kPi * u) * std::log1p(-2.0 * h * h);
      }
      return -2.0 / (kPi * u) * std::log(std::sin(0.5 * kPi * (1.0 - r)));
    case SubloadingFunction::neg_log:
      // ds = dr / (-u ln r)  =>  s = -li(r) / u = -Ei(ln r) / u.
      return -std::expint(std::log(r)) / u;
    case SubloadingFunction::reciprocal:
      // ds = r dr / (u (1 - r))  =>  s = (-ln(1 - r) - r) / u.
      return (-std::log1p(-r) - r) / u;
  }
  return 0.0;
}

double SubloadingFrictionLaw::subloading_inverse_integral(double h) const {
  if (h <= 0.0) return 0.0;
  // H(r) is increasing and convex on [0, 1) with H(1) = infinity: Newton from a bracket.
  auto eval = [&](double r) {
    const double value = subloading_slip_integral(r) - h;
    const double slope = 1.0 / subloading_rate(r);
    return std::pair{value, slope};
  };
  const auto root =
      safeguarded_newton(eval, 0.0, 1.0, 0.5, 1e-15 * std::max(h, 1e-300), 1e-15, 1e-300, 400);
  return root.x;
}

ValueAndSlope SubloadingFrictionLaw::subloading_ratio_after(double r_s0, double slip) const {
  return subloading_ratio_after(subloading_start(r_s0), slip);
}

SubloadingFrictionLaw::SubloadingStart SubloadingFrictionLaw::subloading_start(double r_s0) const {
  const double r0 = std::clamp(r_s0, 0.0, 1.0);
  if (p_.subloading.function == SubloadingFunction::cot) {
    if (r0 == 0.0) return {0.0, 1.0, 0.0, 0.0, kInf};  // a virgin (or restarted) system
    // One sine, taken where it keeps the digits: 1 - cos through sin(pi r/4) for small r,
    // cos through the sine of the distance to 1 otherwise. U(r0) = u cos/sin needs no tangent.
    double cos0, one_minus_cos0;
    if (r0 < 0.5) {
      const double h = std::sin(0.25 * kPi * r0);
      one_minus_cos0 = 2.0 * h * h;
      cos0 = 1.0 - one_minus_cos0;
    } else {
      cos0 = std::sin(0.5 * kPi * (1.0 - r0));
      one_minus_cos0 = 1.0 - cos0;
    }
    const double sin0 = std::sqrt(one_minus_cos0 * (1.0 + cos0));
    const double rate0 = p_.subloading.u_tilde * cos0 / sin0;  // +inf at r0 = 0, as U(0)
    return {r0, cos0, one_minus_cos0, 0.0, rate0};
  }
  return {r0, 0.0, 0.0, subloading_slip_integral(r0), subloading_rate(r0)};
}

ValueAndSlope SubloadingFrictionLaw::subloading_ratio_after(const SubloadingStart& st,
                                                            double slip) const {
  if (slip <= 0.0 || st.r0 >= 1.0) return {st.r0, st.rate0};
  if (p_.subloading.function != SubloadingFunction::cot) {
    const double r1 = std::clamp(subloading_inverse_integral(st.integral0 + slip), st.r0, 1.0);
    return {r1, subloading_rate(r1)};
  }
  // (2.28): x = cos(pi r1/2) = cos(pi r0/2) exp(-pi u s/2), carried with 1 - x so that small r0
  // and small s keep their digits (acos is ill-conditioned next to 1). The slope
  // U(r1) = u cot(pi r1/2) = u x / sqrt((1 - x)(1 + x)) needs no further trigonometry.
  const double u = p_.subloading.u_tilde;
  const double a = 0.5 * kPi * u * slip;
  const double decay = std::expm1(-a);
  const double x = st.cos0 * (1.0 + decay);
  const double one_minus_x = st.one_minus_cos0 - st.cos0 * decay;
  const double r1 = (x > 0.5) ? (4.0 / kPi) * std::asin(std::sqrt(0.5 * one_minus_x))
                              : (2.0 / kPi) * std::acos(x);
  if (r1 <= st.r0) return {st.r0, st.rate0};
  if (r1 >= 1.0) return {1.0, 0.0};
  return {r1, u * x / std::sqrt(one_minus_x * (1.0 + x))};
}

ValueAndSlope SubloadingFrictionLaw::friction_coefficient_after(double mu0, double slip,
                                                                double dt) const {
  // dmu/dt = a - b mu with a = kappa sdot + xi, b = kappa sdot/mu_k + xi/mu_s is linear in mu
  // for a constant slip rate sdot = slip/dt, so the step has the exact solution
  //   mu1 = mu0 + (A - B mu0) (1 - e^{-B}) / B,  A = a dt, B = b dt,
  // which is unconditionally stable and never crosses mu_s or mu_k.
  const auto& f = p_.friction;
  if (f.kappa == 0.0 && f.xi == 0.0) return {mu0, 0.0};
  const double A = f.kappa * slip + f.xi * dt;
  const double B = f.kappa * slip / f.mu_k + f.xi * dt / f.mu_s;
  const double d_drive = f.kappa - f.kappa / f.mu_k * mu0;
  // No slip and no recovery time (an idle system in an implicit step's evaluation, the common
  // case): mu stays, and the series below would give exactly that (phi1(0) = 1, drive = 0).
  if (B == 0.0) return {mu0, d_drive};
  const Phi1 ph = phi1(B);
  const double drive = A - B * mu0;
  const double mu1 = mu0 + drive * ph.value;
  const double d_mu1 = d_drive * ph.value + drive * ph.slope * (f.kappa / f.mu_k);
  return {mu1, d_mu1};
}

FlowResidual SubloadingFrictionLaw::flow_residual(double r, double r_s, double slip,
                                                  double dt) const {
  const auto& o = p_.overstress;
  if (is_rate_independent()) return {r - r_s, 1.0, -1.0, 0.0, true};
  if (r >= o.r_hat) return {kInf, 0.0, 0.0, 0.0, false};
  const double gap = o.r_hat - r;
  const double rate = slip / dt;
  const double y = o.eta_v * gap * rate;  // = g(r - r_s) on the solution
  double inv, d_inv_dy;
  if (o.form == OverstressForm::exponential) {
    inv = std::log1p(y) / o.n;
    d_inv_dy = 1.0 / (o.n * (1.0 + y));
  } else {
    if (y > 0.0) {
      inv = std::pow(y, 1.0 / o.n);
      d_inv_dy = inv / (o.n * y);
    } else {
      inv = 0.0;
      d_inv_dy = kInf;
    }
  }
  const double dy_dr = -o.eta_v * rate;
  const double dy_dslip = o.eta_v * gap / dt;
  const double d_slip =
      (y > 0.0 || o.form == OverstressForm::exponential) ? -d_inv_dy * dy_dslip : -kInf;
  const double d_r = 1.0 - (y > 0.0 ? d_inv_dy * dy_dr : 0.0);
  return {(r - r_s) - inv, d_r, -1.0, d_slip, true};
}

double SubloadingFrictionLaw::viscous_slope_at_zero_slip(double r, double dt) const {
  const auto& o = p_.overstress;
  if (is_rate_independent()) return 0.0;
  const double rate_scale = o.eta_v * std::max(o.r_hat - r, 0.0) / dt;
  if (o.form == OverstressForm::exponential) return rate_scale / o.n;
  return o.n >= 1.0 ? std::pow(rate_scale, 1.0 / o.n) : 0.0;
}

SubloadingFrictionLaw::SteadyState SubloadingFrictionLaw::steady_state(double v) const {
  const auto& f = p_.friction;
  const double mu = (f.kappa * v + f.xi) / (f.kappa * v / f.mu_k + f.xi / f.mu_s);
  if (is_rate_independent() || v <= 0.0) return {mu, 1.0, mu};
  // phi(r, 1) = v, increasing in r on [1, r_hat).
  auto eval = [&](double r) {
    const double phi = slip_rate(r, 1.0);
    return std::pair{phi - v, slip_rate_slope(r, 1.0)};
  };
  const double r_hat = p_.overstress.r_hat;
  const auto root =
      safeguarded_newton(eval, 1.0, r_hat, 1.0 + 1e-3 * (r_hat - 1.0), 1e-14 * v, 1e-16, 1.0, 1000);
  return {mu, root.x, root.x * mu};
}

double SubloadingFrictionLaw::plastic_modulus(double r, double mu) const {
  const auto& f = p_.friction;
  return f.kappa * (1.0 - mu / f.mu_k) * r + subloading_rate(r) * mu;
}

double SubloadingFrictionLaw::creep_modulus(double r, double mu) const {
  const auto& f = p_.friction;
  return f.xi * (1.0 - mu / f.mu_s) * r;
}

}  // namespace subslip::law
