// Forward sensitivities of a grain's path to its law's constants, tau0 and initial_mu, carried
// through the implicit grain steps, against central finite differences of whole runs; and the
// replay they differentiate, which must be the step's own equations.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "../src/crystal/grain_sensitivity.hpp"
#include "subslip/crystal/elasticity.hpp"
#include "subslip/law/parameter_table.hpp"
#include "subslip/material_point.hpp"

namespace {

using namespace subslip;
using crystal::kGrainParameterCount;

// What a grain's constants are: the law, tau0 [MPa] and initial_mu (0: mu_s).
struct Constants {
  law::LawParameters law;
  double tau0 = 20.0;
  double initial_mu = 0.0;

  double& operator[](int k) {
    if (k == crystal::kTau0Column) return tau0;
    if (k == crystal::kInitialMuColumn) return initial_mu;
    return law::kLawParameters[static_cast<std::size_t>(k)].ref(law);
  }
};

// A hardening law (mu_s < mu_k, kappa > 0) that recovers in time (xi > 0).
law::LawParameters hardening_law(law::OverstressForm form) {
  law::LawParameters p;
  p.friction = {1.0, 1.6, 3.0, 0.02};
  p.subloading = {law::SubloadingFunction::cot, 200.0};
  if (form == law::OverstressForm::exponential)
    p.overstress = {form, 500.0, 16.0, 1.8};
  else
    p.overstress = {form, 2.0, 3.0, 1.8};
  return p;
}

enum class Lattice { fcc, fcc_latent, bcc, single_slip };

crystal::PhaseDescription phase_of(Lattice lattice, const Constants& c) {
  crystal::PhaseDescription d;
  const crystal::SlipGroupSettings settings{c.law, c.tau0, c.initial_mu};
  switch (lattice) {
    case Lattice::fcc:
    case Lattice::fcc_latent:
      d.families = {crystal::SlipFamily::fcc_111_110};
      if (lattice == Lattice::fcc_latent)
        d.latent = {crystal::LatentHardening::Kind::coplanar, 1.0, 1.0, 1.4};
      d.family_settings = {settings};
      d.stiffness = crystal::cubic_stiffness(168400.0, 121400.0, 75400.0);
      break;
    case Lattice::bcc:
      d.families = {crystal::SlipFamily::bcc_110_111, crystal::SlipFamily::bcc_112_111};
      d.family_settings = {settings, settings};
      d.stiffness = crystal::cubic_stiffness(231400.0, 134700.0, 116400.0);
      break;
    case Lattice::single_slip:
      d.custom_systems = {{Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 0, 1)}};
      d.custom_settings = settings;
      d.stiffness = crystal::cubic_stiffness(168400.0, 121400.0, 75400.0);
      break;
  }
  return d;
}

point::GrainOptions tight() {
  point::GrainOptions o;
  o.tolerance = 1e-15;  // the differences below resolve 1e-6 of the derivatives
  o.tangent = false;
  return o;
}

// A general orientation: Bunge angles (40, 30, 70) degrees.
Eigen::Matrix3d general_orientation() {
  const double deg = std::acos(-1.0) / 180.0;
  return (Eigen::AngleAxisd(70 * deg, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(30 * deg, Eigen::Vector3d::UnitX()) *
          Eigen::AngleAxisd(40 * deg, Eigen::Vector3d::UnitZ()))
      .toRotationMatrix()
      .transpose();
}

struct Step {
  Eigen::Matrix3d L;
  double dt;
};

// Tension along a direction off the crystal axes (with some shear, so the lattice turns), a
// hold (the stress relaxes, mu recovers towards mu_s), and a reversal into compression: fixed
// steps of 0.5 s at a strain rate of 1e-3/s.
std::vector<Step> path(double strain_per_segment) {
  Eigen::Matrix3d tension;
  tension << 1.0, 0.2, 0.0, 0.1, -0.5, 0.0, 0.0, 0.05, -0.5;
  tension *= 1e-3;
  const double dt = 0.5;
  const int steps = static_cast<int>(std::lround(strain_per_segment / (1e-3 * dt)));
  std::vector<Step> p;
  for (int i = 0; i < steps; ++i) p.push_back({tension, dt});
  for (int i = 0; i < 10; ++i) p.push_back({Eigen::Matrix3d::Zero(), 2.0});
  for (int i = 0; i < 2 * steps; ++i) p.push_back({-tension, dt});
  return p;
}

// The outputs compared at every state: the sample-frame stress, mu and r_s of every system.
enum Quantity { stress, mu, r_s, kQuantities };
const char* const kQuantityNames[] = {"stress", "mu", "r_s"};

struct Outputs {
  std::string active;          // which systems slipped in each step, and which way
  double relative_step = 0.0;  // of finite differences: the h they took
  std::vector<double> values[kQuantities];
  std::vector<Eigen::Matrix<double, 1, kGrainParameterCount>> gradients[kQuantities];
};

Outputs run(Lattice lattice, const Constants& c, const std::vector<Step>& steps,
            bool sensitivities) {
  const point::GrainPoint grain(phase_of(lattice, c), tight());
  point::GrainState s = grain.initial_state(general_orientation());
  point::GrainSensitivity d;
  if (sensitivities) d = grain.initial_sensitivity();
  Outputs out;
  for (const Step& step : steps) {
    const point::GrainUpdate u =
        sensitivities ? grain.update(s, step.L, step.dt, d) : grain.update(s, step.L, step.dt);
    if (!u.report.ok) throw std::runtime_error("grain step failed: " + u.report.why);
    s = u.state;
    for (int i = 0; i < 6; ++i) {
      out.values[stress].push_back(u.stress(i));
      if (sensitivities) out.gradients[stress].push_back(d.sample_stress.row(i));
    }
    for (int a = 0; a < s.mu.size(); ++a) {
      out.active += s.rate(a) > 0.0 ? '+' : s.rate(a) < 0.0 ? '-' : '.';
      out.values[mu].push_back(s.mu(a));
      out.values[r_s].push_back(s.r_s(a));
      if (sensitivities) {
        out.gradients[mu].push_back(d.mu.row(a));
        out.gradients[r_s].push_back(d.r_s.row(a));
      }
    }
  }
  return out;
}

// d(outputs)/d(constant k) by central differences of whole runs, Richardson-extrapolated from
// relative steps 2h and h (truncation error of order h^4). A run of fixed steps is a smooth
// function of the constants only between events: a system that starts or stops slipping in
// another step (in a hold, recovery lifts r past r_s at a time that depends on every
// constant). So h is the largest of 1e-3, 1e-4, 1e-5 whose runs keep the base run's active
// systems in every step: the largest keeps the runs' round-off (the solve resolves a stress to
// a few ulp, which a difference over h magnifies by 1/h) the smallest.
Outputs finite_difference(Lattice lattice, const Constants& c, const std::vector<Step>& steps,
                          int k, const std::string& active) {
  bool same_events = true;
  auto central = [&](double relative) {
    Constants up = c, down = c;
    const double step = relative * up[k];
    up[k] += step;
    down[k] -= step;
    const Outputs a = run(lattice, up, steps, false), b = run(lattice, down, steps, false);
    same_events = same_events && a.active == active && b.active == active;
    Outputs d;
    for (int q = 0; q < kQuantities; ++q)
      for (std::size_t i = 0; i < a.values[q].size(); ++i)
        d.values[q].push_back((a.values[q][i] - b.values[q][i]) / (2.0 * step));
    return d;
  };
  for (double h : {1e-3, 1e-4, 1e-5}) {
    same_events = true;
    const Outputs coarse = central(2.0 * h), fine = central(h);
    if (!same_events) continue;
    Outputs d = fine;
    for (int q = 0; q < kQuantities; ++q)
      for (std::size_t i = 0; i < d.values[q].size(); ++i)
        d.values[q][i] = (4.0 * fine.values[q][i] - coarse.values[q][i]) / 3.0;
    d.relative_step = h;
    return d;
  }
  ADD_FAILURE() << "an event within 2e-5 of " << k << ": no finite difference";
  return {};
}

std::string column_name(int k) {
  if (k == crystal::kTau0Column) return "tau0";
  if (k == crystal::kInitialMuColumn) return "initial_mu";
  return std::string(law::kLawParameters[static_cast<std::size_t>(k)].name);
}

// Every constant: each quantity's sensitivities along the path equal the finite differences to
// 1e-6 of their largest magnitude over the path (which must not vanish: the path depends on
// every constant), but initial_mu's where the phase starts from mu_s (its column is zero).
void expect_sensitivities_match(Lattice lattice, const Constants& c,
                                const std::vector<Step>& steps) {
  const Outputs carried = run(lattice, c, steps, true);
  const Outputs plain = run(lattice, c, steps, false);
  for (int q = 0; q < kQuantities; ++q)
    ASSERT_EQ(carried.values[q], plain.values[q]) << "carrying them changed the path";
  for (int k = 0; k < kGrainParameterCount; ++k) {
    if (k == crystal::kInitialMuColumn && !(c.initial_mu > 0.0)) {
      for (int q = 0; q < kQuantities; ++q)
        for (const auto& g : carried.gradients[q]) ASSERT_EQ(g(k), 0.0);
      continue;
    }
    const Outputs fd = finite_difference(lattice, c, steps, k, plain.active);
    ASSERT_GT(fd.relative_step, 0.0);
    for (int q = 0; q < kQuantities; ++q) {
      double scale = 0.0, error = 0.0;
      std::size_t worst = 0;
      for (std::size_t i = 0; i < fd.values[q].size(); ++i) {
        const double d = carried.gradients[q][i](k);
        scale = std::max(scale, std::abs(d));
        if (std::abs(d - fd.values[q][i]) > error) {
          error = std::abs(d - fd.values[q][i]);
          worst = i;
        }
      }
      EXPECT_GT(scale, 0.0) << column_name(k) << ", " << kQuantityNames[q];
      EXPECT_LE(error, 1e-6 * scale)
          << column_name(k) << ", " << kQuantityNames[q] << ": output " << worst << " carried "
          << carried.gradients[q][worst](k) << ", finite differences " << fd.values[q][worst]
          << ", largest " << scale;
      std::printf("  %-10s %-6s largest %.3e  relative difference %.2e (h = %.0e)\n",
                  column_name(k).c_str(), kQuantityNames[q], scale,
                  scale > 0.0 ? error / scale : 0.0, fd.relative_step);
    }
  }
}

TEST(GrainSensitivity, FccExponentialOverstressMatchesFiniteDifferences) {
  Constants c{hardening_law(law::OverstressForm::exponential)};
  c.initial_mu = 1.1;
  expect_sensitivities_match(Lattice::fcc, c, path(0.01));
}

TEST(GrainSensitivity, FccPowerOverstressMatchesFiniteDifferences) {
  Constants c{hardening_law(law::OverstressForm::power)};
  c.initial_mu = 1.1;
  expect_sensitivities_match(Lattice::fcc, c, path(0.01));
}

TEST(GrainSensitivity, FccStartingFromMuSMatchesFiniteDifferences) {
  expect_sensitivities_match(Lattice::fcc, {hardening_law(law::OverstressForm::exponential)},
                             path(0.01));
}

// Latent hardening (coplanar 1.0, non-coplanar 1.4): mu is driven by the others' slips too.
TEST(GrainSensitivity, FccLatentHardeningMatchesFiniteDifferences) {
  Constants c{hardening_law(law::OverstressForm::exponential)};
  c.initial_mu = 1.1;
  expect_sensitivities_match(Lattice::fcc_latent, c, path(0.01));
}

// A friction coefficient that softens with slip (mu_k < mu_s) and heals in the hold: the
// signed-slip formulation takes every step (docs/grain_step.md), whose end state the same
// equations hold at.
TEST(GrainSensitivity, FccSofteningMatchesFiniteDifferences) {
  Constants c{hardening_law(law::OverstressForm::exponential)};
  c.law.friction.mu_s = 1.6;
  c.law.friction.mu_k = 1.2;
  expect_sensitivities_match(Lattice::fcc, c, path(0.01));
}

TEST(GrainSensitivity, SingleSlipMatchesFiniteDifferences) {
  Constants c{hardening_law(law::OverstressForm::exponential)};
  c.initial_mu = 1.1;
  expect_sensitivities_match(Lattice::single_slip, c, path(0.01));
}

TEST(GrainSensitivity, Bcc48SystemsMatchFiniteDifferences) {
  Constants c{hardening_law(law::OverstressForm::power)};
  c.initial_mu = 1.1;
  expect_sensitivities_match(Lattice::bcc, c, path(0.005));
}

}  // namespace

namespace {

// The replay that the sensitivities differentiate, in doubles, from each step's start and its
// converged slips: the step's end state to round-off, and every slipping system's flow rule
// within the solve's tolerance. Were a term of the step's equations missing or different, the
// end state would differ by far more (its size times the term's share).
TEST(GrainSensitivity, ReplayIsTheStepsOwnEquations) {
  Constants c{hardening_law(law::OverstressForm::exponential)};
  c.initial_mu = 1.1;
  const crystal::PhaseDescription description = phase_of(Lattice::fcc, c);
  const point::GrainPoint grain(description, tight());
  const crystal::Phase<12> phase = crystal::build_phase<12>(description).phase;
  point::GrainState s = grain.initial_state(general_orientation());
  auto kernel_state = [](const point::GrainState& p) {
    crystal::GrainState<12> k;
    k.stress = p.stress, k.orientation = p.orientation, k.mu = p.mu, k.r_s = p.r_s, k.slip = p.slip,
    k.rate = p.rate;
    return k;
  };
  double worst_stress = 0.0, worst_slip_state = 0.0, worst_orientation = 0.0, worst_residual = 0.0;
  int slipping = 0;
  for (const Step& step : path(0.01)) {
    const point::GrainUpdate u = grain.update(s, step.L, step.dt);
    ASSERT_TRUE(u.report.ok) << u.report.why;
    const crystal::GrainState<12> s0 = kernel_state(s), s1 = kernel_state(u.state);
    const auto replayed = crystal::replayed_grain_step(
        phase, s0, step.L, step.dt, crystal::SlipTypes<12>::VecN(s1.rate * step.dt));
    const double stress_size = s1.stress.cwiseAbs().maxCoeff();
    worst_stress = std::max(
        worst_stress, (replayed.state.stress - s1.stress).cwiseAbs().maxCoeff() / stress_size);
    worst_slip_state =
        std::max({worst_slip_state, (replayed.state.mu - s1.mu).cwiseAbs().maxCoeff(),
                  (replayed.state.r_s - s1.r_s).cwiseAbs().maxCoeff()});
    worst_orientation = std::max(
        worst_orientation, (replayed.state.orientation - s1.orientation).cwiseAbs().maxCoeff());
    worst_residual = std::max(worst_residual, replayed.residual.cwiseAbs().maxCoeff());
    slipping += static_cast<int>((s1.rate.array() != 0.0).count());
    s = u.state;
  }
  std::printf(
      "  replay: stress %.1e (relative), mu and r_s %.1e, orientation %.1e, flow rules "
      "%.1e over %d slipping systems\n",
      worst_stress, worst_slip_state, worst_orientation, worst_residual, slipping);
  EXPECT_GT(slipping, 100);
  EXPECT_LE(worst_stress, 1e-13);
  EXPECT_LE(worst_slip_state, 1e-13);
  EXPECT_LE(worst_orientation, 1e-14);
  EXPECT_LE(worst_residual, 1e-12);
}

}  // namespace

namespace {

TEST(GrainSensitivity, PhasesWithoutOneLawAreRefused) {
  Constants c{hardening_law(law::OverstressForm::exponential)};
  crystal::PhaseDescription two_laws = phase_of(Lattice::bcc, c);
  two_laws.family_settings[1].tau0 = 25.0;
  const point::GrainPoint grain(two_laws);
  EXPECT_THROW(grain.initial_sensitivity(), std::invalid_argument);
  point::GrainSensitivity d = point::GrainPoint(phase_of(Lattice::bcc, c)).initial_sensitivity();
  EXPECT_THROW(
      grain.update(grain.initial_state(general_orientation()), Eigen::Matrix3d::Zero(), 1.0, d),
      std::invalid_argument);
  two_laws.family_settings[1] = two_laws.family_settings[0];
  two_laws.family_settings[1].law.friction.kappa = 2.0;
  EXPECT_THROW(point::GrainPoint(two_laws).initial_sensitivity(), std::invalid_argument);
  crystal::PhaseDescription pressure = phase_of(Lattice::fcc, c);
  pressure.pressure_sensitive = true;
  EXPECT_THROW(point::GrainPoint(pressure).initial_sensitivity(), std::invalid_argument);
  // A sensitivity of another slip count.
  const point::GrainPoint fcc(phase_of(Lattice::fcc, c));
  EXPECT_THROW(
      fcc.update(fcc.initial_state(general_orientation()), Eigen::Matrix3d::Zero(), 1.0, d),
      std::invalid_argument);
}

}  // namespace

namespace {

// The resistance is CRSS = mu tau0 and mu's evolution is homogeneous of degree one in (mu,
// mu_s, mu_k, kappa, xi): scaling tau0 by c and mu_s, mu_k, kappa, xi and initial_mu by 1/c
// leaves the stress, r_s and the slips as they are and scales mu by 1/c. So along any path
//   tau0 d/dtau0 - sum_q q d/dq = 0 for the stress and r_s, and -mu for mu
// (q over the five), to round-off: an exact check of seven columns that needs no finite
// difference, and the one direction a fit of stress curves cannot determine.
TEST(GrainSensitivity, ScalingTheResistanceIsInvisible) {
  Constants c{hardening_law(law::OverstressForm::exponential)};
  c.initial_mu = 1.1;
  const int scaled[] = {0, 1, 2, 3, crystal::kInitialMuColumn};  // mu_s, mu_k, kappa, xi
  static_assert(law::kLawParameters[3].name == "xi");
  Eigen::Matrix<double, 1, kGrainParameterCount> weights =
      Eigen::Matrix<double, 1, kGrainParameterCount>::Zero();
  weights(crystal::kTau0Column) = c.tau0;
  Constants values = c;
  for (int k : scaled) weights(k) = -values[k];
  const Outputs carried = run(Lattice::fcc, c, path(0.01), true);
  for (int q = 0; q < kQuantities; ++q) {
    double worst = 0.0, scale = 0.0;
    for (std::size_t i = 0; i < carried.values[q].size(); ++i) {
      const auto& g = carried.gradients[q][i];
      const double expected = q == mu ? -carried.values[q][i] : 0.0;
      worst = std::max(worst, std::abs(g.dot(weights) - expected));
      scale = std::max(scale, g.cwiseProduct(weights).cwiseAbs().maxCoeff());
    }
    std::printf("  %-6s: largest term %.3e, identity within %.1e\n", kQuantityNames[q], scale,
                worst);
    EXPECT_GT(scale, 0.0);
    EXPECT_LE(worst, 1e-12 * scale) << kQuantityNames[q];
  }
}

}  // namespace
