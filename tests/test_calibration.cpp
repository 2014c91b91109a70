// Fitting the friction law to curves: recovery of the paper's section-5 constants from synthetic
// curves with noise, the constants one speed leaves undetermined, and the fit file's errors.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "paper_law.hpp"
#include "scratch_dir.hpp"
#include "subslip/calibration/contact_fit.hpp"
#include "subslip/calibration/crystal_fit.hpp"
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

// ---- the crystal fit file and its curves -------------------------------------------------------

// The phase of inputs/fcc_single_crystal_tension_001.yaml (with `phase_extra`'s lines after
// tau0), `free` and `curve` on lines 12 and 14 (without them).
struct CrystalFitFiles {
  std::filesystem::path dir = subslip::testing::scratch_dir("crystal_fit");
  void write(const std::string& name, const std::string& text) {
    std::ofstream(dir / name) << text;
  }
  std::filesystem::path fit(
      const std::string& free = "mu_s: [1, 3]",
      const std::string& curve = "{file: a.csv, orientation: [90, 90, 0], strain_rate: 1.0e-3}",
      const std::string& phase_extra = "") {
    write("fit.yaml",
          "fit: crystal\nunits: {stress: MPa, time: s}\nphase:\n"
          "  families: [fcc_111_110]\n"
          "  elasticity: {type: cubic, C11: 168400, C12: 121400, C44: 75400}\n"
          "  tau0: 10\n" +
              phase_extra +
              "  law:\n"
              "    friction: {mu_s: 1.6, mu_k: 14.8, kappa: 20, xi: 0}\n"
              "    subloading: {function: cot, u_tilde: 200}\n"
              "    overstress: {form: exponential, eta_v: 1.0e-3, n: 16, r_hat: 1.6}\n"
              "free:\n  " +
              free + "\ncurves:\n  - " + curve + "\n");
    return dir / "fit.yaml";
  }
};

const std::string kTwoPoints = "strain [-], stress [MPa]\n0.002, 20\n0.004, 25\n";

// The error of reading `fit` (written by `write`): its file, line, key and a part of its message.
template <class Write>
void expect_crystal_error(Write write, const std::string& file, int line, const std::string& key,
                          const std::vector<std::string>& parts) {
  CrystalFitFiles files;
  const std::filesystem::path fit = write(files);
  try {
    io::read_fit_file(fit);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file, (files.dir / file).string());
    EXPECT_EQ(e.line, line) << e.what();
    EXPECT_EQ(e.key, key) << e.what();
    for (const auto& part : parts) EXPECT_NE(e.message.find(part), std::string::npos) << e.what();
  }
}

// The error of reading `csv` as the crystal curve file.
void expect_crystal_curve_error(const std::string& csv, int line, const std::string& key,
                                const std::string& part, double rate = 1.0e-3) {
  expect_crystal_error(
      [&](CrystalFitFiles& files) {
        files.write("a.csv", csv);
        std::ostringstream curve;
        curve << "{file: a.csv, orientation: [90, 90, 0], strain_rate: " << rate << "}";
        return files.fit("mu_s: [1, 3]", curve.str());
      },
      "a.csv", line, key, {part});
}

TEST(FitFile, ReadsACrystalFileInItsUnits) {
  CrystalFitFiles files;
  files.write("a.csv",
              "# tension\nstrain [-], force [N], stress [GPa]\n0.002, 1, 0.02\n"
              "0.004, 2, 0.025\n0.006, 3, 0.03\n");
  const io::FitFile f = io::read_fit_file(
      files.fit("mu_s: [1, 3]\n  xi: [0, 1]",
                "{file: a.csv, orientation: [90, 35.2643897, 225], strain_rate: 0.06 1/min, "
                "weight: 2}"));
  EXPECT_EQ(f.kind, io::FitKind::crystal);
  const calibration::CrystalFitProblem& p = f.crystal;
  ASSERT_EQ(p.curves.size(), 1u);
  EXPECT_EQ(p.curves[0].strain, (std::vector<double>{0.002, 0.004, 0.006}));
  ASSERT_EQ(p.curves[0].stress.size(), 3u);
  EXPECT_NEAR(p.curves[0].stress[1], 25.0, 1e-12);      // GPa to the file's MPa
  EXPECT_NEAR(p.curves[0].strain_rate, 1.0e-3, 1e-18);  // 0.06 /min in the file's 1/s
  EXPECT_EQ(p.curves[0].weight, 2.0);
  // [111] along sample x: g e_x, the crystal direction of sample x, is [111]/sqrt(3).
  const Eigen::Vector3d axis = p.curves[0].orientation.col(0);
  EXPECT_NEAR((axis - Eigen::Vector3d::Constant(1.0 / std::sqrt(3.0))).norm(), 0.0, 1e-8);
  ASSERT_EQ(f.euler_degrees.size(), 1u);
  EXPECT_EQ(f.euler_degrees[0], Eigen::Vector3d(90, 35.2643897, 225));
  ASSERT_EQ(p.free.size(), 2u);
  EXPECT_EQ(law::kLawParameters[static_cast<std::size_t>(p.free[0].index)].name, "mu_s");
  EXPECT_TRUE(p.free[0].log_scale);
  EXPECT_EQ(law::kLawParameters[static_cast<std::size_t>(p.free[1].index)].name, "xi");
  EXPECT_FALSE(p.free[1].log_scale);  // its bounds reach 0
  ASSERT_EQ(p.phase.family_settings.size(), 1u);
  EXPECT_EQ(p.phase.family_settings[0].tau0, 10.0);
  // Without phase.initial_mu the systems start from mu_s, and move with it.
  EXPECT_EQ(p.phase.family_settings[0].initial_mu, 0.0);
}

TEST(FitFile, TheShippedCrystalExampleReads) {
  const io::FitFile f = io::read_fit_file(std::filesystem::path(SUBSLIP_SOURCE_DIR) / "inputs" /
                                          "crystal_fit_three_orientations.yaml");
  EXPECT_EQ(f.kind, io::FitKind::crystal);
  ASSERT_EQ(f.crystal.curves.size(), 3u);
  // Each orientation puts its crystal direction along sample x: g e_x, the first column.
  const std::vector<Eigen::Vector3d> along_x = {{0, 0, 1}, {1, 1, 1}, {-1, 2, 3}};
  for (std::size_t c = 0; c < 3; ++c) {
    const auto& curve = f.crystal.curves[c];
    EXPECT_EQ(curve.strain.size(), 60u) << curve.name;
    EXPECT_EQ(curve.strain_rate, 1.0e-3) << curve.name;
    EXPECT_NEAR((curve.orientation.col(0) - along_x[c].normalized()).norm(), 0.0, 1e-8)
        << curve.name;
  }
  std::vector<std::string> names;
  for (const auto& p : f.crystal.free)
    names.emplace_back(law::kLawParameters[static_cast<std::size_t>(p.index)].name);
  EXPECT_EQ(names, (std::vector<std::string>{"mu_s", "mu_k", "kappa", "u_tilde"}));
}

TEST(FitFile, ACrystalFitsInitialMuWhereThePhaseGivesIt) {
  CrystalFitFiles files;
  files.write("a.csv", kTwoPoints);
  const io::FitFile f = io::read_fit_file(files.fit(
      "initial_mu: [1, 3]", "{file: a.csv, orientation: [90, 90, 0], strain_rate: 1.0e-3}",
      "  initial_mu: 1.7\n"));
  ASSERT_EQ(f.crystal.free.size(), 1u);
  EXPECT_EQ(f.crystal.free[0].index, crystal::kInitialMuColumn);
  EXPECT_EQ(f.crystal.free[0].lower, 1.0);
  EXPECT_EQ(f.crystal.free[0].upper, 3.0);
  EXPECT_EQ(f.crystal.phase.family_settings[0].initial_mu, 1.7);
}

TEST(FitFile, InitialMuIsNotFreeWhereTheSystemsStartFromMuS) {
  expect_crystal_error(
      [](CrystalFitFiles& files) {
        files.write("a.csv", kTwoPoints);
        return files.fit("initial_mu: [1, 3]");
      },
      "fit.yaml", 12, "free.initial_mu", {"gives no initial_mu", "free mu_s"});
}

TEST(FitFile, ACrystalPhaseWhoseFamiliesDifferIsRefused) {
  expect_crystal_error(
      [](CrystalFitFiles& files) {
        files.write("a.csv", kTwoPoints);
        files.write("fit.yaml",
                    "fit: crystal\nunits: {stress: MPa, time: s}\nphase:\n"
                    "  families: [bcc_110_111, bcc_112_111]\n"
                    "  elasticity: {type: cubic, C11: 230000, C12: 135000, C44: 117000}\n"
                    "  tau0: 10\n"
                    "  law:\n"
                    "    friction: {mu_s: 1.6, mu_k: 14.8, kappa: 20, xi: 0}\n"
                    "    subloading: {function: cot, u_tilde: 200}\n"
                    "    overstress: {form: exponential, eta_v: 1.0e-3, n: 16, r_hat: 1.6}\n"
                    "  per_family:\n"
                    "    bcc_112_111: {tau0: 12}\n"
                    "free:\n  mu_s: [1, 3]\n"
                    "curves:\n  - {file: a.csv, orientation: [0, 0, 0], strain_rate: 1.0e-3}\n");
        return files.dir / "fit.yaml";
      },
      "fit.yaml", 12, "phase.per_family", {"bcc_112_111 differs from bcc_110_111 in tau0"});
}

TEST(FitFile, ACrystalCurvesNaNNamesItsLineAndColumn) {
  expect_crystal_curve_error("strain [-], stress [MPa]\n0.002, 20\n0.004, nan\n", 3, "stress",
                             "finite");
}

TEST(FitFile, UnsortedStrainsNameTheirLine) {
  expect_crystal_curve_error("strain [-], stress [MPa]\n0.002, 20\n0.006, 25\n0.004, 27\n", 4,
                             "strain", "increase in magnitude");
}

TEST(FitFile, AMissingStressColumnIsNamed) {
  expect_crystal_curve_error("strain [-], sigma [MPa]\n0.002, 20\n", 1, "stress",
                             "missing column (write it as 'stress [MPa]')");
}

TEST(FitFile, AUnitThatIsNoStressIsRefused) {
  expect_crystal_curve_error("strain [-], stress [mm]\n0.002, 20\n", 1, "stress", "not a stress");
}

TEST(FitFile, AStrainOfTheWrongSignIsRefused) {
  expect_crystal_curve_error(kTwoPoints, 2, "strain", "the strain rate's sign (-0.001)", -1.0e-3);
}

TEST(FitFile, CrystalBoundsThatExcludeTheStartAreRefused) {
  expect_crystal_error(
      [](CrystalFitFiles& files) {
        files.write("a.csv", kTwoPoints);
        return files.fit("mu_s: [2, 5]");
      },
      "fit.yaml", 12, "free.mu_s", {"exclude the start mu_s = 1.6", "the phase's value"});
}

TEST(FitFile, Tau0IsNeverFreeAndTheMessageSaysWhy) {
  expect_crystal_error(
      [](CrystalFitFiles& files) {
        files.write("a.csv", kTwoPoints);
        return files.fit("tau0: [5, 20]");
      },
      "fit.yaml", 12, "free.tau0", {"tau0 cannot be fitted", "CRSS", "mu_s or initial_mu"});
}

}  // namespace
