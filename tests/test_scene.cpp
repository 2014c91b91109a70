// Scene files: the YAML checking layer, sweeps, the contact scene parser, and every shipped
// scene in inputs/.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <ostream>
#include <string>
#include <vector>

#include "scene_text.hpp"
#include "scratch_dir.hpp"
#include "subslip/io/contact_scene.hpp"
#include "subslip/io/input_error.hpp"
#include "subslip/io/scene_common.hpp"
#include "subslip/io/scene_compose.hpp"
#include "subslip/io/sweep.hpp"
#include "subslip/io/yaml_checked.hpp"

namespace fs = std::filesystem;
using namespace subslip;
using namespace subslip::io;

namespace {

const fs::path kSource = SUBSLIP_SOURCE_DIR;

// A valid one-segment scene; tests append or substitute lines.
const std::string kTiny = std::string("scene: contact\ntitle: \"tiny\"\n") +
                          subslip::testing::kContactUnitsAndLaw + R"(contact:
  alpha_n: 1.0e6
  alpha_t: 1.0e6
  normal_traction: 5.56
loading:
  - slide: {speed: 2.0, direction: [3, 4], distance: 0.1}
    increments: 20
    growth: 1.1
)";

ContactScene parse(const std::string& text) {
  return parse_contact_scene(YamlDocument::from_string(text, "test.yaml"));
}

// The InputError `text` raises (fails the test when none is raised).
InputError error_of(const std::string& text) {
  try {
    parse(text);
  } catch (const InputError& e) {
    return e;
  }
  ADD_FAILURE() << "no InputError for:\n" << text;
  return InputError("", 0, "", "");
}

}  // namespace

// ---------------------------------------------------------------- the checking layer

TEST(YamlChecked, EditDistance) {
  EXPECT_EQ(edit_distance("kitten", "sitting"), 3u);
  EXPECT_EQ(edit_distance("", "abc"), 3u);
  EXPECT_EQ(edit_distance("eta_v", "eta_v"), 0u);
  EXPECT_EQ(edit_distance("eta", "eta_v"), 2u);
}

TEST(YamlChecked, SuggestsOnlyPlausibleTypos) {
  const std::vector<std::string_view> keys = {"mu_s", "mu_k", "kappa", "xi"};
  EXPECT_EQ(nearest_name("kapa", keys), "kappa");
  EXPECT_EQ(nearest_name("Mu_s", keys), "mu_s");
  EXPECT_FALSE(nearest_name("static_friction", keys).has_value());
  EXPECT_EQ(suggestion("kapa", keys), "did you mean 'kappa'?");
  EXPECT_EQ(suggestion("static_friction", keys), "expected one of: mu_s, mu_k, kappa, xi");
}

TEST(YamlChecked, Ranges) {
  EXPECT_TRUE(Range::positive().contains(1e-300));
  EXPECT_FALSE(Range::positive().contains(0.0));
  EXPECT_TRUE(Range::non_negative().contains(0.0));
  EXPECT_TRUE(Range::at_least(1.0).contains(1.0));
  EXPECT_FALSE(Range::greater_than(1.0).contains(1.0));
  EXPECT_FALSE(Range::in_open_interval(0.0, 1.0).contains(1.0));
  EXPECT_TRUE(Range::in_closed_interval(0.0, 1.0).contains(1.0));
  EXPECT_EQ(Range::greater_than(1.0).describe(), "> 1");
  EXPECT_EQ(Range::in_open_interval(0.0, 1.0).describe(), "in (0, 1)");
}

TEST(YamlChecked, ReadsTypedValuesWithPaths) {
  const auto doc =
      YamlDocument::from_string("a:\n  b: [1, 2.5, 1e3]\n  c: 7\n  d: on_off\n", "x.yaml");
  const CheckedNode a = doc.root().required("a");
  EXPECT_EQ(a.path(), "a");
  EXPECT_EQ(a.required("b").as_doubles(Range::positive(), 3), (std::vector<double>{1, 2.5, 1000}));
  EXPECT_EQ(a.required("b").element(2).as_int(), 1000);
  EXPECT_EQ(a.required("b").element(1).path(), "a.b[1]");
  EXPECT_EQ(a.get_int("c", Range::at_least(1)), 7);
  EXPECT_EQ(a.get_int("missing", 3, Range::any()), 3);
  EXPECT_EQ(a.get_choice("d", {"on_off", "x"}), "on_off");
  try {
    a.required("b").element(1).as_int();
    FAIL() << "2.5 read as an integer";
  } catch (const InputError& e) {
    EXPECT_EQ(e.line, 2);
    EXPECT_EQ(e.key, "a.b[1]");
  }
  try {
    a.allow_keys({"b", "c"});
    FAIL() << "unknown key d accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.line, 4);
    EXPECT_EQ(e.key, "a.d");
  }
}

TEST(YamlChecked, MalformedYamlHasItsLine) {
  try {
    YamlDocument::from_string("a: 1\nb: [1, 2\nc: 3\n", "bad.yaml");
    FAIL() << "malformed YAML accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file, "bad.yaml");
    EXPECT_GE(e.line, 2);
    EXPECT_NE(std::string(e.what()).find("YAML syntax error"), std::string::npos);
  }
}

TEST(YamlChecked, MissingFileIsAnInputError) {
  EXPECT_THROW(YamlDocument::from_file("/nonexistent/scene.yaml"), InputError);
}

// ---------------------------------------------------------------- the contact scene

TEST(ContactScene, TinySceneResolvesUnitsDefaultsAndDirections) {
  const ContactScene scene = parse(kTiny);
  EXPECT_EQ(scene.title, "tiny");
  EXPECT_EQ(scene.units.velocity(), "mm/min");
  ASSERT_EQ(scene.cases.size(), 1u);
  const ContactCase& c = scene.cases[0];
  EXPECT_EQ(c.name, "base");
  EXPECT_DOUBLE_EQ(c.model.law.friction.kappa, 0.2);
  EXPECT_DOUBLE_EQ(c.model.initial_law_state.mu, 0.097);  // default: mu_s
  EXPECT_DOUBLE_EQ(c.model.initial_normal_traction, 5.56);
  ASSERT_EQ(c.segments.size(), 1u);
  const auto& s = c.segments[0];
  EXPECT_NEAR(s.velocity.x(), 2.0 * 0.6, 1e-15);  // direction [3, 4] normalised
  EXPECT_NEAR(s.velocity.y(), 2.0 * 0.8, 1e-15);
  EXPECT_DOUBLE_EQ(s.duration, 0.05);  // distance / speed
  EXPECT_EQ(s.increments, 20);
  EXPECT_DOUBLE_EQ(s.growth, 1.1);
  EXPECT_EQ(s.normal_control, contact::NormalControl::traction);
  EXPECT_DOUBLE_EQ(s.normal_traction, 5.56);  // f_n held constant
  EXPECT_EQ(c.fields.size(), kAllContactFields.size());
  EXPECT_EQ(c.integrator.method, contact::Method::implicit);
  EXPECT_EQ(output_count(c.segments), 21u);
}

TEST(ContactScene, SegmentsTrackNormalTraction) {
  const ContactScene scene = parse(kTiny + R"(  - hold: {duration: 2}
    increments: 4
    normal: {traction: 8.0}
  - slide: {velocity: [0, -1], duration: 0.5}
    increments: 10
    output_every: 3
  - hold: {duration: 1}
    increments: 2
    normal: {velocity: -1.0e-6}
  - hold: {duration: 1}
    increments: 1
integrator: {method: forward_euler, max_cutbacks: 5, residual_tolerance: 1.0e-10}
output: {fields: [ratio, time, mu]}
initial: {mu: 0.09}
)");
  const ContactCase& c = scene.cases.at(0);
  ASSERT_EQ(c.segments.size(), 5u);
  EXPECT_DOUBLE_EQ(c.segments[1].normal_traction, 8.0);
  EXPECT_DOUBLE_EQ(c.segments[2].normal_traction, 8.0);  // kept from the ramp's end
  EXPECT_EQ(c.segments[2].velocity, contact::Vec2(0, -1));
  EXPECT_EQ(c.segments[3].normal_control, contact::NormalControl::velocity);
  EXPECT_DOUBLE_EQ(c.segments[3].normal_velocity, -1.0e-6);
  EXPECT_NEAR(c.segments[4].normal_traction, 8.0 - 1.0e6 * 1.0e-6 * 1.0, 1e-12);
  EXPECT_EQ(output_count(c.segments), 1u + 20 + 4 + 4 + 2 + 1);
  EXPECT_EQ(c.integrator.method, contact::Method::forward_euler);
  EXPECT_EQ(c.integrator.max_cutbacks, 5);
  EXPECT_DOUBLE_EQ(c.integrator.residual_tolerance, 1.0e-10);
  EXPECT_EQ(c.fields,
            (std::vector<ContactField>{ContactField::time, ContactField::ratio, ContactField::mu}));
  EXPECT_DOUBLE_EQ(c.model.initial_law_state.mu, 0.09);
  EXPECT_DOUBLE_EQ(last_sliding_speed(c.segments), 1.0);
}

TEST(ContactScene, RateIndependentNeedsNoOverstressConstants) {
  std::string text = kTiny;
  const std::string rate_dependent = "form: exponential, eta_v: 950, n: 16, r_hat: 1.8";
  text.replace(text.find(rate_dependent), rate_dependent.size(), "form: rate_independent");
  const ContactScene scene = parse(text);
  EXPECT_EQ(scene.cases[0].model.law.overstress.form, law::OverstressForm::rate_independent);
}

TEST(ContactScene, SweepIsACartesianProductFirstKeySlowest) {
  const ContactScene scene = parse(kTiny + R"(sweep:
  "law.overstress.eta_v": [10, 1.0e5]
  "loading[0].slide.speed": [0.5, 4]
)");
  ASSERT_EQ(scene.cases.size(), 4u);
  const std::vector<std::string> names = {"eta_v=10,speed=0.5", "eta_v=10,speed=4",
                                          "eta_v=1.0e5,speed=0.5", "eta_v=1.0e5,speed=4"};
  for (std::size_t k = 0; k < 4; ++k) EXPECT_EQ(scene.cases[k].name, names[k]);
  const ContactCase& c = scene.cases[2];
  EXPECT_DOUBLE_EQ(c.model.law.overstress.eta_v, 1.0e5);
  EXPECT_NEAR(c.segments[0].velocity.norm(), 0.5, 1e-15);
  EXPECT_DOUBLE_EQ(c.segments[0].duration, 0.1 / 0.5);
  ASSERT_EQ(c.overrides.size(), 2u);
  EXPECT_EQ(c.overrides[0].path, "law.overstress.eta_v");
  EXPECT_EQ(c.overrides[0].value, "1.0e5");
  EXPECT_DOUBLE_EQ(*c.overrides[0].number, 1.0e5);
  // Cases do not leak into each other.
  EXPECT_DOUBLE_EQ(scene.cases[0].model.law.overstress.eta_v, 10.0);
}

TEST(ContactScene, SweepWildcardAndAmbiguousKeys) {
  const ContactScene scene = parse(kTiny + R"(  - slide: {speed: 1, distance: 0.1}
    increments: 5
sweep:
  "loading[*].slide.speed": [3]
  "loading[1].slide.distance": [0.3]
  "loading[0].slide.distance": [0.6]
  "loading[0].slide.direction": [[0, 1]]
)");
  ASSERT_EQ(scene.cases.size(), 1u);
  const ContactCase& c = scene.cases[0];
  EXPECT_EQ(c.name,
            "speed=3,loading[1].slide.distance=0.3,loading[0].slide.distance=0.6,"
            "direction=[0, 1]");
  EXPECT_NEAR(c.segments[0].velocity.y(), 3.0, 1e-15);
  EXPECT_DOUBLE_EQ(c.segments[0].duration, 0.2);
  EXPECT_DOUBLE_EQ(c.segments[1].duration, 0.1);
  EXPECT_FALSE(c.overrides[3].number.has_value());
}

// A value written with its unit keeps it in the case's name; the group that stores the case
// writes '/' as '_', and two names that would share a group are refused.
TEST(ContactScene, SweepNamesKeepTheUnitsAsWritten) {
  const ContactScene scene =
      parse(kTiny + "sweep:\n  \"loading[0].slide.speed\": [1 mm/min, 0.5 mm/s]\n");
  ASSERT_EQ(scene.cases.size(), 2u);
  EXPECT_EQ(scene.cases[0].name, "speed=1 mm/min");
  EXPECT_EQ(scene.cases[1].name, "speed=0.5 mm/s");
  EXPECT_EQ(case_group_name(scene.cases[1].name), "speed=0.5 mm_s");
  EXPECT_NEAR(scene.cases[1].segments[0].velocity.norm(), 30.0, 1e-13);  // mm/min
  const InputError e =
      error_of(kTiny + "sweep:\n  \"loading[0].slide.speed\": [1 mm/min, 1 mm_min]\n");
  EXPECT_EQ(e.key, "sweep");
  EXPECT_NE(e.message.find("stored as group 'speed=1 mm_min'"), std::string::npos) << e.what();
}

TEST(ContactScene, SweepErrorsNameTheCase) {
  const InputError e = error_of(kTiny + "sweep:\n  \"law.friction.mu_k\": [0.08, -1]\n");
  EXPECT_EQ(e.key, "law.friction.mu_k");
  EXPECT_EQ(e.line, 17);  // the sweep block's line
  EXPECT_NE(std::string(e.what()).find("mu_k=-1"), std::string::npos) << e.what();
}

// ---------------------------------------------------------------- base scenes and settings

namespace {

// The InputError composing and parsing `scene` with `settings` raises.
InputError compose_error(const YamlDocument& scene, const std::vector<std::string>& settings) {
  try {
    parse_contact_scene(compose_scene(scene, settings));
  } catch (const InputError& e) {
    return e;
  }
  ADD_FAILURE() << "no InputError for:\n" << scene.text();
  return InputError("", 0, "", "");
}

}  // namespace

// A scene over a base: its own keys win, mappings are merged key by key (a list is replaced
// whole), the base's relative to the file that names it; errors name the file they are in.
TEST(SceneBase, MergesKeyByKeyAndErrorsNameTheirFile) {
  const fs::path dir = subslip::testing::scratch_dir("scene_base");
  fs::create_directories(dir / "bases");
  std::ofstream(dir / "bases/tiny.yaml") << kTiny;
  std::ofstream(dir / "fast.yaml") << R"(base: bases/tiny.yaml
title: "fast"
law:
  friction: {mu_s: 0.2}
loading:
  - slide: {speed: 8, distance: 0.4}
    increments: 10
)";
  const ContactScene scene = load_contact_scene(dir / "fast.yaml");
  EXPECT_EQ(scene.title, "fast");
  const ContactCase& c = scene.cases.at(0);
  EXPECT_EQ(c.model.law.friction.mu_s, 0.2);     // the scene's
  EXPECT_EQ(c.model.law.friction.mu_k, 0.085);   // the base's, beside it
  EXPECT_EQ(c.model.law.overstress.eta_v, 950);  // a block only the base has
  ASSERT_EQ(c.segments.size(), 1u);              // the list is the scene's
  EXPECT_DOUBLE_EQ(c.segments[0].duration, 0.05);
  EXPECT_EQ(c.segments[0].increments, 10);
  ASSERT_EQ(scene.makeup.bases.size(), 1u);
  EXPECT_EQ(scene.makeup.bases[0].first, (dir / "bases/tiny.yaml").string());
  EXPECT_EQ(scene.makeup.bases[0].second, kTiny);

  // A bad value from the base names the base file and its line; one of the scene, the scene.
  std::string bad_base = kTiny;
  bad_base.replace(bad_base.find("normal_traction: 5.56"), 21, "normal_traction: -1");
  std::ofstream(dir / "bases/tiny.yaml") << bad_base;
  const InputError in_base = compose_error(YamlDocument::from_file(dir / "fast.yaml"), {});
  EXPECT_EQ(in_base.file, (dir / "bases/tiny.yaml").string());
  EXPECT_EQ(in_base.line, 11);
  EXPECT_EQ(in_base.key, "contact.normal_traction");
  std::ofstream(dir / "bases/tiny.yaml") << kTiny;
  const auto in_scene = compose_error(
      YamlDocument::from_string("base: bases/tiny.yaml\nlaw:\n  friction: {mu_s: -2}\n",
                                (dir / "neg.yaml").string()),
      {});
  EXPECT_EQ(in_scene.file, (dir / "neg.yaml").string());
  EXPECT_EQ(in_scene.line, 3);
  EXPECT_EQ(in_scene.key, "law.friction.mu_s");
  // A base that cannot be read, and bases that name each other, at the `base:` key.
  const auto missing = compose_error(
      YamlDocument::from_string("title: \"x\"\nbase: nowhere.yaml\n", (dir / "m.yaml").string()),
      {});
  EXPECT_EQ(missing.line, 2);
  EXPECT_EQ(missing.key, "base");
  EXPECT_NE(missing.message.find("cannot read the base scene " + (dir / "nowhere.yaml").string()),
            std::string::npos)
      << missing.what();
  std::ofstream(dir / "a.yaml") << "base: b.yaml\n";
  std::ofstream(dir / "b.yaml") << "title: \"b\"\nbase: a.yaml\n";
  const auto loop = compose_error(YamlDocument::from_file(dir / "a.yaml"), {});
  EXPECT_EQ(loop.file, (dir / "b.yaml").string());
  EXPECT_EQ(loop.line, 2);
  EXPECT_NE(loop.message.find("in a loop"), std::string::npos) << loop.what();
}

// `--set PATH=VALUE`: the value replaces the scene's, or is added where the scene has none,
// before the sweep; it is checked as any value, its errors naming the argument.
TEST(SceneSettings, SetValuesAreCheckedAsTheScenesOwn) {
  const YamlDocument tiny = YamlDocument::from_string(kTiny, "tiny.yaml");
  const ContactScene scene = parse_contact_scene(
      compose_scene(tiny, {"law.friction.mu_s=0.3", "loading[0].slide.speed=3 mm/s",
                           "integrator.method=implicit", "loading[*].increments=7"}));
  const ContactCase& c = scene.cases.at(0);
  EXPECT_EQ(c.model.law.friction.mu_s, 0.3);
  EXPECT_DOUBLE_EQ(c.segments[0].velocity.norm(), 180.0);  // mm/min
  EXPECT_EQ(c.segments[0].increments, 7);
  EXPECT_EQ(scene.makeup.settings.size(), 4u);
  EXPECT_EQ(scene.makeup.settings[1], "loading[0].slide.speed=3 mm/s");

  struct Bad {
    const char* setting;
    const char* key;
    const char* fragment;
  };
  for (const Bad& b : {Bad{"law.friction.mu_s=-1", "law.friction.mu_s", "must be > 0, got -1"},
                       Bad{"law.friction.mu_ss=1", "law.friction.mu_ss", "did you mean 'mu_s'?"},
                       Bad{"lawz.friction.mu_s=1", "lawz", "did you mean 'law'?"},
                       Bad{"loading[3].increments=1", "loading[3].increments", "no element 3"},
                       Bad{"law.friction.mu_s.x=1", "law.friction.mu_s.x", "is not a mapping"},
                       Bad{"law..mu_s=1", "law..mu_s", "malformed --set path"},
                       Bad{"law.friction.mu_s", "", "expected PATH=VALUE"},
                       Bad{"law.friction.mu_s=[1", "law.friction.mu_s", "no YAML value"}}) {
    SCOPED_TRACE(b.setting);
    const InputError e = compose_error(tiny, {b.setting});
    EXPECT_EQ(e.file, std::string("--set ") + b.setting);
    EXPECT_EQ(e.line, 0);  // a command line argument has no lines
    EXPECT_EQ(e.key, b.key);
    EXPECT_NE(e.message.find(b.fragment), std::string::npos) << e.what();
  }
  // A later setting and a sweep win over an earlier one.
  const ContactScene swept = parse_contact_scene(
      compose_scene(YamlDocument::from_string(
                        kTiny + "sweep:\n  \"law.friction.mu_k\": [0.05, 0.06]\n", "t.yaml"),
                    {"law.friction.mu_k=0.07", "law.friction.mu_s=0.1", "law.friction.mu_s=0.2"}));
  ASSERT_EQ(swept.cases.size(), 2u);
  EXPECT_EQ(swept.cases[1].model.law.friction.mu_k, 0.06);
  EXPECT_EQ(swept.cases[1].model.law.friction.mu_s, 0.2);
  // A swept value of a base scene's sweep block names the base in its errors.
  const fs::path dir = subslip::testing::scratch_dir("scene_settings");
  std::ofstream(dir / "base.yaml") << kTiny + "sweep:\n  \"law.friction.mu_k\": [0.05, -1]\n";
  std::ofstream(dir / "s.yaml") << "base: base.yaml\n";
  const InputError e = compose_error(YamlDocument::from_file(dir / "s.yaml"), {});
  EXPECT_EQ(e.file, (dir / "base.yaml").string());
  EXPECT_EQ(e.line, 17);
  EXPECT_NE(e.message.find("(in sweep case 'mu_k=-1')"), std::string::npos) << e.what();
}

// ---------------------------------------------------------------- broken scenes

namespace {

struct Broken {
  const char* file;
  int line;  // 0: no line
  const char* key;
  const char* fragment;  // part of the message
};

// Names the case in test listings (ctest shows the parameter).
void PrintTo(const Broken& b, std::ostream* os) {
  *os << b.file;
}

class BrokenScene : public ::testing::TestWithParam<Broken> {};

}  // namespace

TEST_P(BrokenScene, RaisesInputErrorAtFileLineKey) {
  const Broken& b = GetParam();
  const fs::path path = kSource / "tests/data/scenes" / b.file;
  ASSERT_TRUE(fs::exists(path)) << path;
  try {
    load_contact_scene(path);
    FAIL() << b.file << " was accepted";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(e.file, path.string());
    EXPECT_EQ(e.line, b.line) << what;
    EXPECT_EQ(e.key, b.key) << what;
    const std::string where = path.string() + (b.line > 0 ? ":" + std::to_string(b.line) : "") +
                              ": " + (*b.key ? std::string(b.key) + ": " : "");
    EXPECT_EQ(what.rfind(where, 0), 0u) << what;
    EXPECT_NE(what.find(b.fragment), std::string::npos) << what;
  }
}

INSTANTIATE_TEST_SUITE_P(
    Table, BrokenScene,
    ::testing::Values(
        Broken{"unknown_key.yaml", 7, "law.overstress.eta", "did you mean 'eta_v'?"},
        Broken{"missing_key.yaml", 5, "law.friction.xi", "missing required key"},
        Broken{"missing_units.yaml", 0, "units", "missing required key"},
        Broken{"wrong_type.yaml", 5, "law.friction.mu_s", "expected a number, got 'abc'"},
        Broken{"quoted_number.yaml", 6, "law.subloading.u_tilde", "quoted string"},
        Broken{"nan_value.yaml", 5, "law.friction.kappa", "finite"},
        Broken{"range_r_hat.yaml", 7, "law.overstress.r_hat", "must be > 1, got 0.9"},
        Broken{"range_speed.yaml", 13, "loading[0].slide.speed", "must be >= 0"},
        Broken{"range_increments.yaml", 14, "loading[0].increments", "must be >= 1"},
        Broken{"range_growth.yaml", 15, "loading[0].growth", "must be > 0"},
        Broken{"range_alpha.yaml", 10, "contact.alpha_t", "must be > 0"},
        Broken{"range_normal_traction.yaml", 11, "contact.normal_traction", "must be > 0"},
        Broken{"zero_direction.yaml", 13, "loading[0].slide.direction", "non-zero"},
        Broken{"short_direction.yaml", 13, "loading[0].slide.direction", "expected 2 numbers"},
        Broken{"malformed.yaml", 14, "", "YAML syntax error"},
        Broken{"empty.yaml", 0, "", "expected a mapping"},
        Broken{"bad_unit.yaml", 3, "units.stress", "did you mean 'MPa'?"},
        Broken{"bad_scene_kind.yaml", 1, "scene", "did you mean 'contact'?"},
        Broken{"unknown_function.yaml", 6, "law.subloading.function", "cot, neg_log, reciprocal"},
        Broken{"bad_method.yaml", 16, "integrator.method", "forward_euler"},
        Broken{"distance_and_duration.yaml", 13, "loading[0].slide.duration", "not both"},
        Broken{"no_distance.yaml", 13, "loading[0].slide", "needs one of: distance, duration"},
        Broken{"hold_without_duration.yaml", 16, "loading[1].hold.duration",
               "missing required key"},
        Broken{"slide_and_hold.yaml", 17, "loading[1].hold", "not both"},
        Broken{"duplicate_key.yaml", 12, "contact.alpha_t", "duplicate key"},
        Broken{"rate_independent_eta.yaml", 7, "law.overstress.eta_v", "rate_independent"},
        Broken{"unknown_field.yaml", 17, "output.fields[2]", "did you mean 'ratio'?"},
        Broken{"fields_without_ratio.yaml", 17, "output.fields", "must include 'ratio'"},
        Broken{"bad_sweep_path.yaml", 17, "sweep[\"loading[0].slide.sped\"]",
               "did you mean 'speed'?"},
        Broken{"bad_sweep_index.yaml", 17, "sweep[\"loading[3].slide.speed\"]", "no element 3"},
        Broken{"malformed_sweep_path.yaml", 17, "sweep[\"loading[0]..speed\"]",
               "malformed sweep path"},
        Broken{"sweep_units.yaml", 17, "sweep[\"units.stress\"]", "cannot be swept"},
        Broken{"empty_sweep.yaml", 17, "sweep[\"loading[0].slide.speed\"]", "at least one value"},
        Broken{"bad_sweep_value.yaml", 18, "law.overstress.eta_v", "(in sweep case 'eta_v=-1')"}),
    [](const ::testing::TestParamInfo<Broken>& info) {
      std::string name = info.param.file;
      name = name.substr(0, name.find('.'));
      return name;
    });

// Every broken scene in tests/data/scenes is in the table above (a new file needs a row).
TEST(BrokenScenes, TableCoversEveryFile) {
  std::size_t files = 0;
  for (const auto& entry : fs::directory_iterator(kSource / "tests/data/scenes")) {
    if (entry.path().extension() == ".yaml") ++files;
  }
  EXPECT_EQ(files, 34u);
}

// ---------------------------------------------------------------- shipped scenes

TEST(ShippedScenes, EveryInputParses) {
  std::vector<fs::path> scenes;
  for (const auto& entry : fs::directory_iterator(kSource / "inputs")) {
    // Crystal scenes are checked in test_crystal_scene.cpp, fit files (`fit:`, not `scene:`)
    // in test_calibration.cpp.
    if (entry.path().extension() == ".yaml" &&
        !YamlDocument::from_file(entry.path()).root().has("fit") &&
        scene_kind(YamlDocument::from_file(entry.path()), {"contact", "crystal"}) == "contact")
      scenes.push_back(entry.path());
  }
  std::sort(scenes.begin(), scenes.end());
  ASSERT_GE(scenes.size(), 13u);
  for (const auto& path : scenes) {
    SCOPED_TRACE(path.string());
    ContactScene scene;
    ASSERT_NO_THROW(scene = load_contact_scene(path));
    EXPECT_FALSE(scene.title.empty());
    EXPECT_EQ(scene.units.stress, "MPa");
    EXPECT_EQ(scene.units.length, "mm");
    EXPECT_EQ(scene.units.time, "min");
    EXPECT_FALSE(scene.cases.empty());
  }
}

TEST(ShippedScenes, PaperSweepsHaveTheirCases) {
  const auto fig7 = load_contact_scene(kSource / "inputs/paper_fig7_r_hat.yaml");
  ASSERT_EQ(fig7.cases.size(), 20u);
  EXPECT_EQ(fig7.cases.front().name, "r_hat=1.2,speed=0.1");
  EXPECT_EQ(fig7.cases.back().name, "r_hat=6.4,speed=1000");
  EXPECT_DOUBLE_EQ(fig7.cases.back().model.law.overstress.r_hat, 6.4);
  EXPECT_DOUBLE_EQ(fig7.cases.back().model.law.overstress.eta_v, 1000.0);
  EXPECT_EQ(load_contact_scene(kSource / "inputs/paper_fig9_peak_bottom.yaml").cases.size(), 17u);
  const auto fig11a = load_contact_scene(kSource / "inputs/paper_fig11a_exponential.yaml");
  ASSERT_EQ(fig11a.cases.size(), 5u);
  EXPECT_DOUBLE_EQ(fig11a.cases[0].model.law.friction.kappa, 0.2);
  EXPECT_DOUBLE_EQ(fig11a.cases[0].model.law.friction.xi, 0.009);
  EXPECT_DOUBLE_EQ(fig11a.cases[4].segments[0].velocity.norm(), 200.0);
  const auto fig11b = load_contact_scene(kSource / "inputs/paper_fig11b_power.yaml");
  EXPECT_EQ(fig11b.cases[0].model.law.overstress.form, law::OverstressForm::power);
}
