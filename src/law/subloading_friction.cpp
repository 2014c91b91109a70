#include "subslip/law/subloading_friction.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

#include "subslip/integrators/scalar_root.hpp"
#include "subslip/law/closed_form.hpp"

namespace subslip::law {

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kInf = std::numeric_limits<double>::infinity();

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
    case SubloadingFunction::neg_log: {
      // ds = dr / (-u ln r)  =>  s = -li(r) / u = -Ei(ln r) / u = E1(L) / u, L = ln(1/r).
      const double L = -std::log(r);
      if (L < 40.0) return -std::expint(-L) / u;
      // libstdc++'s Ei keeps only the first term of its asymptotic series beyond |x| = 50
      // (relative error 1/L: 1 % at r = 1e-44, 0.4 % at 1e-100, measured), which also makes H
      // jump down by 2 % as r falls through e^-50. The series itself, summed to its smallest
      // term: E1(L) = (e^-L / L) sum_k (-1)^k k! / L^k, whose smallest term from L = 40 on is
      // below 1e-16 relative.
      double term = 1.0, sum = 0.0;
      for (int k = 1; std::abs(term) > 1e-17; ++k) {
        sum += term;
        const double next = -term * k / L;
        if (std::abs(next) >= std::abs(term)) break;
        term = next;
      }
      return r / (u * L) * sum;
    }
    case SubloadingFunction::reciprocal:
      // ds = r dr / (u (1 - r))  =>  s = (-ln(1 - r) - r) / u. The two terms cancel for small r
      // (relative error 2 eps / r: no digit left below r = 1e-16), so there the series
      // -ln(1 - r) - r = sum_{k >= 2} r^k / k, whose terms all add.
      if (r < 0.25) {
        double sum = 0.0, power = r * r;
        for (int k = 2; power > 1e-17 * sum; ++k, power *= r) sum += power / k;
        return sum / u;
      }
      return (-std::log1p(-r) - r) / u;
  }
  return 0.0;
}

namespace {

// u H(1/2), the slip integral to the middle ratio times u: the same for every law of one U, so
// computed once (the inverse below asks for it at every call).
double middle_slip_integral(SubloadingFunction f) {
  static const double neg_log = -std::expint(-std::log(2.0));  // E1(ln 2) = -Ei(-ln 2)
  switch (f) {
    case SubloadingFunction::cot:
      return std::log(2.0) / kPi;  // -(2/pi) ln cos(pi/4)
    case SubloadingFunction::neg_log:
      return neg_log;
    case SubloadingFunction::reciprocal:
      return std::log(2.0) - 0.5;  // -ln(1 - 1/2) - 1/2
  }
  return 0.0;
}

}  // namespace

double SubloadingFrictionLaw::subloading_inverse_integral(double h) const {
  if (h <= 0.0) return 0.0;
  // H(r) is increasing and convex on [0, 1); it rises from zero like a power of r (r^2 / (2u)
  // for the reciprocal U, about r / (u ln(1/r)) for neg_log) and to infinity at r = 1 like
  // ln(1 / (1 - r)) / u. Newton in r bisects towards either end (about log2 of the distance:
  // hundreds of evaluations of Ei for the slips of 1e-100 and below that an implicit step's
  // iterates pass through on their way to zero). In the variable that straightens each end,
  // Newton takes a few steps: t = ln r with ln H below the middle ratio, w = ln(1 / (1 - r))
  // above it.
  constexpr double kMiddle = 0.5;
  const double h_middle = middle_slip_integral(p_.subloading.function) / p_.subloading.u_tilde;
  if (h >= h_middle) {
    auto eval = [&](double w) {
      const double one_minus_r = std::exp(-w);
      const double r = 1.0 - one_minus_r;  // 1 beyond w = 37: H = infinity there
      return std::pair{subloading_slip_integral(r) - h, one_minus_r / subloading_rate(r)};
    };
    const double w_middle = -std::log(kMiddle);
    const double guess = std::min(w_middle + p_.subloading.u_tilde * (h - h_middle), 37.0);
    const auto root = safeguarded_newton(eval, w_middle, 40.0, guess, 1e-15 * h, 1e-15, 1.0, 400);
    return 1.0 - std::exp(-root.x);
  }
  const double log_h = std::log(h);
  auto eval = [&](double t) {
    const double r = std::exp(t);
    const double integral = subloading_slip_integral(r);  // 0 where r underflows: ln = -inf
    return std::pair{std::log(integral) - log_h, r / (subloading_rate(r) * integral)};
  };
  const double t_min = std::log(std::numeric_limits<double>::denorm_min());
  const double t_middle = std::log(kMiddle);
  // To 1e-10 in ln H; one Newton step in r then takes r to full precision (t resolves r only to
  // |t| eps relative).
  const double r =
      std::exp(safeguarded_newton(eval, t_min, t_middle, t_middle, 1e-10, 1e-16, 1.0, 400).x);
  const double polished = r - (subloading_slip_integral(r) - h) * subloading_rate(r);
  return polished > 0.0 && polished < kMiddle ? polished : r;
}

ValueAndSlope SubloadingFrictionLaw::subloading_ratio_after(double r_s0, double slip) const {
  return subloading_ratio_after(subloading_start(r_s0), slip);
}

SubloadingFrictionLaw::SubloadingStart SubloadingFrictionLaw::subloading_start(double r_s0) const {
  const double r0 = std::clamp(r_s0, 0.0, 1.0);
  if (p_.subloading.function == SubloadingFunction::cot) {
    if (r0 == 0.0) return {0.0, 1.0, 0.0, 0.0, kInf};  // a virgin (or restarted) system
    const auto start = closed_form::cot_subloading_start(p_.subloading.u_tilde, r0);
    return {r0, start.cos0, start.one_minus_cos0, 0.0, start.rate0};
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
  const auto r1 = closed_form::cot_subloading_ratio_after(p_.subloading.u_tilde, st.r0, st.cos0,
                                                          st.one_minus_cos0, st.rate0, slip);
  return {r1.value, r1.slope};
}

ValueAndSlope SubloadingFrictionLaw::friction_coefficient_after(double mu0, double slip,
                                                                double dt) const {
  const auto& f = p_.friction;
  if (f.kappa == 0.0 && f.xi == 0.0) return {mu0, 0.0};
  // No slip and no recovery time (an idle system in an implicit step's evaluation, the common
  // case): mu stays, which the closed form gives exactly (phi1(0) = 1, drive = 0).
  if (f.kappa * slip / f.mu_k + f.xi * dt / f.mu_s == 0.0)
    return {mu0, f.kappa - f.kappa / f.mu_k * mu0};
  const auto mu1 = closed_form::friction_coefficient_after(f, mu0, slip, dt);
  return {mu1.value, mu1.slope};
}

FlowResidual SubloadingFrictionLaw::flow_residual(double r, double r_s, double slip,
                                                  double dt) const {
  const auto& o = p_.overstress;
  if (is_rate_independent()) return {r - r_s, 1.0, -1.0, 0.0, true};
  if (r >= o.r_hat) return {kInf, 0.0, 0.0, 0.0, false};
  if (o.form == OverstressForm::exponential) {
    const auto g = closed_form::exponential_flow_residual(o, r, r_s, slip, dt);
    return {g.value, g.d_r, -1.0, g.d_slip, true};
  }
  const double gap = o.r_hat - r;
  const double rate = slip / dt;
  const double y = o.eta_v * gap * rate;  // = g(r - r_s) on the solution
  double inv = 0.0, d_inv_dy = kInf;
  if (y > 0.0) {
    inv = std::pow(y, 1.0 / o.n);
    d_inv_dy = inv / (o.n * y);
  }
  const double dy_dr = -o.eta_v * rate;
  const double dy_dslip = o.eta_v * gap / dt;
  const double d_slip = y > 0.0 ? -d_inv_dy * dy_dslip : -kInf;
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
