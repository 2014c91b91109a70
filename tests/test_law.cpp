// Tests that pin down the physics of the subloading-overstress friction law (Hashiguchi et al.
// 2016, Proc. R. Soc. A 472:20160212; equation numbers refer to the paper).
//
// Every expected value here is computed inside the test, independently of the code under test:
// finite differences, a small RK4 integrator, closed forms derived in the comments, or a
// bisection. No number is copied from a run of the code.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "paper_law.hpp"
#include "subslip/law/subloading_friction.hpp"

using namespace subslip::law;

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kEps = std::numeric_limits<double>::epsilon();

const SubloadingFunction kAllFunctions[] = {SubloadingFunction::cot, SubloadingFunction::neg_log,
                                            SubloadingFunction::reciprocal};

// The material constants of the paper's section 5 (figure 11a).
using subslip::testing::paper_law;

// The paper's law with another overstress form and exponent n.
SubloadingFrictionLaw paper_law_with_exponent(OverstressForm form, double n) {
  LawParameters p = paper_law(form);
  p.overstress.n = n;
  return SubloadingFrictionLaw(p);
}

// U(r) written out again here, from (2.27) and (2.29), so that the reference integrations do not
// call the code under test.
double U_ref(SubloadingFunction f, double u, double r) {
  switch (f) {
    case SubloadingFunction::cot:
      return u / std::tan(0.5 * kPi * r);
    case SubloadingFunction::neg_log:
      return -u * std::log(r);
    case SubloadingFunction::reciprocal:
      return u * (1.0 / r - 1.0);
  }
  return 0.0;
}

// The overstress function g(x) of (3.10)/(3.15) and the forward slip rate phi(r, r_s), again
// written independently of the code under test.
double phi_ref(const Overstress& o, double r, double r_s) {
  if (r <= r_s) return 0.0;
  const double x = r - r_s;
  const double g = o.form == OverstressForm::exponential ? std::expm1(o.n * x) : std::pow(x, o.n);
  return g / (o.eta_v * (o.r_hat - r));
}

// d phi/d r, analytical, for tolerances only.
double phi_r_ref(const Overstress& o, double r, double r_s) {
  const double x = r - r_s, gap = o.r_hat - r;
  const bool e = o.form == OverstressForm::exponential;
  const double g = e ? std::expm1(o.n * x) : std::pow(x, o.n);
  const double dg = e ? o.n * std::exp(o.n * x) : o.n * std::pow(x, o.n - 1.0);
  return (dg * gap + g) / (o.eta_v * gap * gap);
}

// Richardson-extrapolated central difference: (4 D(h/2) - D(h)) / 3 with D(h) the central
// difference. Truncation error O(h^4 f^(5)); rounding error about 2 eps |f| / h.
double derivative(const std::function<double(double)>& f, double x, double h) {
  auto d = [&](double hh) { return (f(x + hh) - f(x - hh)) / (2.0 * hh); };
  return (4.0 * d(0.5 * h) - d(h)) / 3.0;
}

// Allowance for the rounding part of `derivative` when the function values are of magnitude
// `scale` and carry a relative error `rel` (eps for closed forms, more for iterative solves):
// the two central differences have errors rel*scale/h and 2 rel*scale/h, combined with weights
// 4/3 and 1/3 -> about 3 rel*scale/h. Doubled for safety.
double rounding_allowance(double scale, double rel, double h) {
  return 6.0 * rel * scale / h;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// 1. Derivatives (NEML2-style: every analytical partial against finite differences).
// ---------------------------------------------------------------------------------------------

TEST(LawDerivatives, FrictionCoefficientSlopeMatchesFiniteDifferences) {
  struct Case {
    double mu_s, mu_k, kappa, xi;
  };
  // Softening (mu_k < mu_s: friction) and hardening (mu_k > mu_s: crystal slip), with and
  // without recovery, and a stiff kappa.
  const Case cases[] = {{0.097, 0.085, 0.2, 0.009}, {0.097, 0.085, 5.0, 0.009},
                        {0.085, 0.097, 0.2, 0.009}, {0.085, 0.097, 1.0, 0.0},
                        {0.097, 0.085, 1.0, 0.0},   {0.5, 1.5, 20.0, 3.0}};
  int checked = 0;
  for (const auto& c : cases) {
    LawParameters p = paper_law();
    p.friction = {c.mu_s, c.mu_k, c.kappa, c.xi};
    const SubloadingFrictionLaw law(p);
    for (double mu0 : {c.mu_s, c.mu_k, 0.5 * (c.mu_s + c.mu_k), 1.3 * std::max(c.mu_s, c.mu_k)}) {
      for (double dt : {1e-6, 1e-2, 1.0, 100.0}) {
        for (double slip : {1e-8, 1e-4, 1e-2, 0.3, 3.0, 30.0}) {
          auto value = [&](double s) { return law.friction_coefficient_after(mu0, s, dt).value; };
          // h well inside (0, slip) and small against the slip scale mu_k/kappa of the update.
          const double h = 1e-2 * std::min(slip, c.mu_k / std::max(c.kappa, 1e-300));
          const double fd = derivative(value, slip, h);
          const double analytical = law.friction_coefficient_after(mu0, slip, dt).d_slip;
          // Truncation: (h kappa/mu_k)^4 <= 1e-8 relative to the slope scale kappa; rounding: the
          // closed form is good to a few eps of mu.
          const double tol = 1e-8 * c.kappa * (1.0 + mu0 / c.mu_k) +
                             rounding_allowance(std::max(mu0, c.mu_s), 4 * kEps, h);
          EXPECT_NEAR(analytical, fd, tol)
              << "mu_s=" << c.mu_s << " mu_k=" << c.mu_k << " kappa=" << c.kappa << " xi=" << c.xi
              << " mu0=" << mu0 << " dt=" << dt << " slip=" << slip;
          ++checked;
        }
      }
    }
  }
  EXPECT_EQ(checked, 6 * 4 * 4 * 6);
}

// The value: along a step at constant slip rate sdot, mu1(t) = friction_coefficient_after(mu0,
// sdot t, t) must satisfy the ODE (3.4) itself, d mu1/dt = kappa (1 - mu1/mu_k) sdot
// + xi (1 - mu1/mu_s), at every t. This checks the value by differentiation, independently of
// the RK4 comparison further down; it also crosses the series branch of the code (B ~ 1e-4).
TEST(LawDerivatives, FrictionCoefficientValueSatisfiesTheOde) {
  for (const auto& fr : {FrictionCoefficientEvolution{0.097, 0.085, 0.2, 0.009},
                         FrictionCoefficientEvolution{0.085, 0.097, 1.0, 0.005}}) {
    LawParameters p = paper_law();
    p.friction = fr;
    const SubloadingFrictionLaw law(p);
    for (double sdot : {0.0, 1e-5, 1.0, 200.0}) {
      for (double mu0 : {0.06, 0.09, 0.12}) {
        // t spans B = (kappa sdot/mu_k + xi/mu_s) t from 1e-6 (series branch) to ~10.
        for (double t : {1e-4, 1e-2, 0.1, 1.0, 5.0}) {
          auto mu_of_t = [&](double tt) {
            return law.friction_coefficient_after(mu0, sdot * tt, tt).value;
          };
          const double b = fr.kappa * sdot / fr.mu_k + fr.xi / fr.mu_s;  // decay rate [1/time]
          // h resolves both t and the decay time 1/b, so the truncation (h b)^4/480 <= 1e-11
          // relative to the rate scale b |mu| (|mu| < 0.2); rounding from eps-accurate closed
          // form values.
          const double h = 1e-2 * std::min(t, 1.0 / b);
          const double mu1 = mu_of_t(t);
          const double rhs =
              fr.kappa * (1.0 - mu1 / fr.mu_k) * sdot + fr.xi * (1.0 - mu1 / fr.mu_s);
          const double tol = 1e-8 * b * 0.2 + rounding_allowance(0.2, 4 * kEps, h);
          EXPECT_NEAR(derivative(mu_of_t, t, h), rhs, tol)
              << "sdot=" << sdot << " mu0=" << mu0 << " t=" << t;
        }
      }
    }
  }
}

TEST(LawDerivatives, SubloadingRatioSlopeIsUAndMatchesFiniteDifferences) {
  for (auto f : kAllFunctions) {
    const SubloadingFrictionLaw law(paper_law(OverstressForm::exponential, f));
    for (double r0 : {0.0, 1e-6, 0.1, 0.5, 0.9, 0.999}) {
      for (double slip : {1e-9, 1e-6, 1e-4, 1e-3, 1e-2, 5e-2}) {
        const auto out = law.subloading_ratio_after(r0, slip);
        ASSERT_TRUE(std::isfinite(out.value));
        // The slope of the exact update is dr_s1/dslip = U(r_s1) (differentiate (2.25) at the
        // end point). The code may compute it from cos(pi r1/2) before r1 is rounded, so it must
        // equal U at the returned value within U's sensitivity to a few ulp of r1 (near r1 = 1,
        // cot amplifies one ulp of r1 by 1/(1 - r1)), plus a few ulp of U itself.
        const double r1 = out.value;
        const double spread =
            std::abs(U_ref(f, 80.0, std::nextafter(std::nextafter(r1, 0.0), 0.0)) -
                     U_ref(f, 80.0, std::nextafter(std::nextafter(r1, 2.0), 2.0)));
        const double u_at = U_ref(f, 80.0, r1);
        EXPECT_NEAR(out.d_slip, u_at,
                    spread + 8.0 * std::numeric_limits<double>::epsilon() * std::abs(u_at))
            << to_string(f) << " r0=" << r0 << " slip=" << slip;
        if (out.value >= 1.0) continue;  // saturated: U = 0 and the value is flat
        auto value = [&](double s) { return law.subloading_ratio_after(r0, s).value; };
        const double h = 5e-3 * slip;
        const double fd = derivative(value, slip, h);
        // Truncation: r_s(slip) varies on the scale of the slip itself (power law from r = 0)
        // or of 2/(pi u) (exponential approach to 1), so (h/scale)^4/480 <= 1e-9 relative.
        // Rounding: the cot form is closed (eps); the other two are a Newton inverse solved to
        // 1e-15 relative in slip, i.e. 1e-15 * U * slip_total in r, bounded by 1e-15 * max(r, 1)
        // for these three functions (U*H <= max(r, 1)).
        const double tol = 1e-7 * std::abs(out.d_slip) +
                           rounding_allowance(std::max(out.value, 1.0), 1e-15 + 4 * kEps, h);
        EXPECT_NEAR(fd, out.d_slip, tol) << to_string(f) << " r0=" << r0 << " slip=" << slip;
      }
    }
  }
}

TEST(LawDerivatives, FlowResidualPartialsMatchFiniteDifferences) {
  int checked = 0;
  for (auto form :
       {OverstressForm::exponential, OverstressForm::power, OverstressForm::rate_independent}) {
    const SubloadingFrictionLaw law(paper_law(form));
    const double r_hat = 1.8;
    for (double r_s : {0.0, 0.3, 0.99, 1.0}) {
      for (double over : {-0.2, 0.01, 0.3, 0.7}) {  // r - r_s
        const double r = r_s + over;
        if (r < 0.0 || r >= r_hat) continue;
        for (double slip : {1e-8, 1e-3, 1.0}) {
          for (double dt : {1e-3, 1.0, 100.0}) {
            const auto g = law.flow_residual(r, r_s, slip, dt);
            ASSERT_TRUE(g.admissible);
            ASSERT_TRUE(std::isfinite(g.value) && std::isfinite(g.d_r) && std::isfinite(g.d_rs) &&
                        std::isfinite(g.d_slip));
            auto G_r = [&](double x) { return law.flow_residual(x, r_s, slip, dt).value; };
            auto G_rs = [&](double x) { return law.flow_residual(r, x, slip, dt).value; };
            auto G_s = [&](double x) { return law.flow_residual(r, r_s, x, dt).value; };
            // Steps: a small fraction of the distance to the singular point r_hat, and 1% of the
            // slip (the residual depends on slip through y = eta (r_hat - r) slip/dt only).
            const double hr = 1e-3 * std::min(r_hat - r, 1.0);
            const double hs = 1e-2 * slip;
            // The residual is O(1) (traction-ratio units) and computed in closed form (eps);
            // truncation of the extrapolated difference is ~(h/scale)^4 <= 1e-8 relative to the
            // partial's own size.
            const double fd_r = derivative(G_r, r, hr);
            const double fd_rs = derivative(G_rs, r_s, hr);
            const double fd_s = derivative(G_s, slip, hs);
            EXPECT_NEAR(g.d_r, fd_r, 1e-7 * std::abs(g.d_r) + rounding_allowance(2.0, kEps, hr))
                << to_string(form) << " r=" << r << " r_s=" << r_s << " slip=" << slip
                << " dt=" << dt;
            EXPECT_NEAR(g.d_rs, fd_rs, 1e-7 + rounding_allowance(2.0, kEps, hr));
            EXPECT_NEAR(g.d_slip, fd_s,
                        1e-7 * std::abs(g.d_slip) + rounding_allowance(2.0, kEps, hs))
                << to_string(form) << " r=" << r << " r_s=" << r_s << " slip=" << slip
                << " dt=" << dt;
            ++checked;
          }
        }
      }
    }
  }
  EXPECT_GT(checked, 200);
}

// The row scale the crystal's Newton takes from the law: the overstress term's slope in the
// unknown z = slip^(1/p) at zero slip, checked against a one-sided difference of the flow
// residual itself (where the slope exists: exponential any n, power n >= 1; 0 for n < 1).
TEST(LawDerivatives, ViscousSlopeAtZeroSlipIsTheResidualsSlopeInZ) {
  for (auto form : {OverstressForm::exponential, OverstressForm::power}) {
    for (double n : {0.5, 1.0, 16.0}) {
      const SubloadingFrictionLaw law = paper_law_with_exponent(form, n);
      const double exponent = law.slip_exponent();
      for (double r : {0.2, 1.0, 1.5}) {
        for (double dt : {1e-5, 1.0, 1e3}) {
          const double slope = law.viscous_slope_at_zero_slip(r, dt);
          ASSERT_TRUE(std::isfinite(slope) && slope >= 0.0);
          // G(z) = (r - r_s) - overstress^-1(z): its fall over a z small enough that the
          // overstress term is still linear in z (relative curvature below 1e-6).
          const double r_s = 0.1;
          const double g0 = law.flow_residual(r, r_s, 0.0, dt).value;
          const double z = slope > 0.0 ? 1e-8 / slope : 1e-8;
          const double fall = g0 - law.flow_residual(r, r_s, std::pow(z, exponent), dt).value;
          if (form == OverstressForm::power && n < 1.0) {
            EXPECT_EQ(slope, 0.0);
          } else {
            EXPECT_NEAR(fall / z, slope, 1e-5 * slope)
                << to_string(form) << " n=" << n << " r=" << r << " dt=" << dt;
          }
        }
      }
    }
  }
  EXPECT_EQ(SubloadingFrictionLaw(paper_law(OverstressForm::rate_independent))
                .viscous_slope_at_zero_slip(1.0, 1.0),
            0.0);
}

// The implicit residual and the explicit slip rate describe the same flow rule: G vanishes at
// slip = dt * phi(r, r_s) (3.10, 3.15), and is positive (too little slip) below it.
TEST(LawDerivatives, FlowResidualVanishesOnTheForwardSlipRate) {
  for (auto form : {OverstressForm::exponential, OverstressForm::power}) {
    const SubloadingFrictionLaw law(paper_law(form));
    const auto& o = law.parameters().overstress;
    for (double r_s : {0.0, 0.5, 1.0}) {
      for (double x : {1e-3, 0.1, 0.5, 0.79}) {
        const double r = r_s + x;
        if (r >= o.r_hat) continue;
        for (double dt : {1e-4, 1.0}) {
          const double slip = dt * phi_ref(o, r, r_s);
          const auto g = law.flow_residual(r, r_s, slip, dt);
          // g^{-1}(g(x)) - x: a few eps of x for the exponential (log1p/expm1); the power form
          // goes through pow twice, which costs ~n eps relative.
          EXPECT_NEAR(g.value, 0.0, 64 * o.n * kEps * std::max(x, 1.0))
              << to_string(form) << " r=" << r << " r_s=" << r_s;
          EXPECT_GT(law.flow_residual(r, r_s, 0.5 * slip, dt).value, 0.0);
          EXPECT_LT(law.flow_residual(r, r_s, 2.0 * slip, dt).value, 0.0);
        }
      }
    }
    // r >= r_hat: no finite slip rate satisfies the flow rule.
    EXPECT_FALSE(law.flow_residual(o.r_hat, 0.5, 1.0, 1.0).admissible);
    EXPECT_FALSE(law.flow_residual(o.r_hat + 0.1, 0.5, 1.0, 1.0).admissible);
  }
}

TEST(LawDerivatives, SlipRateMatchesPaperAndSlopeMatchesFiniteDifferences) {
  for (auto form : {OverstressForm::exponential, OverstressForm::power}) {
    for (double n : {1.0, 4.0, 16.0}) {
      const SubloadingFrictionLaw law = paper_law_with_exponent(form, n);
      const auto& o = law.parameters().overstress;
      for (double r_s : {0.0, 0.4, 1.0}) {
        for (double x : {1e-3, 0.05, 0.3, 0.75}) {
          const double r = r_s + x;
          if (r >= o.r_hat) continue;
          const double phi = law.slip_rate(r, r_s);
          EXPECT_NEAR(phi, phi_ref(o, r, r_s), 4 * kEps * phi);
          auto f = [&](double rr) { return law.slip_rate(rr, r_s); };
          const double h = 1e-3 * std::min(x, o.r_hat - r);
          const double fd = derivative(f, r, h);
          const double slope = law.slip_rate_slope(r, r_s);
          // Truncation (h/scale)^4 <= 1e-12 with scale = min(x, r_hat - r) (the distances to the
          // two singular points of phi); closed-form values -> eps rounding.
          EXPECT_NEAR(slope, fd, 1e-8 * slope + rounding_allowance(phi, 4 * kEps, h))
              << to_string(form) << " n=" << n << " r=" << r << " r_s=" << r_s;
        }
      }
      // Loading criterion (Macaulay bracket): no viscoplastic slip at or below r_s; unbounded
      // slip rate at r_hat (3.9).
      EXPECT_EQ(law.slip_rate(0.5, 0.5), 0.0);
      EXPECT_EQ(law.slip_rate(0.3, 0.5), 0.0);
      EXPECT_EQ(law.slip_rate(o.r_hat, 0.5), std::numeric_limits<double>::infinity());
    }
  }
  EXPECT_EQ(SubloadingFrictionLaw(paper_law(OverstressForm::rate_independent)).slip_rate(1.5, 0.5),
            0.0);
}

// ---------------------------------------------------------------------------------------------
// 2. The exact updates equal the ODEs.
// ---------------------------------------------------------------------------------------------

namespace {

// RK4 of dr/ds = U(r) from (s0, r0) to each slip in `targets` (ascending), with a step that
// resolves the local slip scale: h = c * min(r/U(r), 1/u) (r/U is the slip over which r changes
// by its own size, which near r = 0 is ~ 2 s, so the steps are graded from the singular start;
// 1/u bounds h * |U'(1)| <= c * pi/2 near saturation).
std::vector<double> rk4_subloading(SubloadingFunction f, double u, double s0, double r0,
                                   const std::vector<double>& targets, double c) {
  std::vector<double> out;
  double s = s0, r = r0;
  for (double target : targets) {
    while (s < target) {
      const double Ur = U_ref(f, u, r);
      double h = c * std::min(Ur > 0.0 ? r / Ur : 1.0 / u, 1.0 / u);
      h = std::min(h, target - s);
      const double k1 = U_ref(f, u, r);
      const double k2 = U_ref(f, u, r + 0.5 * h * k1);
      const double k3 = U_ref(f, u, r + 0.5 * h * k2);
      const double k4 = U_ref(f, u, r + h * k3);
      r += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
      s = (target - s <= h) ? target : s + h;
    }
    out.push_back(r);
  }
  return out;
}

// The small-r asymptote of the exact integral s(r) = int_0^r dr'/U(r') (U singular at r = 0),
// used to start RK4 at a tiny r0 instead of at the singular point r = 0:
//   cot:        s = -(2/(pi u)) ln cos(pi r/2) = (pi r^2/(4u)) (1 + (pi r/2)^2/6 + ...)
//   reciprocal: s = (-ln(1-r) - r)/u             = (r^2/(2u)) (1 + 2r/3 + ...)
//   neg_log:    s = E1(L)/u with L = -ln r        = (r/(u L)) (1 - 1/L + 2/L^2 - ...)
// (the last from the substitution r = e^{-t} and the asymptotic series of E1).
// The truncation error of these series at r0 is ~1e-13 relative (cot, reciprocal at r0=1e-8 ...)
// or 6/L^3 ~ 3e-4 relative (neg_log at r0 = 1e-12). Its effect on r downstream is tiny: an error
// delta_s0 in the start slip shifts the whole solution by delta_s0 in slip, i.e. changes r(s) by
// U(r(s)) * delta_s0 <= 1e3 * 3e-4 * 5e-16 ~ 1e-16.
double small_r_start_slip(SubloadingFunction f, double u, double r0) {
  switch (f) {
    case SubloadingFunction::cot: {
      const double z = 0.5 * kPi * r0;
      return kPi * r0 * r0 / (4.0 * u) * (1.0 + z * z / 6.0);
    }
    case SubloadingFunction::reciprocal:
      return r0 * r0 / (2.0 * u) * (1.0 + 2.0 * r0 / 3.0);
    case SubloadingFunction::neg_log: {
      const double L = -std::log(r0);
      return r0 / (u * L) * (1.0 - 1.0 / L + 2.0 / (L * L));
    }
  }
  return 0.0;
}

double small_r_start_ratio(SubloadingFunction f) {
  return f == SubloadingFunction::neg_log ? 1e-12 : 1e-8;
}

}  // namespace

TEST(LawExactUpdates, SubloadingRatioEqualsRk4FromZero) {
  const double u = 80.0;
  const std::vector<double> targets = {1e-9, 1e-6, 1e-4, 1e-3, 1e-2, 3e-2, 0.1};
  for (auto f : kAllFunctions) {
    const SubloadingFrictionLaw law(paper_law(OverstressForm::exponential, f));
    const double r0 = small_r_start_ratio(f);
    const double s0 = small_r_start_slip(f, u, r0);
    ASSERT_LT(s0, targets.front());
    const auto coarse = rk4_subloading(f, u, s0, r0, targets, 2e-3);
    const auto fine = rk4_subloading(f, u, s0, r0, targets, 1e-3);
    for (size_t i = 0; i < targets.size(); ++i) {
      // The reference's own error: RK4 is 4th order, so halving c reduces it 16x and the
      // difference coarse-fine is ~15/16 of the coarse error; requiring it below 1e-12 bounds
      // the fine reference error by ~7e-14.
      ASSERT_NEAR(coarse[i], fine[i], 1e-12) << to_string(f) << " s=" << targets[i];
      // 1e-12: the reference's bounded error plus the update's own (~1e-15), with margin.
      EXPECT_NEAR(law.subloading_ratio_after(0.0, targets[i]).value, fine[i], 1e-12)
          << to_string(f) << " s=" << targets[i];
    }
  }
}

TEST(LawExactUpdates, SubloadingRatioEqualsRk4FromInteriorStart) {
  const double u = 80.0;
  const std::vector<double> targets = {1e-6, 1e-4, 1e-3, 1e-2, 3e-2, 0.1};
  for (auto f : kAllFunctions) {
    const SubloadingFrictionLaw law(paper_law(OverstressForm::exponential, f));
    for (double r0 : {0.05, 0.3, 0.7, 0.95}) {
      const auto coarse = rk4_subloading(f, u, 0.0, r0, targets, 2e-3);
      const auto fine = rk4_subloading(f, u, 0.0, r0, targets, 1e-3);
      for (size_t i = 0; i < targets.size(); ++i) {
        // Same reasoning as the start from zero: the reference is bounded to ~7e-14.
        ASSERT_NEAR(coarse[i], fine[i], 1e-12) << to_string(f) << " r0=" << r0;
        EXPECT_NEAR(law.subloading_ratio_after(r0, targets[i]).value, fine[i], 1e-12)
            << to_string(f) << " r0=" << r0 << " s=" << targets[i];
      }
    }
  }
}

// R(R(r0, a), b) = R(r0, a + b): the update is the flow of an autonomous ODE.
TEST(LawExactUpdates, SubloadingRatioComposes) {
  for (auto f : kAllFunctions) {
    const SubloadingFrictionLaw law(paper_law(OverstressForm::exponential, f));
    for (double r0 : {0.0, 1e-4, 0.2, 0.6, 0.97}) {
      for (double a : {1e-7, 1e-4, 3e-3, 2e-2}) {
        for (double b : {1e-7, 1e-4, 3e-3, 2e-2}) {
          const double two_steps =
              law.subloading_ratio_after(law.subloading_ratio_after(r0, a).value, b).value;
          const double one_step = law.subloading_ratio_after(r0, a + b).value;
          // Each evaluation is good to ~1e-15 relative in the slip integral (closed form for
          // cot; a Newton inverse to 1e-15 for the others), i.e. to ~1e-15 * max(r, U H) in r;
          // three evaluations plus the rounding of a + b: 1e-14 leaves a factor ~3.
          EXPECT_NEAR(two_steps, one_step, 1e-14)
              << to_string(f) << " r0=" << r0 << " a=" << a << " b=" << b;
        }
      }
    }
  }
}

// (2.28): r = (2/pi) acos{cos(pi r0/2) exp[-(pi/2) u (s - s0)]} and its inverse
// s - s0 = (2/(pi u)) ln[cos(pi r0/2)/cos(pi r/2)], evaluated directly as printed.
TEST(LawExactUpdates, CotFormMatchesPaperClosedForm) {
  const double u = 80.0;
  const SubloadingFrictionLaw law(paper_law());
  for (double r0 : {0.0, 0.01, 0.2, 0.5, 0.8, 0.99}) {
    for (double s : {1e-6, 1e-4, 1e-3, 1e-2, 0.05}) {
      const double paper =
          2.0 / kPi * std::acos(std::cos(0.5 * kPi * r0) * std::exp(-0.5 * kPi * u * s));
      const double code = law.subloading_ratio_after(r0, s).value;
      // acos is ill-conditioned next to 1: the paper's formula itself carries an error of about
      // (2/pi) * 2 eps / sin(pi r/2) in r (the code uses a better-conditioned form). The
      // tolerance is that conditioning bound, times 4.
      const double tol = 4.0 * (2.0 / kPi) * 2.0 * kEps / std::sin(0.5 * kPi * paper) + 4 * kEps;
      EXPECT_NEAR(code, paper, tol) << "r0=" << r0 << " s=" << s;
      if (code < 0.999) {
        const double s_back =
            2.0 / (kPi * u) * std::log(std::cos(0.5 * kPi * r0) / std::cos(0.5 * kPi * code));
        // ds/dr = tan(pi r/2)/u: an eps-level error in r maps to eps * tan/u in s.
        EXPECT_NEAR(s_back, s, 1e-9 * s + 16 * kEps * std::tan(0.5 * kPi * code) / u)
            << "r0=" << r0 << " s=" << s;
      }
    }
  }
}

// The cot start (cos(pi r0/2), 1 - cos(pi r0/2), U(r0)), taken from one sine of a quarter or
// half angle, against libm's cosine and tangent of the ratio itself, to a few ulps of each
// (1 - cos relative: it keeps its digits at small r0 through sin^2(pi r0/4)).
TEST(LawExactUpdates, CotStartIsTheCosineOfItsRatio) {
  const double u = 80.0;
  const SubloadingFrictionLaw law(paper_law());
  for (double r0 = 1e-9; r0 <= 1.0; r0 = r0 < 0.01 ? 3.0 * r0 : r0 + 0.0137) {
    const auto start = law.subloading_start(r0);
    const double half = std::sin(0.25 * kPi * r0);
    const double cos0 = std::cos(0.5 * kPi * r0);
    EXPECT_NEAR(start.cos0, cos0, 4 * kEps) << r0;
    EXPECT_NEAR(start.one_minus_cos0, 2.0 * half * half, 4 * kEps * 2.0 * half * half) << r0;
    const double rate = u / std::tan(0.5 * kPi * r0);
    EXPECT_NEAR(start.rate0, rate, 8 * kEps * rate + 4 * kEps * u / std::sin(0.5 * kPi * r0)) << r0;
  }
}

// The slip integral s(r) = int_0^r dr/U (the inverse of the update from 0) is consistent with
// the update, and equals an independent quadrature.
TEST(LawExactUpdates, SlipIntegralInvertsTheUpdate) {
  const double u = 80.0;
  for (auto f : kAllFunctions) {
    const SubloadingFrictionLaw law(paper_law(OverstressForm::exponential, f));
    EXPECT_EQ(law.subloading_slip_integral(0.0), 0.0);
    EXPECT_EQ(law.subloading_slip_integral(1.0), std::numeric_limits<double>::infinity());
    double previous = 0.0;
    for (double r : {1e-3, 0.1, 0.5, 0.9, 0.999}) {
      const double H = law.subloading_slip_integral(r);
      EXPECT_GT(H, previous) << to_string(f);  // monotone increasing
      previous = H;
      // Round trip through the update from 0: if H is good to ~1e-15 relative, r comes back to
      // U H 1e-15 <= max(r, u H) 1e-15; 1e-14 * max(1, u H) allows ten times that.
      EXPECT_NEAR(law.subloading_ratio_after(0.0, H).value, r, 1e-14 * std::max(1.0, u * H))
          << to_string(f) << " r=" << r;
    }
  }
  // Independent quadrature of s(r) = int_0^r dr/U: composite 5-point Gauss-Legendre on panels
  // no wider than 0.005 (1/U has a pole at r = 1, 0.2 away from r = 0.8: (0.0025/0.2)^10 is
  // negligible) and geometrically graded toward r = 0 (where 1/U ~ r or 1/ln r).
  const double xg[5] = {-0.9061798459386640, -0.5384693101056831, 0.0, 0.5384693101056831,
                        0.9061798459386640};
  const double wg[5] = {0.2369268850561891, 0.4786286704993665, 0.5688888888888889,
                        0.4786286704993665, 0.2369268850561891};
  for (auto f : kAllFunctions) {
    const SubloadingFrictionLaw law(paper_law(OverstressForm::exponential, f));
    const double r = 0.8;
    double sum = 0.0;
    for (double hi = r; hi > 0.0;) {
      const double lo = hi < 1e-15 ? 0.0 : hi - std::min(0.005, 0.15 * hi);
      for (int i = 0; i < 5; ++i) {
        const double x = 0.5 * (lo + hi) + 0.5 * (hi - lo) * xg[i];
        sum += 0.5 * (hi - lo) * wg[i] / U_ref(f, u, x);
      }
      hi = lo;
    }
    // Quadrature converged to rounding (~1e-15 relative of a sum of ~400 positive terms).
    EXPECT_NEAR(law.subloading_slip_integral(r), sum, 1e-13 * sum) << to_string(f);
  }
}

// Regression (was a bug): for the cot form, the formula
// -(2/(pi u)) ln sin(pi (1 - r)/2) loses all its digits as r -> 0
// (the sine rounds to 1 - O(r^2)), e.g. r = 1e-6 gives a relative error ~1e-4 and r = 1e-9 gives
// exactly 0, which breaks the documented "monotone increasing" property. Expected: the series
// s = (pi r^2/(4u)) (1 + (pi r/2)^2/6), accurate to ~(pi r/2)^4 relative, i.e. to rounding here.
TEST(LawExactUpdates, CotSlipIntegralAccurateAtSmallRatio) {
  const double u = 80.0;
  const SubloadingFrictionLaw law(paper_law());
  for (double r : {1e-3, 1e-6, 1e-9}) {
    const double z = 0.5 * kPi * r;
    const double series = kPi * r * r / (4.0 * u) * (1.0 + z * z / 6.0);
    // Neglected series term ~z^4/90 <= 7e-14 relative at r = 1e-3; rounding a few eps.
    EXPECT_NEAR(law.subloading_slip_integral(r), series, 1e-12 * series) << "r=" << r;
    EXPECT_NEAR(law.subloading_ratio_after(0.0, law.subloading_slip_integral(r)).value, r,
                1e-12 * r)
        << "r=" << r;
  }
}

// Regressions (were bugs) at small ratios, where slips of 1e-40 and below occur in implicit
// iterates on their way to zero:
// * for the reciprocal U the closed form (-ln(1 - r) - r)/u cancels (relative error ~2 eps / r:
//   4e-4 at r = 1e-12, no digit below r = 1e-16): expected the series (r^2/2 + r^3/3 + r^4/4)/u,
//   whose next term is below rounding at these r;
// * for neg_log, libstdc++'s Ei beyond |x| = 50 kept only the first term of its asymptotic series,
//   so H(r) = -Ei(ln r)/u was off by 1/L (L = ln(1/r)) and its slope was not 1/U: expected
//   dH/dr = 1/U(r) by central differences (error ~1e-8 relative with a step of 1e-4 r), on both
//   sides of r = e^-50 and far below, and H increasing across e^-50.
// The update from 0 by H(r) gives r back to rounding, down to the smallest ratios (Newton in r
// bisected towards them: ~log2(1/r) evaluations of Ei).
TEST(LawExactUpdates, SlipIntegralAndUpdateAccurateAtTinyRatios) {
  const double u = 80.0;
  const SubloadingFrictionLaw reciprocal(
      paper_law(OverstressForm::exponential, SubloadingFunction::reciprocal));
  const SubloadingFrictionLaw neg_log(
      paper_law(OverstressForm::exponential, SubloadingFunction::neg_log));
  for (double r : {1e-6, 1e-9, 1e-20, 1e-100, 1e-300}) {
    const double series = (0.5 * r * r + r * r * r / 3.0 + r * r * r * r / 4.0) / u;
    if (series > std::numeric_limits<double>::min()) {
      EXPECT_NEAR(reciprocal.subloading_slip_integral(r), series, 1e-14 * series) << "r=" << r;
      EXPECT_NEAR(reciprocal.subloading_ratio_after(0.0, series).value, r, 1e-14 * r) << "r=" << r;
    }
  }
  for (double r : {1e-9, 1e-20, std::exp(-49.9), std::exp(-50.1), 1e-100, 1e-300}) {
    const double h = 1e-4 * r;
    const double slope =
        (neg_log.subloading_slip_integral(r + h) - neg_log.subloading_slip_integral(r - h)) /
        (2.0 * h);
    const double inverse_u = 1.0 / (-u * std::log(r));
    EXPECT_NEAR(slope, inverse_u, 1e-7 * inverse_u) << "r=" << r;
    const double H = neg_log.subloading_slip_integral(r);
    EXPECT_NEAR(neg_log.subloading_ratio_after(0.0, H).value, r, 1e-14 * r) << "r=" << r;
  }
  EXPECT_LT(neg_log.subloading_slip_integral(std::exp(-50.0) * (1.0 - 1e-9)),
            neg_log.subloading_slip_integral(std::exp(-50.0) * (1.0 + 1e-9)));
}

namespace {

// RK4 of the mu evolution (3.4) at constant slip rate sdot = slip/dt, over the step.
double rk4_mu(const FrictionCoefficientEvolution& fr, double mu0, double slip, double dt, int n) {
  const double sdot = slip / dt;
  auto rhs = [&](double mu) {
    return fr.kappa * (1.0 - mu / fr.mu_k) * sdot + fr.xi * (1.0 - mu / fr.mu_s);
  };
  const double h = dt / n;
  double mu = mu0;
  for (int i = 0; i < n; ++i) {
    const double k1 = rhs(mu), k2 = rhs(mu + 0.5 * h * k1), k3 = rhs(mu + 0.5 * h * k2),
                 k4 = rhs(mu + h * k3);
    mu += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
  }
  return mu;
}

}  // namespace

TEST(LawExactUpdates, FrictionCoefficientEqualsRk4AtConstantSlipRate) {
  const FrictionCoefficientEvolution cases[] = {
      {0.097, 0.085, 0.2, 0.009},  // paper section 5
      {0.097, 0.085, 0.0, 0.009},  // kappa = 0: pure recovery
      {0.097, 0.085, 0.2, 0.0},    // xi = 0: pure sliding softening
      {0.09, 0.09, 0.2, 0.009},    // mu_s = mu_k
      {0.085, 0.097, 1.0, 0.005},  // mu_k > mu_s: hardening by slip
  };
  const std::pair<double, double> steps[] = {{0.0, 1.0},  {1e-6, 1e-3},  {0.5, 1.0},
                                             {5.0, 0.01}, {0.01, 100.0}, {20.0, 1e4}};
  for (const auto& fr : cases) {
    LawParameters p = paper_law();
    p.friction = fr;
    const SubloadingFrictionLaw law(p);
    for (double mu0 : {fr.mu_s, fr.mu_k, 0.05, 0.12}) {
      for (auto [slip, dt] : steps) {
        // B = b dt is the number of e-folds of the step, z = h b = B/n <= 0.01 per RK4 step.
        // The linear ODE's RK4 error is z^5/120 relative per step, so at the end it is
        // B z^4/120 e^{-B} |mu0 - mu_inf| <= 2e-14 over all (B, n) used (worst near B = 5,
        // n = 1000); tolerance 1e-12 absolute (mu ~ 0.1) adds room for rounding.
        const double B = fr.kappa * slip / fr.mu_k + fr.xi * dt / fr.mu_s;
        const int n = std::max(1000, static_cast<int>(std::ceil(100.0 * B)));
        const double ref = rk4_mu(fr, mu0, slip, dt, n);
        const auto got = law.friction_coefficient_after(mu0, slip, dt);
        EXPECT_NEAR(got.value, ref, 1e-12)
            << "mu_s=" << fr.mu_s << " mu_k=" << fr.mu_k << " kappa=" << fr.kappa << " xi=" << fr.xi
            << " mu0=" << mu0 << " slip=" << slip << " dt=" << dt;
        // The exact update never overshoots: mu1 lies between mu0 and the attractor
        // mu_inf = (kappa sdot + xi)/(kappa sdot/mu_k + xi/mu_s).
        const double sdot = slip / dt;
        const double den = fr.kappa * sdot / fr.mu_k + fr.xi / fr.mu_s;
        if (den > 0.0) {
          const double mu_inf = (fr.kappa * sdot + fr.xi) / den;
          EXPECT_GE(got.value, std::min(mu0, mu_inf) - 4 * kEps);
          EXPECT_LE(got.value, std::max(mu0, mu_inf) + 4 * kEps);
        } else {
          EXPECT_EQ(got.value, mu0);  // kappa = xi = 0 or nothing drives mu
        }
      }
    }
  }
}

// The three limits in closed form (solutions of the linear ODE (3.4) with one term missing):
//   kappa = 0:      mu(t) = mu_s + (mu0 - mu_s) exp(-xi t/mu_s)
//   xi = 0:         mu(s) = mu_k + (mu0 - mu_k) exp(-kappa s/mu_k)
//   mu_s = mu_k = m: mu    = m + (mu0 - m) exp(-(kappa s + xi t)/m)
TEST(LawExactUpdates, FrictionCoefficientLimitsInClosedForm) {
  for (double mu0 : {0.05, 0.09, 0.12}) {
    for (auto [s, t] : {std::pair{0.3, 2.0}, std::pair{3.0, 50.0}, std::pair{1e-7, 1e-5}}) {
      LawParameters p = paper_law();
      p.friction = {0.097, 0.085, 0.0, 0.009};
      double expected = 0.097 + (mu0 - 0.097) * std::exp(-0.009 * t / 0.097);
      // Closed form vs closed form: a few eps of mu.
      EXPECT_NEAR(SubloadingFrictionLaw(p).friction_coefficient_after(mu0, s, t).value, expected,
                  8 * kEps);
      p.friction = {0.097, 0.085, 0.2, 0.0};
      expected = 0.085 + (mu0 - 0.085) * std::exp(-0.2 * s / 0.085);
      EXPECT_NEAR(SubloadingFrictionLaw(p).friction_coefficient_after(mu0, s, t).value, expected,
                  8 * kEps);
      p.friction = {0.09, 0.09, 0.2, 0.009};
      expected = 0.09 + (mu0 - 0.09) * std::exp(-(0.2 * s + 0.009 * t) / 0.09);
      EXPECT_NEAR(SubloadingFrictionLaw(p).friction_coefficient_after(mu0, s, t).value, expected,
                  8 * kEps);
    }
  }
}

// Small steps take the update's (1 - e^-B)/B from its series (no expm1): the value and slope
// agree with the closed form in long double to a few eps on both sides of where the series
// stops (B = 1/16), across the range of B one step sees.
TEST(LawExactUpdates, FrictionCoefficientSeriesMatchesClosedFormInLongDouble) {
  LawParameters p = paper_law();
  p.friction = {0.097, 0.085, 0.7, 0.0};  // xi = 0: B = kappa slip / mu_k
  const SubloadingFrictionLaw law(p);
  const long double kappa = 0.7L, mu_k = 0.085L, mu0 = 0.097L;
  for (double b = 1e-9; b < 4.0; b *= 1.37) {
    const double slip = b * 0.085 / 0.7;
    const long double big_b = kappa * static_cast<long double>(slip) / mu_k;
    // phi = (1 - e^-B)/B and its slope: closed form for B >= 1; below, where the closed slope
    // cancels, their series to 40 terms in long double (truncation < 1e-40).
    long double phi = -std::expm1(-big_b) / big_b;
    long double dphi = (std::exp(-big_b) * big_b + std::expm1(-big_b)) / (big_b * big_b);
    if (big_b < 1.0L) {
      long double term = 1.0L;  // (-B)^k / (k+1)!
      phi = 0.0L, dphi = 0.0L;
      for (int k = 0; k < 40; ++k) {
        phi += term;
        if (k < 39) dphi += (k + 1) * term * (-1.0L) / (k + 2);  // (k+1) c_{k+1} B^k
        term *= -big_b / (k + 2);
      }
    }
    const long double drive = kappa * slip - big_b * mu0;
    const long double mu1 = mu0 + drive * phi;
    const long double d_mu1 = (kappa - kappa / mu_k * mu0) * phi + drive * dphi * (kappa / mu_k);
    const auto got = law.friction_coefficient_after(0.097, slip, 1.0);
    EXPECT_NEAR(got.value, static_cast<double>(mu1), 4 * kEps * 0.097) << "B = " << b;
    // The slope is a sum of two terms of opposite sign: its rounding is relative to theirs.
    const long double terms =
        std::abs((kappa - kappa / mu_k * mu0) * phi) + std::abs(drive * dphi * (kappa / mu_k));
    EXPECT_NEAR(got.d_slip, static_cast<double>(d_mu1), 16 * kEps * static_cast<double>(terms))
        << "B = " << b;
  }
}

// ---------------------------------------------------------------------------------------------
// Analytical steady state (paper section 3b) and the functions U.
// ---------------------------------------------------------------------------------------------

namespace {

// mu_ss from kappa (1 - mu/mu_k) v + xi (1 - mu/mu_s) = 0 (linear in mu).
double steady_mu(const FrictionCoefficientEvolution& f, double v) {
  return (f.kappa * v + f.xi) / (f.kappa * v / f.mu_k + f.xi / f.mu_s);
}

// r_ss from phi(r, 1) = v by plain bisection on [1, r_hat] (phi increasing there).
double steady_r(const Overstress& o, double v) {
  double lo = 1.0, hi = o.r_hat;
  for (int i = 0; i < 200 && hi - lo > 0.0; ++i) {
    const double mid = 0.5 * (lo + hi);
    if (mid == lo || mid == hi) break;
    (phi_ref(o, mid, 1.0) < v ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace

TEST(LawSteadyState, MatchesIndependentSolution) {
  for (auto form : {OverstressForm::exponential, OverstressForm::power}) {
    const SubloadingFrictionLaw law(paper_law(form));
    const auto& p = law.parameters();
    for (double v : {1e-4, 1.0, 10.0, 200.0, 1e6}) {
      const auto ss = law.steady_state(v);
      const double mu = steady_mu(p.friction, v);
      const double r = steady_r(p.overstress, v);
      EXPECT_NEAR(ss.mu, mu, 4 * kEps * mu);
      // Bisection is exact to one ulp; the code's Newton stops at |phi - v| <= 1e-14 v, i.e.
      // |dr| <= 1e-14 v / phi_r (phi_r estimated by a difference here), or at 1e-16 in r.
      const double phi_r = phi_r_ref(p.overstress, r, 1.0);
      EXPECT_NEAR(ss.r, r, 4 * kEps + 2e-14 * v / phi_r) << to_string(form) << " v=" << v;
      EXPECT_NEAR(ss.ratio, ss.r * ss.mu, 2 * kEps * ss.ratio);
    }
  }
  const SubloadingFrictionLaw ri(paper_law(OverstressForm::rate_independent));
  const auto ss = ri.steady_state(1.0);
  EXPECT_EQ(ss.r, 1.0);
  EXPECT_NEAR(ss.mu, steady_mu(ri.parameters().friction, 1.0), 4 * kEps);
}

// (2.26): U -> +inf at r = 0, U > 0 on (0, 1), U(1) = 0, U < 0 for r > 1, U decreasing;
// (2.31): cot -> -inf as r -> 2.
TEST(LawSubloadingFunction, SatisfiesPaperConditions) {
  for (auto f : kAllFunctions) {
    const SubloadingFrictionLaw law(paper_law(OverstressForm::exponential, f));
    EXPECT_EQ(law.subloading_rate(0.0), std::numeric_limits<double>::infinity());
    EXPECT_GT(law.subloading_rate(1e-300), 1e3);
    EXPECT_NEAR(law.subloading_rate(1.0), 0.0, 1e-13);
    double previous = std::numeric_limits<double>::infinity();
    for (double r = 0.01; r < 1.95; r += 0.01) {
      const double U = law.subloading_rate(r);
      EXPECT_NEAR(U, U_ref(f, 80.0, r), 4 * kEps * std::abs(U) + 1e-13);
      EXPECT_LT(U, previous) << to_string(f) << " r=" << r;
      if (r < 0.995) {
        EXPECT_GT(U, 0.0);
      }
      if (r > 1.005) {
        EXPECT_LT(U, 0.0);
      }
      previous = U;
    }
  }
  const SubloadingFrictionLaw cot(paper_law());
  EXPECT_LT(cot.subloading_rate(2.0 - 1e-9), -1e9);
}

// (2.41): m^p = kappa (1 - mu/mu_k) r + U(r) mu, m^c = xi (1 - mu/mu_s) r >= 0 for mu <= mu_s.
TEST(LawModuli, PlasticAndCreepModuli) {
  const SubloadingFrictionLaw law(paper_law(OverstressForm::rate_independent));
  for (double r : {0.1, 0.5, 1.0, 1.3}) {
    for (double mu : {0.085, 0.09, 0.097}) {
      EXPECT_NEAR(law.plastic_modulus(r, mu),
                  0.2 * (1.0 - mu / 0.085) * r + U_ref(SubloadingFunction::cot, 80.0, r) * mu,
                  1e-12);
      EXPECT_NEAR(law.creep_modulus(r, mu), 0.009 * (1.0 - mu / 0.097) * r, 1e-16);
      EXPECT_GE(law.creep_modulus(r, mu), 0.0);
    }
  }
  // Normal yield at the kinetic coefficient is the neutral state: m^p = 0.
  EXPECT_NEAR(law.plastic_modulus(1.0, 0.085), 0.0, 1e-13);
}

TEST(LawParametersCheck, RejectsOutOfRange) {
  auto make = [](auto edit) {
    LawParameters p = paper_law();
    edit(p);
    return SubloadingFrictionLaw(p);
  };
  EXPECT_THROW(make([](LawParameters& p) { p.friction.mu_s = 0.0; }), std::invalid_argument);
  EXPECT_THROW(make([](LawParameters& p) { p.friction.mu_k = -1.0; }), std::invalid_argument);
  EXPECT_THROW(make([](LawParameters& p) { p.friction.kappa = -1.0; }), std::invalid_argument);
  EXPECT_THROW(make([](LawParameters& p) { p.friction.xi = -1.0; }), std::invalid_argument);
  EXPECT_THROW(make([](LawParameters& p) { p.subloading.u_tilde = 0.0; }), std::invalid_argument);
  EXPECT_THROW(make([](LawParameters& p) { p.overstress.r_hat = 1.0; }), std::invalid_argument);
  EXPECT_THROW(make([](LawParameters& p) { p.overstress.eta_v = 0.0; }), std::invalid_argument);
  EXPECT_THROW(make([](LawParameters& p) { p.overstress.n = 0.0; }), std::invalid_argument);
  // The rate-independent model has no overstress parameters to check.
  EXPECT_NO_THROW(make([](LawParameters& p) {
    p.overstress.form = OverstressForm::rate_independent;
    p.overstress.r_hat = 0.5;
  }));
}
