// Fitting the law to single-crystal tension curves: the model's stress and its sensitivities
// along the mixed-controlled path (lateral stresses held at zero) against finite differences of
// whole paths, the lateral stresses' zero, and the recovery of the initial CRSS and the hardening
// constants from three orientations' curves with noise.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "subslip/calibration/crystal_fit.hpp"
#include "subslip/crystal/aggregate.hpp"
#include "subslip/crystal/elasticity.hpp"
#include "subslip/crystal/phase_builder.hpp"
#include "subslip/law/parameter_table.hpp"

namespace {

using namespace subslip;
using crystal::kGrainParameterCount;

// Copper's elasticity and a hardening law (CRSS mu tau0 from 16 MPa toward 148 MPa) [MPa, s].
law::LawParameters copper_law(double eta_v) {
  law::LawParameters p;
  p.friction = {1.6, 14.8, 20.0, 0.0};
  p.subloading = {law::SubloadingFunction::cot, 200.0};
  p.overstress = {law::OverstressForm::exponential, eta_v, 16.0, 1.6};
  return p;
}

crystal::PhaseDescription copper(const law::LawParameters& law, double initial_mu = 0.0) {
  crystal::PhaseDescription d;
  d.families = {crystal::SlipFamily::fcc_111_110};
  d.family_settings = {{law, 10.0, initial_mu}};
  d.stiffness = crystal::cubic_stiffness(168400.0, 121400.0, 75400.0);
  return d;
}

// The orientation that puts the crystal direction `axis` along sample x (v_crystal = g v_sample).
Eigen::Matrix3d along_x(const Eigen::Vector3d& axis) {
  return Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitX(), axis.normalized())
      .toRotationMatrix();
}

const std::vector<Eigen::Vector3d> kAxes = {{0, 0, 1}, {1, 1, 1}, {-1, 2, 3}};

// `count` strains from 0.002 to `last` (evenly), tension at 1e-3/s.
calibration::CrystalCurve tension(const Eigen::Vector3d& axis, int count, double last) {
  calibration::CrystalCurve c;
  std::ostringstream name;
  name << "[" << axis.x() << " " << axis.y() << " " << axis.z() << "]";
  c.name = name.str();
  c.orientation = along_x(axis);
  c.strain_rate = 1e-3;
  for (int i = 0; i < count; ++i) c.strain.push_back(0.002 + (last - 0.002) * i / (count - 1));
  c.stress.assign(c.strain.size(), 0.0);
  return c;
}

// The constant of column k of a phase with one slip family.
double& constant(crystal::PhaseDescription& d, int k) {
  crystal::SlipGroupSettings& g = d.family_settings.front();
  if (k == crystal::kTau0Column) return g.tau0;
  if (k == crystal::kInitialMuColumn) return g.initial_mu;
  return law::kLawParameters[static_cast<std::size_t>(k)].ref(g.law);
}

std::string column_name(int k) {
  if (k == crystal::kTau0Column) return "tau0";
  if (k == crystal::kInitialMuColumn) return "initial_mu";
  return std::string(law::kLawParameters[static_cast<std::size_t>(k)].name);
}

// Every column's sensitivity of sigma11 along a mixed-controlled path equals central differences
// of whole paths (Richardson from relative steps 2h and h, h = 1e-4) to 1e-6 of its largest
// magnitude. A rate-sensitive law (eta_v = 500 s at 1e-3/s): its rate constants move the stress
// by a part in ten, which differences of converged paths resolve.
TEST(CrystalFit, StressSensitivitiesAlongTheMixedPathMatchFiniteDifferences) {
  crystal::PhaseDescription phase = copper(copper_law(500.0), 1.4);
  constant(phase, 3) = 0.02;  // xi: recovery in time, so that its column is not zero
  const calibration::CrystalCurve curve = tension(kAxes[2], 12, 0.03);
  const calibration::CrystalPathSteps steps{60};
  const calibration::CrystalPrediction carried = calibration::predict(phase, curve, steps);
  for (int k = 0; k < kGrainParameterCount; ++k) {
    const auto central = [&](double relative) {
      crystal::PhaseDescription up = phase, down = phase;
      const double h = relative * constant(phase, k);
      constant(up, k) += h;
      constant(down, k) -= h;
      const auto a = calibration::predict(up, curve, steps).stress;
      const auto b = calibration::predict(down, curve, steps).stress;
      std::vector<double> d;
      for (std::size_t i = 0; i < a.size(); ++i) d.push_back((a[i] - b[i]) / (2.0 * h));
      return d;
    };
    const std::vector<double> coarse = central(2e-4), fine = central(1e-4);
    double scale = 0.0, error = 0.0;
    for (std::size_t i = 0; i < fine.size(); ++i) {
      const double fd = (4.0 * fine[i] - coarse[i]) / 3.0;
      const double d = carried.gradient(static_cast<Eigen::Index>(i), k);
      scale = std::max(scale, std::abs(d));
      error = std::max(error, std::abs(d - fd));
    }
    EXPECT_GT(scale, 0.0) << column_name(k);
    EXPECT_LE(error, 1e-6 * scale) << column_name(k) << ": largest " << scale;
    std::printf("  %-10s largest %.3e MPa/unit  relative difference %.2e\n", column_name(k).c_str(),
                scale, scale > 0.0 ? error / scale : 0.0);
  }
}

// The curve's path is the loading of the single-crystal tension scenes, which the Taylor
// aggregate runs: one grain, L11 prescribed, sigma22 = sigma33 = 0 with L22 and L33 free, no
// shear. Both solve the same steps' equations (the aggregate's mixed control to its tolerance
// of 1e-10 of the stress), so sigma11 agrees to far below the steps' own error.
TEST(CrystalFit, ThePathIsTheAggregatesUniaxialTension) {
  const crystal::PhaseDescription phase = copper(copper_law(1e-3));
  calibration::CrystalCurve curve = tension(kAxes[2], 10, 0.05);
  curve.strain.clear();
  for (int i = 1; i <= 10; ++i) curve.strain.push_back(0.005 * i);
  const calibration::CrystalPrediction p = calibration::predict(phase, curve, {50});

  crystal::LoadSegment seg;
  seg.velocity_gradient(0, 0) = curve.strain_rate;
  seg.free(1, 1) = seg.free(2, 2) = true;
  seg.duration = 0.05 / curve.strain_rate;
  seg.increments = 50;
  seg.output_every = 5;
  auto aggregate = crystal::build_taylor_aggregate(
      phase, {crystal::Orientation::from_matrix(curve.orientation)});
  std::vector<double> sigma11;
  aggregate->run({seg}, crystal::AggregateOptions{},
                 [&](const crystal::MacroState& m, const crystal::GrainFields&) {
                   sigma11.push_back(m.stress(0, 0));
                 });
  ASSERT_EQ(sigma11.size(), p.stress.size() + 1);  // and the initial state
  for (std::size_t i = 0; i < p.stress.size(); ++i)
    EXPECT_NEAR(p.stress[i], sigma11[i + 1], 1e-8 * std::abs(sigma11[i + 1])) << "point " << i;
  EXPECT_GT(p.stress.back(), 2.0 * 16.0);  // past yield: twice the CRSS, Schmid factor 1/2 at most
}

// Three orientations' curves to 30 % strain with 1 % noise (seeds 1 ... 10), every free constant
// started 30 % off: mu_s (the initial CRSS mu_s tau0), mu_k and kappa (the hardening) and u_tilde
// (the elastic-plastic transition). The true value lies inside the 95 % interval in at least 8
// of 10 seeds for each (19 of 20 on average).
TEST(CrystalFit, RecoversTheCrssAndTheHardeningFromThreeOrientations) {
  const law::LawParameters truth = copper_law(1e-3);
  const calibration::CrystalPathSteps steps{50};
  std::vector<calibration::CrystalCurve> exact;
  for (const Eigen::Vector3d& axis : kAxes) {
    calibration::CrystalCurve c = tension(axis, 40, 0.3);
    c.stress = calibration::predict(copper(truth), c, steps).stress;
    exact.push_back(c);
  }
  const std::vector<int> free = {0, 1, 2, 4};  // mu_s, mu_k, kappa, u_tilde
  constexpr int kSeeds = 10;
  std::vector<int> inside(free.size(), 0);
  for (unsigned seed = 1; seed <= kSeeds; ++seed) {
    std::mt19937_64 random(seed);
    std::normal_distribution<double> noise(0.0, 0.01);
    calibration::CrystalFitProblem problem;
    problem.phase = copper(truth);
    problem.steps = steps;
    problem.curves = exact;
    for (auto& c : problem.curves)
      for (double& s : c.stress) s *= 1.0 + noise(random);
    for (std::size_t j = 0; j < free.size(); ++j) {
      const auto& info = law::kLawParameters[static_cast<std::size_t>(free[j])];
      const double value = info.value(truth);
      info.ref(problem.phase.family_settings.front().law) = value * (j % 2 == 0 ? 1.3 : 0.7);
      problem.free.push_back({free[j], value / 5.0, value * 5.0, true});
    }
    const calibration::FitResult r = calibration::fit(problem);
    ASSERT_TRUE(r.converged) << "seed " << seed << ": " << r.termination;
    std::printf("  seed %u: %d iterations;", seed, r.iterations);
    for (std::size_t j = 0; j < free.size(); ++j)
      std::printf(" %s %.4g [%.4g, %.4g]", r.names[j].c_str(), r.estimate[j], r.lower[j],
                  r.upper[j]);
    std::printf("\n");
    EXPECT_TRUE(r.warnings.empty()) << "seed " << seed << ": " << r.warnings.front();
    for (std::size_t j = 0; j < free.size(); ++j) {
      const double value = law::kLawParameters[static_cast<std::size_t>(free[j])].value(truth);
      if (r.lower[j] <= value && value <= r.upper[j]) ++inside[j];
    }
  }
  for (std::size_t j = 0; j < free.size(); ++j)
    EXPECT_GE(inside[j], 8) << column_name(free[j]) << ": inside in " << inside[j] << " of "
                            << kSeeds;
}

TEST(CrystalFit, Tau0IsNeverFree) {
  calibration::CrystalFitProblem problem;
  problem.phase = copper(copper_law(1e-3));
  problem.curves = {tension(kAxes[0], 5, 0.01)};
  problem.free = {{crystal::kTau0Column, 1.0, 100.0, true}};
  try {
    (void)calibration::fit(problem);
    FAIL() << "tau0 was fitted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("only the CRSS"), std::string::npos) << e.what();
  }
}

}  // namespace
