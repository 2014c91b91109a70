// Bad input, one row per class: every broken scene or orientation file must give one
// InputError "FILE:LINE: KEY: MESSAGE" naming the file, the line and the key at fault, and the
// executable must exit with code 2 before it creates or touches a result file.
//
// The files are small broken copies of a valid scene in tests/data/bad/; rows for classes that
// the parser tables of test_scene.cpp, test_crystal_scene.cpp and test_orientation_file.cpp
// already hold a file for reuse that file (paths are relative to tests/data).
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <ostream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "scene_text.hpp"
#include "scratch_dir.hpp"
#include "subslip/io/contact_scene.hpp"
#include "subslip/io/crystal_scene.hpp"
#include "subslip/io/input_error.hpp"
#include "subslip/io/orientation_file.hpp"
#include "subslip/io/scene_common.hpp"
#include "subslip/io/yaml_checked.hpp"

namespace fs = std::filesystem;
using namespace subslip;
using namespace subslip::io;

namespace {

const fs::path kData = fs::path(SUBSLIP_SOURCE_DIR) / "tests/data";
const std::string kBinary = SUBSLIP_BINARY;

struct BadInput {
  const char* file;             // relative to tests/data
  const char* key;              // part of the key path the error names ("" : the error has no key)
  int line;                     // 1-based; 0: the error has no line (missing or empty file)
  const char* fragment;         // part of the message
  const char* error_file = "";  // when the error is in another file (relative to tests/data)
};

void PrintTo(const BadInput& b, std::ostream* os) {
  *os << b.file;
}

// Scenes by their `scene:` kind, everything else as an orientation file.
void load(const fs::path& path) {
  if (path.extension() != ".yaml") {
    read_orientation_file(path.string());
    return;
  }
  const YamlDocument document = YamlDocument::from_file(path);
  if (scene_kind(document, {"contact", "crystal"}) == "contact") {
    parse_contact_scene(document);
  } else {
    parse_crystal_scene(document);
  }
}

// clang-format off
const BadInput kTable[] = {
    // YAML itself
    {"scenes/malformed.yaml", "", 14, "YAML syntax error"},
    {"scenes/empty.yaml", "", 0, "expected a mapping"},
    {"bad/scenes/two_documents.yaml", "", 17, "a second YAML document starts here"},
    {"scenes/duplicate_key.yaml", "contact.alpha_t", 12, "duplicate key"},
    // unknown or misspelt keys and names: the nearest valid one, or the list when none is near
    {"scenes/unknown_key.yaml", "law.overstress.eta", 7, "unknown key 'eta'; did you mean 'eta_v'?"},
    {"crystal_scenes/unknown_key.yaml", "phase.tau_0", 7, "did you mean 'tau0'?"},
    {"bad/scenes/unknown_key_no_match.yaml", "contact.tangential_stiffness", 11,
     "expected one of: alpha_n, alpha_t, normal_traction"},
    {"scenes/bad_scene_kind.yaml", "scene", 1, "did you mean 'contact'?"},
    {"crystal_scenes/bad_family.yaml", "phase.families[0]", 5, "did you mean 'fcc_111_110'?"},
    // missing required keys
    {"scenes/missing_key.yaml", "law.friction.xi", 5, "missing required key"},
    {"crystal_scenes/missing_orientations.yaml", "orientations", 0, "missing required key"},
    // wrong types
    {"scenes/wrong_type.yaml", "law.friction.mu_s", 5, "expected a number, got 'abc'"},
    {"scenes/quoted_number.yaml", "law.subloading.u_tilde", 6, "quoted string"},
    {"bad/scenes/mapping_expected.yaml", "law.friction", 6, "expected a mapping"},
    {"bad/scenes/number_expected.yaml", "contact.alpha_n", 10, "expected a number, got a sequence"},
    {"bad/scenes/integer_expected.yaml", "loading[0].increments", 15, "expected an integer"},
    {"bad/scenes/integer_too_large.yaml", "loading[0].increments", 15,
     "1000000000000 is above the largest value this key takes, 2147483647"},
    {"scenes/short_direction.yaml", "loading[0].slide.direction", 13, "expected 2 numbers"},
    {"crystal_scenes/bad_matrix_shape.yaml", "loading[0].L", 15, "3 rows of 3 entries"},
    {"scenes/nan_value.yaml", "law.friction.kappa", 5, "finite"},
    // units: the scene's system from the listed names, never swept; a value written with a unit
    // must use a known unit of its dimension (and dimensionless values take none)
    {"scenes/bad_unit.yaml", "units.stress", 3, "did you mean 'MPa'?"},
    {"bad/scenes/unknown_scene_unit.yaml", "units.length", 4,
     "unknown value 'ft'; expected one of: m, cm, mm, um"},
    {"scenes/missing_units.yaml", "units", 0, "missing required key"},
    {"bad/scenes/unknown_unit.yaml", "contact.normal_traction", 12,
     "unknown unit 'kpa'; did you mean 'kPa'? this value's dimension is stress; it takes Pa, kPa, MPa "
     "or GPa (supported: stress Pa kPa MPa GPa; length m cm mm um nm"},
    {"bad/scenes/unit_of_other_dimension.yaml", "loading[0].slide.speed", 14,
     "'MPa' is a unit of stress, but this value's dimension is length/time"},
    {"bad/scenes/unit_on_dimensionless.yaml", "law.friction.mu_s", 6, "dimensionless"},
    {"bad/crystal_scenes/unit_on_slip_constant.yaml", "phase.law.friction.kappa", 10,
     "dimensionless"},
    {"bad/crystal_scenes/unit_in_velocity_gradient.yaml", "loading[0].L[2][2]", 16,
     "'MPa' is a unit of stress, but this value's dimension is 1/time; it takes 1/s, 1/ms, 1/min or 1/h"},
    {"scenes/sweep_units.yaml", "units.stress", 17, "cannot be swept"},
    // physical ranges of the law
    {"bad/scenes/range_eta_v.yaml", "law.overstress.eta_v", 8, "must be > 0, got 0"},
    {"bad/scenes/range_n.yaml", "law.overstress.n", 8, "must be > 0, got -2"},
    {"scenes/range_r_hat.yaml", "law.overstress.r_hat", 7, "must be > 1, got 0.9"},
    {"bad/scenes/range_mu_s.yaml", "law.friction.mu_s", 6, "must be > 0, got 0"},
    {"bad/scenes/range_mu_k.yaml", "law.friction.mu_k", 6, "must be > 0, got -0.085"},
    {"bad/scenes/range_kappa.yaml", "law.friction.kappa", 6, "must be >= 0, got -0.2"},
    {"scenes/rate_independent_eta.yaml", "law.overstress.eta_v", 7, "rate_independent"},
    // stiffness and reference stresses
    {"scenes/range_alpha.yaml", "contact.alpha_t", 10, "must be > 0"},
    {"scenes/range_normal_traction.yaml", "contact.normal_traction", 11, "must be > 0"},
    {"crystal_scenes/non_pd_elasticity.yaml", "phase.elasticity", 6, "not positive definite"},
    {"bad/crystal_scenes/range_tau0.yaml", "phase.tau0", 8, "must be > 0, got 0"},
    {"bad/crystal_scenes/range_c_over_a.yaml", "phase.c_over_a", 7, "must be in [0.1, 10]"},
    // durations and stepping
    {"bad/scenes/range_duration.yaml", "loading[0].hold.duration", 14, "must be > 0, got 0"},
    {"bad/crystal_scenes/range_duration.yaml", "loading[0].duration", 18, "must be > 0, got -1"},
    {"scenes/range_increments.yaml", "loading[0].increments", 14, "must be >= 1"},
    {"scenes/range_growth.yaml", "loading[0].growth", 15, "must be > 0"},
    {"bad/scenes/growth_overflow.yaml", "loading[0].growth", 16, "overflows"},
    {"bad/scenes/increment_underflow.yaml", "loading[0].increments", 15, "underflows"},
    {"bad/scenes/duration_overflow.yaml", "loading[0].slide.distance", 14, "not a usable duration"},
    {"bad/scenes/normal_ramp_overflow.yaml", "loading[0].normal.velocity", 17, "overflows"},
    {"bad/crystal_scenes/strain_without_rate.yaml", "loading[0].strain", 18,
     "needs a non-zero prescribed component of L"},
    {"scenes/distance_and_duration.yaml", "loading[0].slide.duration", 13, "not both"},
    // mixed control: a free L_ij needs a prescribed stress_ij, and a prescribed stress_ij a free L_ij
    {"crystal_scenes/free_without_stress.yaml", "loading[0].L[0][0]", 15, "no 'stress'"},
    {"crystal_scenes/both_given.yaml", "loading[0].stress[2][2]", 16,
     "L_33 and stress_33 are both given; exactly one of them must be x"},
    {"crystal_scenes/both_free.yaml", "loading[0].stress[2][2]", 16, "are both x"},
    {"crystal_scenes/asymmetric_pair.yaml", "loading[0].stress[1][0]", 16,
     "stress_21 must equal stress_12"},
    // orientations given in the scene
    {"bad/crystal_scenes/euler_out_of_range.yaml", "orientations.euler_deg[1]", 14,
     "[-360, 360]"},
    {"bad/crystal_scenes/weight_sum_overflow.yaml", "orientations.euler_deg", 14, "sum to more"},
    {"bad/crystal_scenes/too_many_grains.yaml", "orientations.random.count", 14,
     "must be in [1, 10000000]"},
    {"crystal_scenes/bad_orientation_file.yaml", "Phi", 3,
     "(orientation file given at " SUBSLIP_SOURCE_DIR
     "/tests/data/crystal_scenes/bad_orientation_file.yaml:13: orientations.file)",
     "crystal_scenes/bad_orientations.txt"},
    // sweeps
    {"scenes/bad_sweep_path.yaml", "sweep[\"loading[0].slide.sped\"]", 17, "did you mean 'speed'?"},
    {"scenes/bad_sweep_value.yaml", "law.overstress.eta_v", 18, "(in sweep case 'eta_v=-1')"},
    {"bad/scenes/non_scalar_sweep_key.yaml", "sweep", 18, "plain names"},
    // orientation files
    {"orientations/empty.txt", "orientations", 0, "empty file"},
    {"orientations/header_only.txt", "orientations", 0, "no orientations"},
    {"orientations/missing_header.txt", "header", 1, "the first line must be the header"},
    {"orientations/unknown_convention.txt", "convention", 1, "unknown convention"},
    {"orientations/active_convention.txt", "header", 1, "only P=-1 is supported"},
    {"orientations/wrong_column_count.txt", "columns", 5, "expected 3 numbers"},
    {"orientations/inconsistent_weights.txt", "columns", 3, "on every line or on none"},
    {"orientations/not_a_number.txt", "Phi", 3, "'abc' is not a number"},
    {"orientations/nan_value.txt", "phi1", 2, "not finite"},
    {"orientations/inf_value.txt", "w", 3, "not finite"},
    {"orientations/quaternion_not_unit.txt", "quaternion", 4, "differs from 1 by more than 1e-3"},
    {"orientations/zero_quaternion.txt", "quaternion", 2, "differs from 1"},
    {"orientations/euler_Phi_out_of_range.txt", "Phi", 2, "outside [0, 180]"},
    {"orientations/negative_weight.txt", "weight", 3, "must be positive"},
};
// clang-format on

// "FILE:LINE: ", or "FILE: " without a line (as InputError::format writes it).
std::string location(const std::string& file, int line) {
  return InputError::format(file, line, "", "");
}

class BadInputTable : public ::testing::TestWithParam<BadInput> {};

}  // namespace

TEST_P(BadInputTable, OneErrorNamingFileLineAndKey) {
  const BadInput& b = GetParam();
  const fs::path path = kData / b.file;
  ASSERT_TRUE(fs::exists(path)) << path;
  const std::string file = (*b.error_file ? kData / b.error_file : path).string();
  try {
    load(path);
    FAIL() << b.file << " was accepted";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(e.file, file) << what;
    EXPECT_EQ(e.line, b.line) << what;
    EXPECT_NE(e.key.find(b.key), std::string::npos) << what;
    EXPECT_EQ(what.rfind(location(file, b.line), 0), 0u) << what;
    if (*b.key) {
      EXPECT_NE(what.find(e.key + ": "), std::string::npos) << what;
    }
    EXPECT_NE(what.find(b.fragment), std::string::npos) << what;
  }
}

INSTANTIATE_TEST_SUITE_P(Classes, BadInputTable, ::testing::ValuesIn(kTable),
                         [](const ::testing::TestParamInfo<BadInput>& info) {
                           std::string name = info.param.file;
                           name = name.substr(0, name.rfind('.'));
                           std::replace_if(
                               name.begin(), name.end(),
                               [](char c) { return !std::isalnum(static_cast<unsigned char>(c)); },
                               '_');
                           return name;
                         });

// Every file in tests/data/bad has a row (a new broken file needs one).
TEST(BadInputFiles, TableCoversEveryFile) {
  std::set<std::string> rows;
  for (const BadInput& b : kTable) rows.insert(b.file);
  for (const auto& entry : fs::recursive_directory_iterator(kData / "bad")) {
    if (!entry.is_regular_file()) continue;
    const std::string relative = fs::relative(entry.path(), kData).string();
    EXPECT_TRUE(rows.count(relative)) << relative << " has no row in the table";
  }
}

// ---------------------------------------------------------------- the executable

namespace {

struct Outcome {
  int code;
  std::string err;
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

fs::path scratch_dir() {
  return subslip::testing::scratch_dir("bad");
}

// Runs `subslip ARGS` in `dir`; stdout is discarded, stderr captured.
Outcome run(const fs::path& dir, const std::string& args) {
  const fs::path err = dir / "stderr.txt";
  const std::string command = "cd '" + dir.string() + "' && '" + kBinary + "' " + args +
                              " >/dev/null 2>'" + err.string() + "'";
  const int status = std::system(command.c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, slurp(err)};
}

// The rows the executable is run on: a scene error, an error in an orientation file read by a
// scene, and errors without a line.
std::vector<BadInput> cli_rows() {
  std::vector<BadInput> rows;
  for (const BadInput& b : kTable) {
    const std::string f = b.file;
    if (f == "bad/scenes/range_eta_v.yaml" || f == "crystal_scenes/asymmetric_pair.yaml" ||
        f == "crystal_scenes/bad_orientation_file.yaml" || f == "scenes/missing_units.yaml" ||
        f == "bad/crystal_scenes/too_many_grains.yaml" || f == "scenes/malformed.yaml" ||
        f == "bad/scenes/unknown_unit.yaml")
      rows.push_back(b);
  }
  return rows;
}

}  // namespace

TEST(BadInputCli, ExitsWithCode2AndOneLineBeforeCreatingOutput) {
  const fs::path dir = scratch_dir();
  const auto rows = cli_rows();
  ASSERT_EQ(rows.size(), 7u);
  for (const BadInput& b : rows) {
    SCOPED_TRACE(b.file);
    const fs::path scene = kData / b.file;
    const fs::path out = dir / "out.h5";
    const Outcome o = run(dir, "run '" + scene.string() + "' -o '" + out.string() + "'");
    EXPECT_EQ(o.code, 2) << o.err;
    const std::string file = (*b.error_file ? kData / b.error_file : scene).string();
    // Exactly one line: "subslip: error: FILE:LINE: KEY: MESSAGE".
    EXPECT_EQ(std::count(o.err.begin(), o.err.end(), '\n'), 1) << o.err;
    EXPECT_EQ(o.err.rfind("subslip: error: " + location(file, b.line), 0), 0u) << o.err;
    EXPECT_NE(o.err.find(b.key), std::string::npos) << o.err;
    EXPECT_NE(o.err.find(b.fragment), std::string::npos) << o.err;
    EXPECT_FALSE(fs::exists(out));
  }
  // The default output location (results/<scene>.h5, directory included) is not created either.
  const Outcome o = run(dir, "run '" + (kData / cli_rows().front().file).string() + "'");
  EXPECT_EQ(o.code, 2);
  EXPECT_FALSE(fs::exists(dir / "results"));
  fs::remove_all(dir);
}

TEST(BadInputCli, ExistingResultIsNotTouchedEvenWithForce) {
  const fs::path dir = scratch_dir();
  const fs::path out = dir / "old.h5";
  const std::string old_content = "an earlier result\n";
  std::ofstream(out, std::ios::binary) << old_content;
  const auto old_time = fs::last_write_time(out);
  for (const char* force : {"", " --force"}) {
    SCOPED_TRACE(force);
    const Outcome o = run(dir, "run '" + (kData / "bad/scenes/range_n.yaml").string() + "' -o '" +
                                   out.string() + "'" + force);
    EXPECT_EQ(o.code, 2) << o.err;
    EXPECT_NE(o.err.find("law.overstress.n: must be > 0"), std::string::npos) << o.err;
    EXPECT_EQ(slurp(out), old_content);
    EXPECT_EQ(fs::last_write_time(out), old_time);
  }
  fs::remove_all(dir);
}

// Fuzz finding (scene_fuzzer): a NUL byte in a key of a swept case. what() is a C string, so
// the message was cut at the NUL, and re-prefixing it for the sweep case read past its end
// (std::out_of_range). Control bytes are now escaped, and the bare message is kept apart; a
// NUL byte is now refused before the YAML is parsed (not a text file), so \x01 stands in.
TEST(InputErrors, ControlBytesInAKeyAreEscapedAndSweepCasesStillNamed) {
  std::string text = subslip::testing::contact_scene_start() + R"(loading:
  - slide: {speed: 1, direction: [1, 0], distance: 0.1}
    increments: 10
sweep:
  "loading[0].slide.speed": [1, 2]
)";
  std::string nul = text;
  nul.replace(nul.find("kappa: 0.2"), 10, std::string("kappa:\0 0.2", 10));
  try {
    parse_contact_scene(YamlDocument::from_string(nul, "nul.yaml"));
    FAIL() << "the key with a NUL byte was accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.line, 4);
    EXPECT_NE(e.message.find("a NUL byte at column"), std::string::npos) << e.what();
  }
  text.replace(text.find("kappa: 0.2"), 10, "kappa:\x01 0.2");
  try {
    parse_contact_scene(YamlDocument::from_string(text, "ctrl.yaml"));
    FAIL() << "the key with a control byte was accepted";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.find('\x01'), std::string::npos);
    EXPECT_NE(what.find("unknown key 'kappa:\\x01"), std::string::npos) << what;
    // (every case has the same unswept key: the message names no case)
    EXPECT_EQ(what.find("(in sweep case"), std::string::npos) << what;
    EXPECT_EQ(what, InputError::format(e.file, e.line, e.key, e.message));
  }
}

// A second YAML document is found in the text: yaml-cpp's LoadAll looped for ever on ",s" (a
// scene_fuzzer finding), so documents are no longer counted with it.
TEST(InputErrors, SecondDocumentsAreFoundInTheText) {
  try {
    YamlDocument::from_string(",s", "f.yaml");  // returns or refuses, but ends
  } catch (const InputError&) {
  }
  auto second_line = [](const std::string& text) {
    try {
      YamlDocument::from_string(text, "f.yaml");
    } catch (const InputError& e) {
      EXPECT_NE(e.message.find("a second YAML document starts here"), std::string::npos)
          << e.what();
      return e.line;
    }
    return 0;
  };
  EXPECT_EQ(second_line("a: 1\n---\nb: 2\n"), 2);
  EXPECT_EQ(second_line("a: 1\n---\n"), 2);
  EXPECT_EQ(second_line("a: 1\n...\n# a comment\n\nb: 2\n"), 5);
  EXPECT_EQ(second_line("# c\n---\na: 1\n...\n"), 0);  // one document, marked
  EXPECT_EQ(second_line("a: |\n  ---\n  text\n"), 0);  // '---' inside a block scalar
}

// ---------------------------------------------------------------- several errors in one scene

namespace {

// A contact scene with five independent mistakes: a misspelt key (whose correct spelling is
// then missing: that follows from it and is not reported), a value out of range in another
// block, two segments with one error each and a misspelt method.
const std::string kFiveErrors = R"(scene: contact
units: {stress: MPa, length: mm, time: min}
law:
  friction: {mu_s: 0.097, mu_k: 0.085, kapa: 0.2, xi: 0.009}
  subloading: {function: cot, u_tilde: 80}
  overstress: {form: exponential, eta_v: 950, n: 16, r_hat: 0.9}
contact: {alpha_n: 1.0e6, alpha_t: 1.0e6, normal_traction: 5.56}
loading:
  - slide: {speed: 1, direction: [1, 0], distance: 0.2}
    increments: 0
  - slide: {speed: -1, distance: 0.2}
    increments: 10
integrator: {method: implicitt}
)";

struct Expected {
  int line;
  const char* key;
  const char* fragment;
};

// The errors `text` raises, all of them (none: the test fails).
std::vector<InputError> errors_of(const std::string& text, bool* stopped = nullptr) {
  try {
    const YamlDocument document = YamlDocument::from_string(text, "s.yaml");
    if (scene_kind(document, {"contact", "crystal"}) == "contact") {
      parse_contact_scene(document);
    } else {
      describe_crystal_scene(document);
    }
  } catch (const InputErrors& e) {
    if (stopped) *stopped = e.stopped;
    return e.all;
  } catch (const InputError& e) {
    if (stopped) *stopped = false;
    return {e};
  }
  ADD_FAILURE() << "no InputError for:\n" << text;
  return {};
}

void expect_errors(const std::vector<InputError>& got, const std::vector<Expected>& wanted) {
  std::string all;
  for (const InputError& e : got) all += std::string(e.what()) + "\n";
  ASSERT_EQ(got.size(), wanted.size()) << all;
  for (std::size_t k = 0; k < got.size(); ++k) {
    SCOPED_TRACE(k);
    EXPECT_EQ(got[k].file, "s.yaml");
    EXPECT_EQ(got[k].line, wanted[k].line) << all;
    EXPECT_EQ(got[k].key, wanted[k].key) << all;
    EXPECT_NE(got[k].message.find(wanted[k].fragment), std::string::npos) << all;
  }
}

}  // namespace

// Every error of a scene in one reading, each with its file, line and key, in the order the
// scene is read; the first is the error itself (what a caller of one error sees), what() has
// one line for each.
TEST(InputErrors, EveryErrorOfASceneIsReportedOnce) {
  try {
    parse_contact_scene(YamlDocument::from_string(kFiveErrors, "s.yaml"));
    FAIL() << "accepted";
  } catch (const InputErrors& e) {
    expect_errors(e.all, {{4, "law.friction.kapa", "unknown key 'kapa'; did you mean 'kappa'?"},
                          {6, "law.overstress.r_hat", "must be > 1, got 0.9"},
                          {10, "loading[0].increments", "must be >= 1, got 0"},
                          {11, "loading[1].slide.speed", "must be >= 0"},
                          {13, "integrator.method", "did you mean 'implicit'?"}});
    EXPECT_FALSE(e.stopped);
    EXPECT_EQ(e.line, 4);  // the first
    EXPECT_EQ(e.key, "law.friction.kapa");
    const std::string what = e.what();
    EXPECT_EQ(std::count(what.begin(), what.end(), '\n'), 4) << what;
    EXPECT_EQ(what.rfind(e.all[0].what(), 0), 0u) << what;
    EXPECT_EQ(what.find("missing required key"), std::string::npos) << what;
  }
}

// A crystal scene: blocks independent of each other are all read; one that needs a failed one
// is not (the integrator's checks need the phase), so that no error only follows from another.
TEST(InputErrors, CrystalBlocksAreReadIndependently) {
  const std::string scene = subslip::testing::copper_scene_start() +
                            R"(orientations: {random: {count: 0, seed: 1}}
loading:
  - L: [[x, 0, 0], [0, x, 0], [0, 0, 1.0e-3]]
    stress: [[0, x, x], [x, 0, x], [x, x, x]]
    duration: -20
    increments: 50
    growth: 0
output: {macro: [stress]}
)";
  std::string text = scene;
  text.replace(text.find("tau0: 10.0"), 10, "tau0: -1");
  expect_errors(errors_of(text), {{6, "phase.tau0", "must be > 0"},
                                  {11, "orientations.random.count", "must be"},
                                  {15, "loading[0].duration", "must be > 0"},
                                  {17, "loading[0].growth", "must be > 0"},
                                  {18, "output.macro", "must include 'time'"}});
  // The phase fails as a whole (its law): the integrator, which checks against it, is skipped.
  text = scene + "integrator: {method: forward_euler, tolerance: 1.0e-3}\n";
  text.replace(text.find("r_hat: 1.6"), 10, "r_hat: 0.5");
  const auto errors = errors_of(text);
  ASSERT_FALSE(errors.empty());
  EXPECT_EQ(errors[0].key, "phase.law.overstress.r_hat");
  for (const InputError& e : errors) EXPECT_NE(e.key.rfind("integrator", 0), 0u) << e.what();
}

// A sweep: an error only some cases have names them; one every case has (a key no swept value
// touches) names none, wherever it comes in the order of reading.
TEST(InputErrors, SweepTagsOnlyWhatDependsOnTheCase) {
  const std::string scene = subslip::testing::contact_scene_start() + R"(loading:
  - slide: {speed: 1, direction: [1, 0], distance: 0.1}
    increments: 10
integrator: {method: implicitt}
sweep:
  "law.overstress.r_hat": [1.8, 0.9, 0.8]
)";
  const auto errors = errors_of(scene);
  ASSERT_EQ(errors.size(), 3u);
  // Case 1 fails on the method only, cases 2 and 3 first on r_hat: the method's error is every
  // case's and comes once, untagged; each r_hat error names its case.
  EXPECT_EQ(errors[0].key, "integrator.method");
  EXPECT_EQ(errors[0].message.find("(in sweep case"), std::string::npos) << errors[0].what();
  EXPECT_EQ(errors[1].key, "law.overstress.r_hat");
  EXPECT_EQ(errors[1].line, 13);  // in the sweep block
  EXPECT_NE(errors[1].message.find("got 0.9 (in sweep case 'r_hat=0.9')"), std::string::npos)
      << errors[1].what();
  EXPECT_NE(errors[2].message.find("got 0.8 (in sweep case 'r_hat=0.8')"), std::string::npos)
      << errors[2].what();
  // The same wrong value reached by two cases: one line naming both.
  const auto shared = errors_of(subslip::testing::contact_scene_start() + R"(loading:
  - slide: {speed: 1, direction: [1, 0], distance: 0.1}
    increments: 10
sweep:
  "loading[0].increments": [0, 10]
  "law.overstress.n": [16, 8]
)");
  ASSERT_EQ(shared.size(), 1u);
  EXPECT_NE(shared[0].message.find("(in sweep cases 'increments=0,n=16', 'increments=0,n=8')"),
            std::string::npos)
      << shared[0].what();
}

// At most 20 errors: the reading stops there, saying so.
TEST(InputErrors, ReadingStopsAtTheLimit) {
  std::string scene = subslip::testing::contact_scene_start() + "loading:\n";
  for (int k = 0; k < 30; ++k) scene += "  - slide: {speed: 1, distance: 0.1}\n    increments: 0\n";
  bool stopped = false;
  const auto errors = errors_of(scene, &stopped);
  ASSERT_EQ(errors.size(), InputErrorList::kDefaultLimit);
  EXPECT_TRUE(stopped);
  EXPECT_EQ(errors.back().key, "loading[19].increments");
  try {
    parse_contact_scene(YamlDocument::from_string(scene, "s.yaml"));
  } catch (const InputErrors& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("\n(stopped after 20 errors; correct these and run again"),
              std::string::npos)
        << what;
  }
}

// The executable prints each error on its own "subslip: error:" line, exit code 2.
TEST(BadInputCli, EveryErrorOnItsOwnLine) {
  const fs::path dir = scratch_dir();
  std::ofstream(dir / "s.yaml") << kFiveErrors;
  const Outcome o = run(dir, "run s.yaml -o out.h5");
  EXPECT_EQ(o.code, 2) << o.err;
  EXPECT_EQ(std::count(o.err.begin(), o.err.end(), '\n'), 5) << o.err;
  for (const char* line : {"subslip: error: s.yaml:4: law.friction.kapa: unknown key 'kapa'",
                           "\nsubslip: error: s.yaml:6: law.overstress.r_hat: must be > 1",
                           "\nsubslip: error: s.yaml:10: loading[0].increments: must be >= 1",
                           "\nsubslip: error: s.yaml:11: loading[1].slide.speed: must be >= 0",
                           "\nsubslip: error: s.yaml:13: integrator.method: unknown value"})
    EXPECT_NE(o.err.find(line), std::string::npos) << line << "\n" << o.err;
  EXPECT_FALSE(fs::exists(dir / "out.h5"));
  fs::remove_all(dir);
}
