// Crystal scene files: the parser, its checks (a table of broken scenes in
// tests/data/crystal_scenes), sweeps into the loading matrices, and every shipped crystal scene.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <ostream>
#include <string>
#include <vector>

#include "subslip/crystal/free_components.hpp"
#include "subslip/crystal/phase_builder.hpp"
#include "subslip/crystal/texture.hpp"
#include "subslip/driver/orientation_sharing.hpp"
#include "subslip/io/crystal_scene.hpp"
#include "subslip/io/input_error.hpp"
#include "subslip/io/scene_common.hpp"
#include "subslip/io/yaml_checked.hpp"

namespace fs = std::filesystem;
using namespace subslip;
using namespace subslip::io;

namespace {

const fs::path kSource = SUBSLIP_SOURCE_DIR;

// A valid two-grain scene; tests append lines or substitute text.
const std::string kTiny = R"(scene: crystal
title: "tiny"
units: {stress: MPa, time: s, length: mm}
phase:
  families: [fcc_111_110]
  elasticity: {type: cubic, C11: 168400, C12: 121400, C44: 75400}
  tau0: 10.0
  law:
    friction: {mu_s: 1.0, mu_k: 3.0, kappa: 5.0, xi: 0.0}
    subloading: {function: cot, u_tilde: 200}
    overstress: {form: exponential, eta_v: 1.0e-3, n: 16, r_hat: 1.6}
orientations:
  euler_deg: [[0, 0, 0], [45, 30, 10, 3]]
loading:
  - L: [[x, 0, 0], [0, x, 0], [0, 0, 1.0e-3]]
    stress: [[0, x, x], [x, 0, x], [x, x, x]]
    duration: 1
    increments: 3
)";

CrystalScene parse(const std::string& text) {
  return parse_crystal_scene(YamlDocument::from_string(text, "test.yaml"));
}

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

std::vector<fs::path> shipped_crystal_scenes() {
  std::vector<fs::path> out;
  for (const auto& entry : fs::directory_iterator(kSource / "inputs")) {
    if (entry.path().extension() != ".yaml") continue;
    if (YamlDocument::from_file(entry.path()).root().has("fit")) continue;  // a fit file
    if (scene_kind(YamlDocument::from_file(entry.path()), {"contact", "crystal"}) == "crystal")
      out.push_back(entry.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace

// ---------------------------------------------------------------- parsing

TEST(CrystalScene, TinySceneResolvesMixedControlAndDefaults) {
  const CrystalScene scene = parse(kTiny);
  EXPECT_EQ(scene.title, "tiny");
  EXPECT_EQ(scene.units.stress, "MPa");
  EXPECT_EQ(scene.units.time, "s");
  ASSERT_EQ(scene.cases.size(), 1u);
  const CrystalCase& c = scene.cases[0];
  EXPECT_EQ(c.name, "base");
  ASSERT_EQ(c.phase.families.size(), 1u);
  ASSERT_EQ(c.phase.family_settings.size(), 1u);
  EXPECT_DOUBLE_EQ(c.phase.family_settings[0].tau0, 10.0);
  EXPECT_DOUBLE_EQ(c.phase.family_settings[0].initial_mu, 1.0);  // default: mu_s
  EXPECT_DOUBLE_EQ(c.phase.stiffness(0, 0), 168400.0);
  EXPECT_DOUBLE_EQ(c.phase.stiffness(3, 3), 2.0 * 75400.0);  // Mandel
  EXPECT_EQ(c.phase.kinematics, crystal::Kinematics::finite_rotation);
  EXPECT_EQ(c.phase.latent.kind, crystal::LatentHardening::Kind::none);
  ASSERT_EQ(c.orientations.size(), 2u);
  EXPECT_DOUBLE_EQ(c.orientations[1].weight, 3.0);
  EXPECT_EQ(c.orientation_source.kind, "euler_deg");
  ASSERT_EQ(c.segments.size(), 1u);
  const crystal::LoadSegment& s = c.segments[0];
  EXPECT_TRUE(s.free(0, 0));
  EXPECT_TRUE(s.free(1, 1));
  EXPECT_FALSE(s.free(2, 2));
  EXPECT_FALSE(s.free(0, 1));
  EXPECT_DOUBLE_EQ(s.velocity_gradient(2, 2), 1.0e-3);
  EXPECT_TRUE(s.stress_target.isZero());
  EXPECT_DOUBLE_EQ(s.duration, 1.0);
  EXPECT_EQ(s.increments, 3);
  EXPECT_EQ(c.options.method, crystal::CrystalMethod::implicit);
  EXPECT_EQ(c.output.macro.size(), kAllMacroFields.size());
  EXPECT_TRUE(c.output.grains.empty());
  EXPECT_EQ(crystal_output_count(c.segments), 4u);
}

TEST(CrystalScene, MatrixRowsAreIAndColumnsJ) {
  const CrystalScene scene =
      parse(replaced(replaced(kTiny, "[[x, 0, 0], [0, x, 0], [0, 0, 1.0e-3]]",
                              "[[x, 2.0, 0], [0, x, 0], [0, 0, 1.0e-3]]"),
                     "[[0, x, x], [x, 0, x], [x, x, x]]", "[[5.0, x, x], [x, 0, x], [x, x, x]]"));
  const crystal::LoadSegment& s = scene.cases[0].segments[0];
  EXPECT_DOUBLE_EQ(s.velocity_gradient(0, 1), 2.0);
  EXPECT_DOUBLE_EQ(s.velocity_gradient(1, 0), 0.0);
  EXPECT_DOUBLE_EQ(s.stress_target(0, 0), 5.0);
}

// A DAMASK-style load case: dot_F and P, each component once; under P a free pair is two
// unknowns (P is not symmetric), and `strain` integrates the largest prescribed |dot_F_ij|.
TEST(CrystalScene, DotFAndFirstPiolaTargetsAreReadComponentByComponent) {
  const std::string text =
      replaced(replaced(kTiny, "  - L: [[x, 0, 0], [0, x, 0], [0, 0, 1.0e-3]]",
                        "  - dot_F: [[x, x, 0], [x, x, 0], [0, 0, 2.0e-3 1/min]]"),
               "    stress: [[0, x, x], [x, 0, x], [x, x, x]]\n    duration: 1",
               "    P: [[0, 0.5, x], [0.25, 0 GPa, x], [x, x, x]]\n    strain: 0.1");
  const auto scene = parse(text);
  const crystal::LoadSegment& seg = scene.cases[0].segments[0];
  EXPECT_EQ(seg.rate_control, crystal::RateControl::deformation_rate);
  EXPECT_EQ(seg.stress_measure, crystal::StressMeasure::first_piola);
  EXPECT_EQ(seg.velocity_gradient, crystal::Mat3::Zero());
  EXPECT_DOUBLE_EQ(seg.deformation_rate(2, 2), 2.0e-3 / 60.0);
  EXPECT_TRUE(seg.free(0, 1) && seg.free(1, 0) && !seg.free(2, 2));
  EXPECT_EQ(seg.stress_target(0, 1), 0.5);
  EXPECT_EQ(seg.stress_target(1, 0), 0.25);
  EXPECT_DOUBLE_EQ(seg.duration, 0.1 / (2.0e-3 / 60.0));
  const auto fc = crystal::free_components(seg);
  ASSERT_EQ(fc.size(), 4u);
  for (const auto& c : fc) EXPECT_FALSE(c.symmetric_pair);
}

TEST(CrystalScene, StrainGivesTheDurationFromTheLargestPrescribedRate) {
  const CrystalScene scene = parse(replaced(kTiny, "duration: 1", "strain: 0.05"));
  EXPECT_DOUBLE_EQ(scene.cases[0].segments[0].duration, 50.0);
}

TEST(CrystalScene, PerFamilyOverridesMergeOverThePhaseLaw) {
  const std::string text =
      replaced(replaced(kTiny, "  families: [fcc_111_110]\n",
                        "  families: [hcp_basal_a, hcp_prismatic_a]\n  c_over_a: 1.624\n"),
               "  elasticity: {type: cubic, C11: 168400, C12: 121400, C44: 75400}\n",
               "  elasticity: {type: hexagonal, C11: 59500, C12: 26100, C13: 21800, C33: 65600, "
               "C44: 16300}\n  per_family:\n    hcp_prismatic_a:\n      tau0: 20.0\n"
               "      law: {friction: {mu_s: 2.0}, overstress: {n: 8}}\n"
               "  latent: {coplanar: 1.0, non_coplanar: 1.4}\n  kinematics: small_strain\n");
  const CrystalCase c = parse(text).cases[0];
  ASSERT_EQ(c.phase.family_settings.size(), 2u);
  const auto& basal = c.phase.family_settings[0];
  const auto& prismatic = c.phase.family_settings[1];
  EXPECT_DOUBLE_EQ(c.phase.c_over_a, 1.624);
  EXPECT_DOUBLE_EQ(basal.tau0, 10.0);
  EXPECT_DOUBLE_EQ(prismatic.tau0, 20.0);
  EXPECT_DOUBLE_EQ(prismatic.law.friction.mu_s, 2.0);
  EXPECT_DOUBLE_EQ(prismatic.law.friction.mu_k, 3.0);  // inherited
  EXPECT_DOUBLE_EQ(prismatic.law.overstress.n, 8.0);
  EXPECT_DOUBLE_EQ(prismatic.law.overstress.r_hat, 1.6);  // inherited
  EXPECT_DOUBLE_EQ(prismatic.initial_mu, 2.0);            // its own mu_s
  EXPECT_DOUBLE_EQ(basal.initial_mu, 1.0);
  EXPECT_EQ(c.phase.latent.kind, crystal::LatentHardening::Kind::coplanar);
  EXPECT_DOUBLE_EQ(c.phase.latent.non_coplanar, 1.4);
  EXPECT_EQ(c.phase.kinematics, crystal::Kinematics::small_strain);
  EXPECT_EQ(c.elasticity_type, "hexagonal");
}

TEST(CrystalScene, GeneratedOrientations) {
  const auto random = parse(
      replaced(kTiny, "euler_deg: [[0, 0, 0], [45, 30, 10, 3]]", "random: {count: 7, seed: 3}"));
  EXPECT_EQ(random.cases[0].orientations.size(), 7u);
  const auto goss = parse(replaced(kTiny, "euler_deg: [[0, 0, 0], [45, 30, 10, 3]]",
                                   "component: {name: goss, count: 5, spread_deg: 0, seed: 1}"));
  ASSERT_EQ(goss.cases[0].orientations.size(), 5u);
  const auto ideal = crystal::ideal_orientation(crystal::TextureComponent::goss);
  EXPECT_LT((goss.cases[0].orientations[4].g - ideal.g).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(CrystalScene, IsotropicElasticityFromGAndNu) {
  const auto scene = parse(replaced(kTiny, "{type: cubic, C11: 168400, C12: 121400, C44: 75400}",
                                    "{type: isotropic, G: 1.0e6, nu: 0.3}"));
  EXPECT_NEAR(scene.cases[0].phase.stiffness(3, 3), 2.0e6, 1e-6);  // Mandel: 2 G
}

TEST(CrystalScene, SweepReachesIntoTheLoadingMatrix) {
  const auto scene = parse(kTiny + "sweep:\n  \"loading[0].L[2][2]\": [1.0e-3, 2.0e-3]\n");
  ASSERT_EQ(scene.cases.size(), 2u);
  EXPECT_EQ(scene.cases[0].name, "L[2][2]=1.0e-3");
  EXPECT_EQ(scene.cases[1].name, "L[2][2]=2.0e-3");
  EXPECT_DOUBLE_EQ(scene.cases[1].segments[0].velocity_gradient(2, 2), 2.0e-3);
}

TEST(CrystalScene, SweptValueErrorsNameTheCase) {
  try {
    parse(kTiny + "sweep:\n  \"phase.tau0\": [10, -1]\n");
    FAIL() << "accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.key, "phase.tau0");
    EXPECT_EQ(e.line, 20);
    EXPECT_NE(std::string(e.what()).find("tau0=-1"), std::string::npos) << e.what();
  }
}

// ---------------------------------------------------------------- broken scenes

namespace {

struct Broken {
  const char* file;
  int line;  // 0: no line
  const char* key;
  const char* fragment;         // part of the message
  const char* error_file = "";  // when the error is in another file of the directory
};

void PrintTo(const Broken& b, std::ostream* os) {
  *os << b.file;
}

class BrokenCrystalScene : public ::testing::TestWithParam<Broken> {};

const fs::path kBrokenDir = kSource / "tests/data/crystal_scenes";

}  // namespace

TEST_P(BrokenCrystalScene, RaisesInputErrorAtFileLineKey) {
  const Broken& b = GetParam();
  const fs::path path = kBrokenDir / b.file;
  ASSERT_TRUE(fs::exists(path)) << path;
  const std::string file = *b.error_file ? (kBrokenDir / b.error_file).string() : path.string();
  try {
    load_crystal_scene(path);
    FAIL() << b.file << " was accepted";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(e.file, file);
    EXPECT_EQ(e.line, b.line) << what;
    EXPECT_EQ(e.key, b.key) << what;
    const std::string where = file + (b.line > 0 ? ":" + std::to_string(b.line) : "") + ": " +
                              (*b.key ? std::string(b.key) + ": " : "");
    EXPECT_EQ(what.rfind(where, 0), 0u) << what;
    EXPECT_NE(what.find(b.fragment), std::string::npos) << what;
  }
}

INSTANTIATE_TEST_SUITE_P(
    Table, BrokenCrystalScene,
    ::testing::Values(
        Broken{"unknown_key.yaml", 7, "phase.tau_0", "did you mean 'tau0'?"},
        Broken{"bad_family.yaml", 5, "phase.families[0]", "did you mean 'fcc_111_110'?"},
        Broken{"mixed_lattices.yaml", 5, "phase.families[1]", "one lattice"},
        Broken{"both_given.yaml", 16, "loading[0].stress[2][2]",
               "component 33: L_33 and stress_33 are both given"},
        Broken{"both_free.yaml", 16, "loading[0].stress[2][2]",
               "component 33: L_33 and stress_33 are both x"},
        Broken{"asymmetric_pair.yaml", 16, "loading[0].stress[1][0]",
               "stress_21 must equal stress_12"},
        Broken{"free_without_stress.yaml", 15, "loading[0].L[0][0]", "no 'stress'"},
        Broken{"bad_matrix_shape.yaml", 15, "loading[0].L", "3 rows of 3 entries"},
        Broken{"missing_orientations.yaml", 0, "orientations", "missing required key"},
        Broken{"bad_orientation_path.yaml", 13, "orientations.file", "no_such_orientations.txt"},
        Broken{"bad_orientation_file.yaml", 3, "Phi",
               "orientation file given at " SUBSLIP_SOURCE_DIR
               "/tests/data/crystal_scenes/bad_orientation_file.yaml:13: orientations.file",
               "bad_orientations.txt"},
        Broken{"non_pd_elasticity.yaml", 6, "phase.elasticity", "not positive definite"},
        Broken{"forward_euler_rate_independent.yaml", 19, "integrator.method", "rate_independent"},
        Broken{"unknown_predictor.yaml", 19, "integrator.predictor", "trend"},
        Broken{"hcp_without_c_over_a.yaml", 5, "phase.c_over_a", "missing required key"},
        Broken{"c_over_a_without_hcp.yaml", 8, "phase.c_over_a", "hcp slip families only"},
        Broken{"unknown_per_family.yaml", 9, "phase.per_family.fcc_111_110.mu_s",
               "unknown key 'mu_s'"},
        Broken{"per_family_not_listed.yaml", 9, "phase.per_family.bcc_110_111", "fcc_111_110"},
        Broken{"custom_not_in_plane.yaml", 5, "phase.slip_systems[0]", "slip plane"},
        Broken{"bad_sweep_L_index.yaml", 20, "sweep[\"loading[0].L[3][0]\"]", "no element 3"},
        Broken{"unknown_compression.yaml", 20, "output.compression", "gzip"},
        Broken{"compression_level_range.yaml", 21, "output.compression_level", "9"},
        Broken{"compression_level_without_gzip.yaml", 21, "output.compression_level",
               "compression: none"},
        Broken{"rate_L_and_dot_F.yaml", 16, "loading[0].dot_F",
               "give either 'L' or 'dot_F', not both"},
        Broken{"stress_and_P.yaml", 17, "loading[0].P", "give either 'stress' or 'P', not both"},
        Broken{"dot_F_and_P_both_given.yaml", 16, "loading[0].P[2][2]",
               "component 33: dot_F_33 and P_33 are both given; exactly one of them must be x"},
        Broken{"dot_F_with_cauchy_stress.yaml", 16, "loading[0].stress",
               "dot_F takes its stress targets as P (first Piola-Kirchhoff)"},
        Broken{"P_in_rate_units.yaml", 16, "loading[0].P[2][2]",
               "'1/s' is a unit of 1/time, but this value's dimension is stress"},
        Broken{"dot_F_in_stress_units.yaml", 15, "loading[0].dot_F[2][2]",
               "'MPa' is a unit of stress, but this value's dimension is 1/time"}),
    [](const ::testing::TestParamInfo<Broken>& info) {
      std::string name = info.param.file;
      return name.substr(0, name.find('.'));
    });

// Every broken scene in tests/data/crystal_scenes is in the table above (a new file needs a row).
TEST(BrokenCrystalScenes, TableCoversEveryFile) {
  std::size_t files = 0;
  for (const auto& entry : fs::directory_iterator(kBrokenDir)) {
    if (entry.path().extension() == ".yaml") ++files;
  }
  EXPECT_EQ(files, 29u);
}

// ---------------------------------------------------------------- shipped scenes

TEST(ShippedCrystalScenes, EveryCrystalInputParses) {
  const auto scenes = shipped_crystal_scenes();
  ASSERT_GE(scenes.size(), 9u);
  for (const auto& path : scenes) {
    SCOPED_TRACE(path.string());
    CrystalScene scene;
    ASSERT_NO_THROW(scene = load_crystal_scene(path));
    EXPECT_FALSE(scene.title.empty());
    EXPECT_FALSE(scene.cases.empty());
    for (const auto& c : scene.cases) {
      EXPECT_FALSE(c.orientations.empty());
      EXPECT_FALSE(c.segments.empty());
      EXPECT_NO_THROW(crystal::described_systems(c.phase));
    }
  }
}

TEST(ShippedCrystalScenes, DefaultIsTheCopperTaylorTensionJob) {
  const auto scene = load_crystal_scene(kSource / "inputs/default.yaml");
  ASSERT_EQ(scene.cases.size(), 1u);
  const CrystalCase& c = scene.cases[0];
  EXPECT_EQ(c.orientations.size(), 1000u);
  EXPECT_EQ(crystal::described_systems(c.phase).size(), 12u);
  const auto& s = c.segments.at(0);
  EXPECT_TRUE(s.free(0, 0) && s.free(1, 1) && !s.free(2, 2));
  EXPECT_DOUBLE_EQ(s.velocity_gradient(2, 2) * s.duration, 0.05);
  EXPECT_TRUE(s.stress_target.isZero());
  EXPECT_TRUE(c.output.grains.empty());
}

TEST(ShippedCrystalScenes, SingleSlipCheckSweepsTheShearRate) {
  const auto scene = load_crystal_scene(kSource / "inputs/single_slip_check.yaml");
  ASSERT_EQ(scene.cases.size(), 5u);
  const double speeds[5] = {1, 10, 50, 100, 200};
  for (std::size_t k = 0; k < 5; ++k) {
    const CrystalCase& c = scene.cases[k];
    EXPECT_EQ(c.name, "L[0][1]=" + std::to_string(static_cast<int>(speeds[k])));
    const auto& s = c.segments.at(0);
    EXPECT_DOUBLE_EQ(s.velocity_gradient(0, 1), speeds[k]);
    EXPECT_NEAR(s.duration, 20.0 / speeds[k], 1e-14);
    EXPECT_FALSE(s.free.any());
    EXPECT_EQ(c.phase.custom_systems.size(), 1u);
    EXPECT_EQ(c.phase.kinematics, crystal::Kinematics::small_strain);
    EXPECT_NEAR(c.phase.stiffness(5, 5), 2.0e6, 1e-6);  // 2 G, G = alpha_t h
    EXPECT_DOUBLE_EQ(c.phase.custom_settings.tau0, 5.56);
    EXPECT_DOUBLE_EQ(c.phase.custom_settings.law.overstress.eta_v, 950.0);
  }
}

// The run model only says where the orientations come from; the driver reads them. Read by
// one process (no team, or a team of one), they are the whole set parse_crystal_scene reads,
// in order, with the same digest; a file's problem is the same error, found when it is read.
TEST(CrystalScene, DescribedSceneLeavesItsOrientationsToTheDriver) {
  const fs::path path = kSource / "inputs/bcc_48_tension.yaml";
  const CrystalScene whole = load_crystal_scene(path);
  for (const parallel::Team* team :
       {static_cast<const parallel::Team*>(nullptr), &parallel::serial_team()}) {
    CrystalScene described = describe_crystal_scene(YamlDocument::from_file(path));
    ASSERT_EQ(described.cases.size(), 1u);
    CrystalCase& c = described.cases[0];
    EXPECT_TRUE(c.orientations.empty());
    ASSERT_TRUE(c.orientation_origin.file.has_value());
    EXPECT_EQ(c.orientation_source.kind, "file");
    driver::read_orientations(described, {team, nullptr});
    EXPECT_FALSE(c.orientation_block.has_value());
    ASSERT_EQ(c.orientations.size(), whole.cases[0].orientations.size());
    EXPECT_EQ(c.orientations_digest(), whole.cases[0].orientations_digest());
    EXPECT_EQ(c.orientation_source.largest_euler_deg,
              whole.cases[0].orientation_source.largest_euler_deg);
  }
  const fs::path bad = kSource / "tests/data/crystal_scenes/bad_orientation_file.yaml";
  std::string parsed_error;
  try {
    parse_crystal_scene(YamlDocument::from_file(bad));
  } catch (const InputError& e) {
    parsed_error = e.what();
  }
  ASSERT_FALSE(parsed_error.empty());
  CrystalScene described = describe_crystal_scene(YamlDocument::from_file(bad));
  try {
    driver::read_orientations(described, {});
    ADD_FAILURE() << "the bad orientation file was read";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), parsed_error);
  }
}
