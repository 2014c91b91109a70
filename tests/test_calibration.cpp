// Fitting the friction law to curves: recovery of the paper's section-5 constants from synthetic
// curves with noise, the constants one speed leaves undetermined, and the fit file's errors.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "paper_law.hpp"
#include "scratch_dir.hpp"
#include "subslip/calibration/contact_fit.hpp"
#include "subslip/io/fit_file.hpp"
#include "subslip/io/input_error.hpp"
#include "subslip/io/scene_common.hpp"
#include "subslip/law/parameter_table.hpp"

namespace {

using namespace subslip;

contact::ContactModel paper_contact(const law::LawParameters& law) {
  contact::ContactModel m;
  m.law = law;
  m.initial_law_state.mu = law.friction.mu_s;
  m.stiffness = {1.0e6, 1.0e6};
  m.initial_normal_traction = 5.56;
  return m;
}

// 60 distances from 2 um to 10 mm, evenly in log: the rise to the peak, the peak near 0.04 mm
// and the decay to kinetic friction.
std::vector<double> distances() {
  std::vector<double> s;
  for (int i = 0; i < 60; ++i) s.push_back(2e-3 * std::pow(10.0 / 2e-3, i / 59.0));
  return s;
}

// Curves of the law at `speeds` [mm/min] with relative Gaussian noise of 1 %.
std::vector<calibration::Curve> synthetic_curves(const law::LawParameters& truth,
                                                 const std::vector<double>& speeds,
                                                 const calibration::PathSteps& steps,
                                                 unsigned seed) {
  std::mt19937_64 random(seed);
  std::normal_distribution<double> noise(0.0, 0.01);
  std::vector<calibration::Curve> curves;
  for (const double v : speeds) {
    calibration::Curve c;
    c.name = "v = " + std::to_string(v);
    c.speed = v;
    c.slip = distances();
    const auto exact = calibration::predict(paper_contact(truth), true, c, steps);
    for (const double r : exact.ratio) c.ratio.push_back(r * (1.0 + noise(random)));
    curves.push_back(c);
  }
  return curves;
}

// Every constant free, started 30 % off its true value (up and down in turn), within wide
// bounds.
calibration::FitProblem problem_of(const std::vector<calibration::Curve>& curves) {
  const law::LawParameters truth = subslip::testing::paper_law();
  calibration::FitProblem p;
  p.model = paper_contact(truth);
  p.curves = curves;
  for (std::size_t k = 0; k < law::kLawParameters.size(); ++k) {
    const auto& info = law::kLawParameters[k];
    const double value = info.value(truth);
    info.ref(p.model.law) = value * (k % 2 == 0 ? 1.3 : 0.7);
    double lower = value / 5.0, upper = value * 5.0;
    if (info.name == "r_hat") lower = 1.05;
    p.free.push_back({static_cast<int>(k), lower, upper, true});
  }
  return p;
}

const std::vector<double> kFiveSpeeds = {1, 10, 50, 100, 200};

TEST(Calibration, RecoversThePaperConstantsFromFiveSpeedsWithNoise) {
  const law::LawParameters truth = subslip::testing::paper_law();
  constexpr int kSeeds = 20;
  std::vector<int> inside(law::kLawParameters.size(), 0);
  for (unsigned seed = 1; seed <= kSeeds; ++seed) {
    const auto problem = problem_of(synthetic_curves(truth, kFiveSpeeds, {}, seed));
    const calibration::FitResult r = calibration::fit(problem);
    ASSERT_TRUE(r.converged) << "seed " << seed << ": " << r.termination;
    for (std::size_t j = 0; j < r.names.size(); ++j) {
      const double value = law::find_law_parameter(r.names[j])->value(truth);
      if (r.lower[j] <= value && value <= r.upper[j]) ++inside[j];
    }
  }
  // A 95 % interval holds the truth in 19 of 20 seeds on average; 17 is the demand.
  for (std::size_t j = 0; j < inside.size(); ++j)
    EXPECT_GE(inside[j], 17) << law::kLawParameters[j].name << ": inside in " << inside[j] << " of "
                             << kSeeds;
}

TEST(Calibration, OneSpeedLeavesTheRateConstantsUndetermined) {
  const auto problem = problem_of(synthetic_curves(subslip::testing::paper_law(), {10.0}, {}, 7));
  const calibration::FitResult r = calibration::fit(problem);
  auto warned = [&](const std::string& name) {
    for (const auto& w : r.warnings)
      if (w.rfind(name + " is not determined", 0) == 0) return true;
    return false;
  };
  EXPECT_TRUE(warned("eta_v"));
  EXPECT_TRUE(warned("n"));
  bool names_a_second_speed = false;
  for (const auto& w : r.warnings)
    names_a_second_speed |= w.find("a second sliding speed") != std::string::npos;
  EXPECT_TRUE(names_a_second_speed);
}

TEST(Calibration, AFitThatStopsEarlySaysWhere) {
  auto problem = problem_of(synthetic_curves(subslip::testing::paper_law(), kFiveSpeeds, {}, 3));
  problem.max_iterations = 1;
  const calibration::FitResult r = calibration::fit(problem);
  EXPECT_FALSE(r.converged);
  EXPECT_NE(r.termination.find("did not converge"), std::string::npos) << r.termination;
  EXPECT_NE(r.termination.find("stopped at mu_s = "), std::string::npos) << r.termination;
}

// ---- the fit file and its curves ---------------------------------------------------------------

struct FitFiles {
  std::filesystem::path dir = subslip::testing::scratch_dir("fit");
  void write(const std::string& name, const std::string& text) {
    std::ofstream(dir / name) << text;
  }
  std::filesystem::path fit(const std::string& free = "eta_v: [100, 5000]") {
    write("fit.yaml",
          "fit: contact\nunits: {stress: MPa, length: mm, time: min}\nlaw:\n"
          "  friction:   {mu_s: 0.097, mu_k: 0.085, kappa: 0.2, xi: 0.009}\n"
          "  subloading: {function: cot, u_tilde: 80}\n"
          "  overstress: {form: exponential, eta_v: 950, n: 16, r_hat: 1.8}\n"
          "contact: {alpha_n: 1.0e6, alpha_t: 1.0e6, normal_traction: 5.56}\n"
          "free:\n  " +
              free +
              "\n"
              "curves:\n  - {file: a.csv, speed: 1}\n");
    return dir / "fit.yaml";
  }
};

// The error of reading `csv` as the curve file: its file, line and key.
void expect_curve_error(const std::string& csv, int line, const std::string& key,
                        const std::string& part) {
  FitFiles files;
  files.write("a.csv", csv);
  try {
    io::read_fit_file(files.fit());
    FAIL() << "no error for:\n" << csv;
  } catch (const InputError& e) {
    EXPECT_EQ(e.file, (files.dir / "a.csv").string());
    EXPECT_EQ(e.line, line) << e.what();
    EXPECT_EQ(e.key, key) << e.what();
    EXPECT_NE(e.message.find(part), std::string::npos) << e.what();
  }
}

TEST(FitFile, ReadsCurvesInTheFitsUnits) {
  FitFiles files;
  files.write("a.csv", "# measured at 1 mm/min\nslip [um], ratio [-]\n10, 0.05\n20, 0.08\n");
  const io::FitFile f = io::read_fit_file(files.fit());
  ASSERT_EQ(f.problem.curves.size(), 1u);
  EXPECT_EQ(f.problem.curves[0].slip, (std::vector<double>{0.01, 0.02}));
  EXPECT_EQ(f.problem.curves[0].ratio, (std::vector<double>{0.05, 0.08}));
  EXPECT_EQ(f.problem.curves[0].speed, 1.0);
  ASSERT_EQ(f.problem.free.size(), 1u);
  EXPECT_EQ(law::kLawParameters[static_cast<std::size_t>(f.problem.free[0].index)].name, "eta_v");
  EXPECT_TRUE(f.problem.free[0].log_scale);
}

TEST(FitFile, NaNNamesItsLineAndColumn) {
  expect_curve_error("slip [mm], ratio [-]\n0.1, 0.05\n0.2, nan\n", 3, "ratio", "finite");
}

TEST(FitFile, UnsortedDistancesNameTheirLine) {
  expect_curve_error("slip [mm], ratio [-]\n0.1, 0.05\n0.3, 0.06\n0.2, 0.07\n", 4, "slip",
                     "increase");
}

TEST(FitFile, AMissingColumnIsNamed) {
  expect_curve_error("slip [mm], f_t [MPa]\n0.1, 0.05\n", 1, "ratio", "missing column");
}

TEST(FitFile, AUnitThatIsNoLengthIsRefused) {
  expect_curve_error("slip [min], ratio [-]\n0.1, 0.05\n", 1, "slip", "not a length");
}

TEST(FitFile, BoundsThatExcludeTheStartAreRefused) {
  FitFiles files;
  files.write("a.csv", "slip [mm], ratio [-]\n0.1, 0.05\n0.2, 0.06\n");
  try {
    io::read_fit_file(files.fit("eta_v: [1000, 5000]"));
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file, (files.dir / "fit.yaml").string());
    EXPECT_EQ(e.line, 9) << e.what();
    EXPECT_EQ(e.key, "free.eta_v") << e.what();
    EXPECT_NE(e.message.find("exclude the start eta_v = 950"), std::string::npos) << e.what();
  }
}

TEST(FitFile, IsNoSceneAndSaysWhichCommandReadsIt) {
  FitFiles files;
  files.write("a.csv", "slip [mm], ratio [-]\n0.1, 0.05\n0.2, 0.06\n");
  try {
    io::scene_kind(io::YamlDocument::from_file(files.fit()), {"contact", "crystal"});
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.line, 1) << e.what();
    EXPECT_EQ(e.key, "fit") << e.what();
    EXPECT_NE(e.message.find("subslip fit"), std::string::npos) << e.what();
  }
}

}  // namespace
