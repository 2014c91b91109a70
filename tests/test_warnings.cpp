// Warnings for legal but suspicious scenes (src/io/scene_warnings.cpp): each one is raised by
// the setting it is about and by nothing else, names the file and the key, and lists the cases
// of a sweep it concerns. The forward-Euler stability estimate is checked against runs just
// below and well above it.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "scratch_dir.hpp"
#include "shell_command.hpp"
#include "subslip/history/contact_history.hpp"
#include "subslip/io/contact_scene.hpp"
#include "subslip/io/crystal_scene.hpp"
#include "subslip/io/scene_warnings.hpp"

using namespace subslip;
using namespace subslip::io;

namespace {

struct CrystalScene_ {
  std::string units = "{stress: MPa, time: s}";
  std::string elasticity = "{type: cubic, C11: 168400, C12: 121400, C44: 75400}";
  std::string rate = "1.0e-3";
  std::string grains = "4";
  std::string tau0 = "10.0";
  std::string overstress = "{form: exponential, eta_v: 1.0e-3, n: 16, r_hat: 1.6}";
  std::string duration = "10";
  std::string increments = "100";
  std::string integrator = "implicit";
  std::string output = "";
  std::string sweep = "";
  std::string text() const {
    return R"(scene: crystal
units: )" + units +
           R"(
phase:
  families: [fcc_111_110]
  elasticity: )" +
           elasticity + R"(
  tau0: )" +
           tau0 + R"(
  law:
    friction: {mu_s: 1.6, mu_k: 14.8, kappa: 20.0, xi: 0.0}
    subloading: {function: cot, u_tilde: 200}
    overstress: )" +
           overstress + R"(
orientations:
  random: {count: )" +
           grains + R"(, seed: 1}
loading:
  - L: [[x, 0, 0], [0, x, 0], [0, 0, )" +
           rate + R"(]]
    stress: [[0, x, x], [x, 0, x], [x, x, x]]
    duration: )" +
           duration + R"(
    increments: )" +
           increments + R"(
integrator: {method: )" +
           integrator + "}\n" + output + sweep;
  }
  std::vector<std::string> warnings(bool checkpoints = true) const {
    return crystal_scene_warnings(parse_crystal_scene(YamlDocument::from_string(text(), "w.yaml")),
                                  checkpoints);
  }
};

std::string contact_text(const std::string& alpha, const std::string& method,
                         const std::string& distance,
                         const std::string& overstress =
                             "{form: exponential, eta_v: 950, n: "
                             "16, r_hat: 1.8}") {
  return R"(scene: contact
units: {stress: MPa, length: mm, time: min}
law:
  friction: {mu_s: 0.097, mu_k: 0.085, kappa: 0.2, xi: 0.009}
  subloading: {function: cot, u_tilde: 80}
  overstress: )" +
         overstress + R"(
contact: {alpha_n: )" +
         alpha + ", alpha_t: " + alpha + R"(, normal_traction: 5.56}
integrator: {method: )" +
         method + R"(}
loading:
  - slide: {speed: 1, direction: [1, 0], distance: )" +
         distance + R"(}
    increments: 2000
)";
}

ContactScene contact_scene(const std::string& text) {
  return parse_contact_scene(YamlDocument::from_string(text, "c.yaml"));
}

// The one warning expected, with the pieces it must contain.
void expect_one(const std::vector<std::string>& w, std::initializer_list<const char*> parts) {
  ASSERT_EQ(w.size(), 1u) << (w.empty() ? "" : w.front());
  for (const char* p : parts) EXPECT_NE(w.front().find(p), std::string::npos) << w.front();
}

std::string number(double x) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", x);
  return buf;
}

}  // namespace

TEST(Warnings, AnOrdinaryCrystalSceneHasNone) {
  EXPECT_TRUE(CrystalScene_{}.warnings().empty());
  EXPECT_TRUE(CrystalScene_{}.warnings(false).empty());  // short: no checkpoints needed
  EXPECT_TRUE(
      contact_scene_warnings(contact_scene(contact_text("1.0e6", "implicit", "20"))).empty());
}

TEST(Warnings, LargeStrainIncrements) {
  CrystalScene_ s;
  s.increments = std::string("2");  // 5 s at 1e-3 /s: 5e-3 per step, still fine
  EXPECT_TRUE(s.warnings().empty());
  s.duration = std::string("40");  // 2e-2 per step
  expect_one(s.warnings(), {"w.yaml: loading[0]: strain increment per step up to 0.02"});
  // Adaptive stepping chooses its own steps.
  s.integrator = std::string("implicit, tolerance: 1.0e-3");
  EXPECT_TRUE(s.warnings().empty());
}

TEST(Warnings, ForwardEulerBeyondItsStabilityEstimate) {
  CrystalScene_ s;
  s.integrator = std::string("forward_euler");
  expect_one(s.warnings(), {"loading[0]: forward_euler", "stability estimate"});
  s.integrator = std::string("implicit");
  EXPECT_TRUE(s.warnings().empty());
  const auto w =
      contact_scene_warnings(contact_scene(contact_text("1.0e6", "forward_euler", "20")));
  expect_one(w, {"c.yaml: loading[0]: forward_euler", "method implicit"});
}

// The estimate 2 / (alpha_t / (f_n mu) dphi/dr) at steady sliding: it matches docs/model.md's
// measured limit (stable below ~5e-8 min, not at 5e-7) for the paper's contact, and with a softer
// contact forward Euler runs cleanly at half the estimate and needs cutbacks at four times it.
TEST(Warnings, ForwardEulerEstimateSeparatesStableFromUnstable) {
  law::LawParameters p;
  p.friction = {0.097, 0.085, 0.2, 0.009};
  p.subloading.u_tilde = 80.0;
  p.overstress = {law::OverstressForm::exponential, 950.0, 16.0, 1.8};
  const double paper = forward_euler_step_limit(p, 1.0, 1.0e6, 5.56);
  EXPECT_GT(paper, 2.5e-8);
  EXPECT_LT(paper, 5e-7);
  const double limit = forward_euler_step_limit(p, 1.0, 1.0e3, 5.56);
  EXPECT_NEAR(limit / paper, 1000.0, 1e-6);  // inversely proportional to the stiffness

  auto run = [&](double steps_per_limit, const std::string& method, double& peak) {
    // 2000 increments of dt = limit / steps_per_limit at 1 mm/min (through the peak).
    const std::string distance = number(2000.0 * limit / steps_per_limit);
    const ContactScene scene = contact_scene(contact_text("1.0e3", method, distance));
    const ContactCase& c = scene.cases.at(0);
    peak = 0.0;
    const auto stats = history::run_history(
        c.model, c.segments, c.integrator,
        [&](const contact::ContactState& s, int) { peak = std::max(peak, s.traction_ratio()); });
    return std::pair{stats.cutbacks, contact_scene_warnings(scene).size()};
  };
  double peak_fe = 0.0, peak_implicit = 0.0;
  const auto stable = run(2.0, "forward_euler", peak_fe);  // dt = limit / 2
  run(2.0, "implicit", peak_implicit);
  EXPECT_EQ(stable.first, 0);
  EXPECT_EQ(stable.second, 0u);  // no warning
  EXPECT_NEAR(peak_fe, peak_implicit, 1e-3 * peak_implicit);
  double peak_unstable = 0.0;
  const auto unstable = run(0.25, "forward_euler", peak_unstable);  // dt = 4 limit
  EXPECT_GT(unstable.first, 0);
  EXPECT_EQ(unstable.second, 1u);
}

TEST(Warnings, HugePerGrainOutput) {
  CrystalScene_ s;
  s.grains = std::string("10000");
  s.increments = std::string("400");
  s.output =
      std::string("output:\n  grains: [stress, orientation, slip, slip_rate, crss, r, r_s]\n");
  // 8 B x (6 + 4 + 5 x 12) values x 10000 grains x 401 rows = 2.2 GB.
  expect_one(s.warnings(), {"output.grains: about 2.25 GB"});
  s.output = std::string("output:\n  grains: [stress]\n");
  EXPECT_TRUE(s.warnings().empty());
}

TEST(Warnings, ExtremeLawConstants) {
  CrystalScene_ s;
  s.overstress = std::string("{form: power, eta_v: 1.0e-3, n: 100, r_hat: 1.6}");
  expect_one(s.warnings(), {"phase.law.overstress.n: n = 100 with the power form"});
  s.overstress = std::string("{form: power, eta_v: 1.0e-3, n: 64, r_hat: 1.6}");
  EXPECT_TRUE(s.warnings().empty());
  s.overstress =
      std::string("{form: exponential, eta_v: 1.0e-3, n: 100, r_hat: 1.6}");  // n is fine there
  EXPECT_TRUE(s.warnings().empty());
  s.overstress = std::string("{form: exponential, eta_v: 1.0e-3, n: 16, r_hat: 1.01}");
  expect_one(s.warnings(), {"phase.law.overstress.r_hat: r_hat = 1.01"});
  const auto w = contact_scene_warnings(contact_scene(contact_text(
      "1.0e6", "implicit", "20", "{form: exponential, eta_v: 950, n: 16, r_hat: 1.005}")));
  expect_one(w, {"c.yaml: law.overstress.r_hat"});
}

TEST(Warnings, StiffnessFarAboveTau0) {
  CrystalScene_ s;
  s.tau0 = std::string("1.0");    // C11 / tau0 = 1.7e5
  s.duration = std::string("1");  // keep the strain increments small
  expect_one(s.warnings(), {"elastic stiffness / tau0 = 1.68e+05"});
}

TEST(Warnings, LongRunWithoutCheckpoints) {
  CrystalScene_ s;
  s.grains = std::string("20000");
  s.increments = std::string("30000");
  s.duration = std::string("30");
  EXPECT_TRUE(s.warnings(true).empty());
  expect_one(s.warnings(false), {"checkpoints are off for a long run (6e+08 grain-steps"});
}

TEST(Warnings, SweepCasesAreListedOnce) {
  CrystalScene_ s;
  s.overstress = std::string("{form: exponential, eta_v: 1.0e-3, n: 16, r_hat: 1.6}");
  s.sweep = std::string("sweep:\n  \"phase.law.overstress.r_hat\": [1.005, 1.6, 1.01]\n");
  auto w = s.warnings();
  ASSERT_EQ(w.size(), 2u);  // two different r_hat values: two messages
  EXPECT_NE(w[0].find("(case r_hat=1.005)"), std::string::npos) << w[0];
  EXPECT_NE(w[1].find("(case r_hat=1.01)"), std::string::npos) << w[1];
  s.sweep = std::string("sweep:\n  \"phase.tau0\": [10, 12]\n");
  s.duration = std::string("40");
  s.increments = std::string("2");
  w = s.warnings();
  ASSERT_EQ(w.size(), 1u);  // every case has it: a value no swept value touches names no case
  EXPECT_EQ(w[0].find("(case"), std::string::npos) << w[0];
  EXPECT_EQ(w[0].find("every case"), std::string::npos) << w[0];
  EXPECT_NE(w[0].find("loading[0]"), std::string::npos) << w[0];
}

// ---------------------------------------------------------------- magnitudes in the wrong unit

// Copper's elastic constants in GPa written in an MPa scene: C11 = 168.4 MPa, a flow stress of a
// few MPa, and no error (the numbers are legal): one warning at the line of C11, the largest
// constant, naming the unit the number fits.
TEST(MagnitudeWarnings, ElasticConstantsInGpaInAnMpaScene) {
  CrystalScene_ s;
  s.elasticity = "{type: cubic, C11: 168.4, C12: 121.4, C44: 75.4}";
  expect_one(s.warnings(), {"w.yaml:5: phase.elasticity.C11: 168.4 MPa (0.1684 GPa) is below the "
                            "elastic constants of crystals (1 to 2000 GPa)",
                            "write '168.4 GPa'"});
  // The same constants written with their unit: no warning.
  s.elasticity = "{type: cubic, C11: 168.4 GPa, C12: 121.4 GPa, C44: 75.4 GPa}";
  EXPECT_TRUE(s.warnings().empty());
  // A unit written, but the wrong one: the number is checked, no unit is suggested.
  s.elasticity = "{type: cubic, C11: 168.4 MPa, C12: 121.4 MPa, C44: 75.4 MPa}";
  expect_one(s.warnings(), {"w.yaml:5: phase.elasticity.C11: 168.4 MPa",
                            "check the number and "
                            "its unit"});
  // Isotropic: E is checked like the cubic constants.
  s.elasticity = "{type: isotropic, E: 200, nu: 0.3}";
  expect_one(s.warnings(), {"w.yaml:5: phase.elasticity.E: 200 MPa", "write '200 GPa'"});
}

// MPa values in a GPa scene: every constant above the stiffest crystal, and tau0 = 10 GPa.
TEST(MagnitudeWarnings, MpaValuesInAGpaScene) {
  CrystalScene_ s;
  s.units = "{stress: GPa, time: s}";
  const auto w = s.warnings();
  ASSERT_EQ(w.size(), 4u);
  EXPECT_NE(w[0].find("w.yaml:5: phase.elasticity.C11: 1.684e+05 GPa is above"), std::string::npos)
      << w[0];
  EXPECT_NE(w[0].find("write '168400 MPa'"), std::string::npos) << w[0];
  EXPECT_NE(w[1].find("w.yaml:5: phase.elasticity.C12: 1.214e+05 GPa"), std::string::npos) << w[1];
  EXPECT_NE(w[2].find("w.yaml:5: phase.elasticity.C44: 7.54e+04 GPa"), std::string::npos) << w[2];
  EXPECT_NE(w[3].find("w.yaml:6: phase.tau0: 10 GPa (1e+04 MPa) is above the reference stresses"),
            std::string::npos)
      << w[3];
  EXPECT_NE(w[3].find("write '10 MPa'"), std::string::npos) << w[3];
  // Written in GPa, the same material warns about nothing.
  s.elasticity = "{type: cubic, C11: 168.4, C12: 121.4, C44: 75.4}";
  s.tau0 = "0.01";
  EXPECT_TRUE(s.warnings().empty());
}

// tau0 below 10 kPa (Pa written where MPa was meant); strain rates and durations far outside
// any test.
TEST(MagnitudeWarnings, Tau0StrainRateAndDuration) {
  CrystalScene_ s;
  s.units = "{stress: Pa, time: s}";
  s.elasticity = "{type: cubic, C11: 168.4e9, C12: 121.4e9, C44: 75.4e9}";
  // (with the stiffness / tau0 warning)
  auto pa = s.warnings();
  ASSERT_EQ(pa.size(), 2u);
  EXPECT_NE(pa[0].find("w.yaml:6: phase.tau0: 10 Pa (1e-05 MPa) is below"), std::string::npos)
      << pa[0];
  EXPECT_NE(pa[0].find("write '10 MPa'"), std::string::npos) << pa[0];
  s.tau0 = "1.0e7";
  EXPECT_TRUE(s.warnings().empty());
  s.rate = "1.0e7";  // 1e7 /s
  s.duration = "1.0e-9";
  s.increments = "1";
  const auto w = s.warnings();
  ASSERT_GE(w.size(), 1u);
  EXPECT_NE(w[0].find("w.yaml:14: loading[0].L[2][2]: 1e+07 1/s is above the strain rates"),
            std::string::npos)
      << w[0];
  s.rate = "1.0e-3";
  s.duration = "1.0e10";  // 300 years
  s.increments = "1000000";
  const auto d = s.warnings();
  ASSERT_GE(d.size(), 1u);
  EXPECT_NE(d[0].find("w.yaml:16: loading[0].duration: 1e+10 s is above the durations"),
            std::string::npos)
      << d[0];
}

// A speed in mm/min written in a scene in m and s: 200 m/s.
TEST(MagnitudeWarnings, SlidingSpeedAndHold) {
  std::string text = contact_text("1.0e6", "implicit", "0.02");
  text.replace(text.find("length: mm, time: min"), 21, "length: m, time: s");
  text.replace(text.find("speed: 1,"), 9, "speed: 200,");
  expect_one(contact_scene_warnings(contact_scene(text)),
             {"c.yaml:10: loading[0].slide.speed: 200 m/s is above the sliding speeds of friction "
              "tests (1e-12 to 100 m/s): check the number and its unit"});
  // A 1e8 min hold (190 years) after a slide at 1 mm/min.
  std::string hold = contact_text("1.0e6", "implicit", "0.02") +
                     "  - hold: {duration: 1.0e8}\n    increments: 10\n";
  expect_one(contact_scene_warnings(contact_scene(hold)),
             {"c.yaml:12: loading[1].hold.duration: 1e+08 min (6e+09 s) is above the durations"});
  hold.replace(hold.find("duration: 1.0e8"), 15, "duration: 60");
  EXPECT_TRUE(contact_scene_warnings(contact_scene(hold)).empty());
}

// A swept value is checked in its case, at its line in the sweep block.
TEST(MagnitudeWarnings, SweptValuesNameTheirCase) {
  CrystalScene_ s;
  s.sweep = "sweep:\n  \"phase.tau0\": [10, 1.0e4]\n";
  s.duration = "1";
  const auto w = s.warnings();
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NE(w[0].find("w.yaml:20: phase.tau0: 1e+04 MPa is above"), std::string::npos) << w[0];
  EXPECT_NE(w[0].find("write '10000 kPa'"), std::string::npos) << w[0];
  EXPECT_NE(w[0].find("(case tau0=1.0e4)"), std::string::npos) << w[0];
}

// The plausible ranges hold every shipped scene: none of them warns about a magnitude.
TEST(MagnitudeWarnings, NoShippedSceneLooksWrittenInAnotherUnit) {
  namespace fs = std::filesystem;
  int scenes = 0;
  for (const auto& entry :
       fs::recursive_directory_iterator(fs::path(SUBSLIP_SOURCE_DIR) / "inputs")) {
    if (entry.path().extension() != ".yaml") continue;
    SCOPED_TRACE(entry.path().string());
    const YamlDocument document = YamlDocument::from_file(entry.path());
    if (document.root().has("fit")) continue;  // a fit file (`subslip fit`), not a scene
    const std::vector<std::string> w =
        scene_kind(document, {"contact", "crystal"}) == "contact"
            ? contact_scene_warnings(parse_contact_scene(document))
            : crystal_scene_warnings(parse_crystal_scene(document), true);
    for (const std::string& line : w) {
      EXPECT_EQ(line.find(" is below the "), std::string::npos) << line;
      EXPECT_EQ(line.find(" is above the "), std::string::npos) << line;
    }
    ++scenes;
  }
  EXPECT_GT(scenes, 30);
}

// `subslip run` prints the warning before the run, on standard error, at the file and line of
// the value, and the run goes on (warnings are not errors): the flow stress of copper with C11
// = 168.4 MPa is a few MPa instead of ~65.
TEST(MagnitudeWarnings, TheCommandLinePrintsThemWithTheLineAndRuns) {
  namespace fs = std::filesystem;
  const fs::path dir = subslip::testing::scratch_dir("warnings");
  CrystalScene_ s;
  s.elasticity = "{type: cubic, C11: 168.4, C12: 121.4, C44: 75.4}";
  const fs::path scene = dir / "gpa_in_mpa.yaml";
  std::ofstream(scene) << s.text();
  const auto run =
      subslip::testing::run_command("'" + std::string(SUBSLIP_BINARY) + "' run '" + scene.string() +
                                    "' -o '" + (dir / "out.h5").string() + "' 2>&1 >/dev/null");
  EXPECT_EQ(run.code, 0) << run.out;
  EXPECT_EQ(run.out.rfind("warning: " + scene.string() + ":5: phase.elasticity.C11: 168.4 MPa", 0),
            0u)
      << run.out;
  EXPECT_TRUE(fs::exists(dir / "out.h5"));
  fs::remove_all(dir);
}
