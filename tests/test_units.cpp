// Units of scene values (include/subslip/model/units.hpp): parsing unit names, exact conversions,
// values written with a unit in a scene, and the physics: one physical scene written in
// MPa/mm/s, in GPa/um/min, and in GPa/um/min with its values given in MPa/mm/s, run through the
// contact driver and the crystal driver, gives the same results once the outputs are converted.
#include <gtest/gtest.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "scratch_dir.hpp"
#include "shell_command.hpp"
#include "single_thread.hpp"
#include "subslip/contact/contact_point.hpp"
#include "subslip/crystal/phase_builder.hpp"
#include "subslip/history/contact_history.hpp"
#include "subslip/io/contact_scene.hpp"
#include "subslip/io/crystal_scene.hpp"
#include "subslip/io/h5_writer.hpp"
#include "subslip/io/input_error.hpp"
#include "subslip/io/units.hpp"

using namespace subslip;
using namespace subslip::io;

namespace {

Unit unit(const char* name) {
  const auto u = parse_unit(name);
  EXPECT_TRUE(u.has_value()) << name;
  return u.value_or(Unit{});
}

// The double nearest to the decimal `text` (from_chars rounds correctly).
double decimal(const std::string& text) {
  double x = 0.0;
  std::from_chars(text.data(), text.data() + text.size(), x);
  return x;
}

}  // namespace

TEST(Units, BaseUnitsAndQuotients) {
  EXPECT_EQ(unit("MPa").dimension, dimension::stress);
  EXPECT_EQ(unit("MPa").scale, (Scale{6, 0}));
  EXPECT_EQ(unit("cm").scale, (Scale{-2, 0}));
  EXPECT_EQ(unit("h").scale, (Scale{0, 2}));
  EXPECT_EQ(unit("mm/min").dimension, dimension::velocity);
  EXPECT_EQ(unit("mm/min").scale, (Scale{-3, -1}));
  EXPECT_EQ(unit("1/s").dimension, dimension::per_time);
  EXPECT_EQ(unit("min/mm").dimension, dimension::time_per_length);
  EXPECT_EQ(unit("GPa/um").dimension, dimension::stiffness);
  EXPECT_EQ(unit("GPa/um").scale, (Scale{15, 0}));
  // The micro sign and the Greek mu both mean um, stored as "um".
  EXPECT_EQ(unit("\xC2\xB5m").name, "um");
  EXPECT_EQ(unit("\xCE\xBCm/s").name, "um/s");
  EXPECT_EQ(unit(" mm / min ").name, "mm/min");
  for (const char* bad : {"", "mpa", "MPa/MPa", "mm/m", "1/1", "m/s/s", "1", "/s", "mm/", "ft",
                          "sec", "mm*s", "kg"}) {
    EXPECT_FALSE(parse_unit(bad).has_value()) << bad;
  }
  EXPECT_EQ(describe(dimension::velocity), "length/time");
  EXPECT_EQ(describe(dimension::per_time), "1/time");
  EXPECT_EQ(unit_names_of(dimension::per_time),
            (std::vector<std::string>{"1/s", "1/ms", "1/min", "1/h"}));
  EXPECT_EQ(unit_names_of(dimension::velocity).size(), 5u * 4u);
}

// Factors are exact (powers of ten, 60, 3600): a conversion is one correctly rounded
// operation where the factor or its inverse is an integer, so 9 mm is the double nearest to
// 0.009 m (9 * 1e-3 is not), and 23 s is 23 / 60 min rounded once.
TEST(Units, ConversionsAreCorrectlyRounded) {
  for (int k = 1; k <= 2000; ++k) {
    const double x = k;
    SCOPED_TRACE(k);
    ASSERT_EQ(convert(x, unit("mm").scale, unit("m").scale), decimal(std::to_string(k) + "e-3"));
    ASSERT_EQ(convert(x, unit("MPa").scale, unit("GPa").scale), decimal(std::to_string(k) + "e-3"));
    ASSERT_EQ(convert(x, unit("nm").scale, unit("mm").scale), decimal(std::to_string(k) + "e-6"));
    ASSERT_EQ(convert(x, unit("s").scale, unit("min").scale), x / 60.0);
    ASSERT_EQ(convert(x, unit("s").scale, unit("h").scale), x / 3600.0);
    ASSERT_EQ(convert(x, unit("h").scale, unit("s").scale), x * 3600.0);
    ASSERT_EQ(convert(x, unit("GPa/um").scale, unit("MPa/mm").scale), x * 1e6);
    // m/min -> mm/s: 1000/60 = 50/3: the product by 50 is exact, the division rounds once.
    ASSERT_EQ(convert(x, unit("m/min").scale, unit("mm/s").scale), x * 50.0 / 3.0);
    ASSERT_EQ(convert(x, unit("1/min").scale, unit("1/h").scale), x * 60.0);
    ASSERT_EQ(convert(x, unit("min/mm").scale, unit("s/um").scale), x * 3.0 / 50.0);
  }
  EXPECT_EQ(to_si(1.0, unit("GPa").scale), 1e9);
  EXPECT_EQ(to_si(1.0, unit("mm/min").scale), 1.0 / 60000.0);
}

TEST(Units, SceneUnitSystemNamesEveryDerivedUnit) {
  const Units u{"GPa", "um", "h"};
  EXPECT_EQ(u.unit(dimension::velocity).name, "um/h");
  EXPECT_EQ(u.unit(dimension::per_length).name, "1/um");
  EXPECT_EQ(u.unit(dimension::time_per_length).name, "h/um");
  EXPECT_EQ(u.unit(dimension::stiffness).name, "GPa/um");
  EXPECT_EQ(u.unit(dimension::none).name, "1");
  EXPECT_EQ(u.unit(dimension::stiffness).scale, (Scale{15, 0}));
  EXPECT_EQ(u.unit(dimension::velocity).scale, (Scale{-6, -2}));
  EXPECT_EQ(u.velocity(), u.unit(dimension::velocity).name);
}

// ---------------------------------------------------------------- values with units in scenes

namespace {

ContactScene contact_scene(const std::string& text) {
  return parse_contact_scene(YamlDocument::from_string(text, "units.yaml"));
}

CrystalScene crystal_scene(const std::string& text) {
  return parse_crystal_scene(YamlDocument::from_string(text, "units.yaml"));
}

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

// One contact history: a graded slide through the peak, a hold with a normal ramp, a slide in
// another direction given as a velocity, and a normal approach. `law`, `contact` and
// `loading` are written in the units named by `units`.
struct ContactText {
  std::string units, law, contact, loading;

  std::string text() const {
    return "scene: contact\nunits: " + units + "\nlaw:\n" + law + "contact: " + contact +
           "\nloading:\n" + loading;
  }
};

// MPa, mm, s.
const ContactText kContactMpaMmS{
    "{stress: MPa, length: mm, time: s}",
    "  friction: {mu_s: 0.097, mu_k: 0.085, kappa: 0.2, xi: 1.5e-4}\n"
    "  subloading: {function: cot, u_tilde: 80}\n"
    "  overstress: {form: exponential, eta_v: 57000, n: 16, r_hat: 1.8}\n",
    "{alpha_n: 1.0e6, alpha_t: 1.0e6, normal_traction: 5.56}",
    "  - slide: {speed: 0.5, direction: [1, 0], distance: 2}\n"
    "    increments: 400\n"
    "    growth: 1.01\n"
    "  - hold: {duration: 600}\n"
    "    increments: 20\n"
    "    growth: 1.2\n"
    "    normal: {traction: 6}\n"
    "  - slide: {velocity: [0.2, 0.1], duration: 6}\n"
    "    increments: 200\n"
    "    normal: {velocity: 1.0e-7}\n"};

// The same in GPa, um, min, converted by hand (kappa 0.2 /mm = 2e-4 /um, xi 1.5e-4 /s = 0.009
// /min, eta_v 57000 s/mm = 0.95 min/um, alpha 1e6 MPa/mm = 1 GPa/um, 0.5 mm/s = 30000 um/min).
const ContactText kContactGpaUmMin{
    "{stress: GPa, length: um, time: min}",
    "  friction: {mu_s: 0.097, mu_k: 0.085, kappa: 2.0e-4, xi: 0.009}\n"
    "  subloading: {function: cot, u_tilde: 0.08}\n"
    "  overstress: {form: exponential, eta_v: 0.95, n: 16, r_hat: 1.8}\n",
    "{alpha_n: 1, alpha_t: 1, normal_traction: 0.00556}",
    "  - slide: {speed: 30000, direction: [1, 0], distance: 2000}\n"
    "    increments: 400\n"
    "    growth: 1.01\n"
    "  - hold: {duration: 10}\n"
    "    increments: 20\n"
    "    growth: 1.2\n"
    "    normal: {traction: 0.006}\n"
    "  - slide: {velocity: [12000, 6000], duration: 0.1}\n"
    "    increments: 200\n"
    "    normal: {velocity: 6.0e-3}\n"};

// GPa, um, min as the scene's units, every dimensional value given in MPa, mm, s.
const ContactText kContactGpaUmMinWithUnits{
    "{stress: GPa, length: um, time: min}",
    "  friction: {mu_s: 0.097, mu_k: 0.085, kappa: 0.2 1/mm, xi: 1.5e-4 1/s}\n"
    "  subloading: {function: cot, u_tilde: 80 1/mm}\n"
    "  overstress: {form: exponential, eta_v: 57000 s/mm, n: 16, r_hat: 1.8}\n",
    "{alpha_n: 1.0e6 MPa/mm, alpha_t: 1.0e6 MPa/mm, normal_traction: 5.56 MPa}",
    "  - slide: {speed: 0.5 mm/s, direction: [1, 0], distance: 2 mm}\n"
    "    increments: 400\n"
    "    growth: 1.01\n"
    "  - hold: {duration: 600 s}\n"
    "    increments: 20\n"
    "    growth: 1.2\n"
    "    normal: {traction: 6 MPa}\n"
    "  - slide: {velocity: [0.2 mm/s, 0.1 mm/s], duration: 6 s}\n"
    "    increments: 200\n"
    "    normal: {velocity: 1.0e-7 mm/s}\n"};

}  // namespace

TEST(UnitsInScenes, ValuesWithAUnitAreConvertedIntoTheSceneUnits) {
  const ContactScene plain = contact_scene(kContactGpaUmMin.text());
  const ContactScene with_units = contact_scene(kContactGpaUmMinWithUnits.text());
  ASSERT_EQ(with_units.cases.size(), 1u);
  const auto& a = plain.cases[0];
  const auto& b = with_units.cases[0];
  // Conversions by one correctly rounded operation equal the hand-written decimals exactly.
  EXPECT_EQ(b.model.stiffness.alpha_n, a.model.stiffness.alpha_n);
  EXPECT_EQ(b.model.initial_normal_traction, a.model.initial_normal_traction);
  EXPECT_EQ(b.model.law.subloading.u_tilde, a.model.law.subloading.u_tilde);
  EXPECT_EQ(b.model.law.friction.kappa, a.model.law.friction.kappa);
  EXPECT_EQ(b.segments[0].velocity.x(), a.segments[0].velocity.x());
  EXPECT_EQ(b.segments[0].duration, a.segments[0].duration);
  EXPECT_EQ(b.segments[1].duration, a.segments[1].duration);
  EXPECT_EQ(b.segments[1].normal_traction, a.segments[1].normal_traction);
  EXPECT_EQ(b.segments[2].duration, a.segments[2].duration);
  // 1.5e-4 and 0.2 are not binary fractions: their conversions are within one rounding.
  EXPECT_NEAR(b.model.law.friction.xi, a.model.law.friction.xi, 1e-16 * a.model.law.friction.xi);
  EXPECT_NEAR(b.model.law.overstress.eta_v, a.model.law.overstress.eta_v,
              2e-16 * a.model.law.overstress.eta_v);
  EXPECT_NEAR(b.segments[2].velocity.y(), a.segments[2].velocity.y(),
              2e-16 * a.segments[2].velocity.y());
  EXPECT_NEAR(b.segments[2].normal_velocity, a.segments[2].normal_velocity,
              2e-16 * a.segments[2].normal_velocity);
  // The scene's units are what the outputs are labelled with.
  EXPECT_EQ(with_units.units.stress, "GPa");
  EXPECT_EQ(with_units.units.velocity(), "um/min");
}

TEST(UnitsInScenes, UnitBlockTakesEveryLengthSpelling) {
  for (const char* length : {"m", "cm", "mm", "um", "\xC2\xB5m", "\xCE\xBCm", "nm"}) {
    const ContactScene s = contact_scene(
        replaced(kContactMpaMmS.text(), "length: mm", std::string("length: ") + length));
    const std::string expected = std::string(length).size() > 2 ? "um" : length;
    EXPECT_EQ(s.units.length, expected) << length;
  }
}

// Crystal values: stresses (elastic constants, tau0, stress targets), 1/time (L, xi), time
// (eta_v, durations); kappa and u_tilde are per unit slip and take no unit.
TEST(UnitsInScenes, CrystalValuesWithUnits) {
  const std::string base = R"(scene: crystal
units: {stress: MPa, time: s}
phase:
  families: [fcc_111_110]
  elasticity: {type: cubic, C11: 168.4 GPa, C12: 121400, C44: 75.4 GPa}
  tau0: 10000 kPa
  law:
    friction: {mu_s: 1.0, mu_k: 3.0, kappa: 5.0, xi: 36 1/h}
    subloading: {function: cot, u_tilde: 200}
    overstress: {form: exponential, eta_v: 1 ms, n: 16, r_hat: 1.6}
  per_family:
    fcc_111_110: {tau0: 0.015625 GPa}
orientations:
  euler_deg: [[0, 0, 0]]
loading:
  - L: [[x, 0, 0], [0, x, 0], [0, 0, 6 1/h]]
    stress: [[0, x, x], [x, 0, x], [x, x, x]]
    duration: 1 min
    increments: 3
)";
  const CrystalScene s = crystal_scene(base);
  const CrystalCase& c = s.cases[0];
  // 168.4 is not a binary fraction: its product by 1000 is within one rounding of 168400.
  EXPECT_DOUBLE_EQ(c.phase.stiffness(0, 0), 168400.0);
  EXPECT_EQ(c.phase.stiffness(0, 1), 121400.0);
  EXPECT_DOUBLE_EQ(c.phase.stiffness(3, 3), 2.0 * 75400.0);  // Mandel: 2 C44
  EXPECT_EQ(c.phase.family_settings[0].tau0, 15.625);
  EXPECT_EQ(c.phase.family_settings[0].law.friction.xi, 0.01);
  EXPECT_EQ(c.phase.family_settings[0].law.overstress.eta_v, 0.001);
  EXPECT_EQ(c.segments[0].velocity_gradient(2, 2), 6.0 / 3600.0);
  EXPECT_EQ(c.segments[0].duration, 60.0);
  // Per unit slip: a length in kappa's unit is refused.
  try {
    crystal_scene(replaced(base, "kappa: 5.0", "kappa: 5.0 1/mm"));
    FAIL() << "kappa with a unit was accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.line, 8);
    EXPECT_EQ(e.key, "phase.law.friction.kappa");
    EXPECT_NE(e.message.find("dimensionless"), std::string::npos) << e.what();
  }
}

// An unknown unit: one error naming the file, the line, the key, a near unit and the units the
// key takes, and the supported ones; a unit of another dimension names both dimensions.
TEST(UnitsInScenes, UnknownOrMismatchedUnitIsOneError) {
  struct Bad {
    std::string from, to, key;
    int line;
    std::vector<std::string> fragments;
  };
  const std::vector<Bad> bad = {
      {"normal_traction: 5.56",
       "normal_traction: 5.56 Mpa",
       "contact.normal_traction",
       7,
       {"unknown unit 'Mpa'; did you mean 'MPa'?", "it takes Pa, kPa, MPa or GPa",
        "supported: stress Pa kPa MPa GPa; length m cm mm um nm", "time s ms min h"}},
      {"speed: 0.5",
       "speed: 0.5 furlong/fortnight",
       "loading[0].slide.speed",
       9,
       {"unknown unit 'furlong/fortnight'",
        "a length unit (m, cm, mm, um, nm) / a time unit "
        "(s, ms, min, h)"}},
      {"speed: 0.5",
       "speed: 0.5 MPa",
       "loading[0].slide.speed",
       9,
       {"'MPa' is a unit of stress, but this value's dimension is length/time"}},
      {"duration: 600",
       "duration: 600 1/s",
       "loading[1].hold.duration",
       12,
       {"'1/s' is a unit of 1/time, but this value's dimension is time", "s, ms, min or h"}},
      {"mu_s: 0.097",
       "mu_s: 0.097 MPa",
       "law.friction.mu_s",
       4,
       {"this value is dimensionless (unit 1), write it without a unit"}},
      {"increments: 20", "increments: 20 s", "loading[1].increments", 13, {"expected an integer"}},
      {"distance: 2",
       "distance: 1e400 mm",
       "loading[0].slide.distance",
       9,
       {"out of the range of double precision"}},
      {"alpha_n: 1.0e6",
       "alpha_n: 1.0e300 GPa/nm",
       "contact.alpha_n",
       7,
       {"out of the range of double precision once converted to MPa/mm"}},
      {"distance: 2",
       "distance: inf mm",
       "loading[0].slide.distance",
       9,
       {"must be a finite number, got inf mm"}},
      {"speed: 0.5",
       "speed: -0.5 mm/min",
       "loading[0].slide.speed",
       9,
       {"must be >= 0, got -0.5 mm/min (-0.008333"}},
  };
  for (const Bad& b : bad) {
    SCOPED_TRACE(b.to);
    try {
      contact_scene(replaced(kContactMpaMmS.text(), b.from, b.to));
      FAIL() << "accepted";
    } catch (const InputError& e) {
      EXPECT_EQ(e.file, "units.yaml");
      EXPECT_EQ(e.line, b.line) << e.what();
      EXPECT_EQ(e.key, b.key) << e.what();
      for (const auto& f : b.fragments) EXPECT_NE(e.message.find(f), std::string::npos) << e.what();
    }
  }
  // In the units block: the names it takes.
  try {
    contact_scene(replaced(kContactMpaMmS.text(), "length: mm", "length: ft"));
    FAIL() << "length: ft accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.key, "units.length");
    EXPECT_NE(e.message.find("expected one of: m, cm, mm, um"), std::string::npos) << e.what();
  }
}

// The result file states the scene's units: /units, each dataset's unit and each parameter's
// X.unit, with the values converted into them (and um stored for µm).
TEST(UnitsInScenes, ResultFileStatesTheSceneUnits) {
  namespace fs = std::filesystem;
  const fs::path dir = subslip::testing::scratch_dir("units");
  std::string text = kContactGpaUmMinWithUnits.text();
  text = replaced(text, "{stress: GPa, length: um, time: min}",
                  "{stress: GPa, length: \xC2\xB5m, time: h}");
  std::ofstream(dir / "h.yaml") << text;
  std::string command = "'";
  command.append(SUBSLIP_BINARY).append("' run -q '").append((dir / "h.yaml").string());
  command.append("' -o '").append((dir / "h.h5").string()).append("' 2>&1");
  const auto run = subslip::testing::run_command(command);
  ASSERT_EQ(run.code, 0) << run.out;
  const h5::File file = h5::File::open_read(dir / "h.h5");
  const h5::Group root = file.root();
  const h5::Group units = root.open_group("units");
  EXPECT_EQ(units.attribute_string("stress"), "GPa");
  EXPECT_EQ(units.attribute_string("length"), "um");
  EXPECT_EQ(units.attribute_string("time"), "h");
  const h5::Group base = root.open_group("cases").open_group("base");
  EXPECT_EQ(base.open_dataset("time").attribute_string("unit"), "h");
  EXPECT_EQ(base.open_dataset("slip_path").attribute_string("unit"), "um");
  EXPECT_EQ(base.attribute_string("alpha_t.unit"), "GPa/um");
  EXPECT_EQ(base.attribute_double("alpha_t"), 1.0);  // 1e6 MPa/mm
  EXPECT_EQ(base.attribute_string("eta_v.unit"), "h/um");
  EXPECT_NEAR(base.attribute_double("eta_v"), 57000.0 / 3600.0 / 1000.0, 1e-16);
  // 600 s + 6 s of the hold and the last slide, 2 mm at 0.5 mm/s before: 610 s in hours.
  EXPECT_NEAR(base.open_dataset("time").read_doubles().back(), 610.0 / 3600.0, 1e-15);
  fs::remove_all(dir);
}

// ---------------------------------------------------------------- one physical scene, three ways

namespace {

// Outputs of a contact run, each state converted to SI by `to_si_of`.
struct ContactSeries {
  std::vector<std::vector<double>> columns;  // time, slip x, y, path, traction x, y, n, ratio,
                                             // mu, r, r_s, vp_slip, vp_rate
};

ContactSeries run_contact(const ContactScene& scene) {
  const Units& u = scene.units;
  const Scale time = u.unit(dimension::time).scale, length = u.unit(dimension::length).scale,
              stress = u.unit(dimension::stress).scale, speed = u.unit(dimension::velocity).scale;
  ContactSeries out;
  out.columns.resize(13);
  const ContactCase& c = scene.cases.at(0);
  history::run_history(c.model, c.segments, c.integrator, [&](const contact::ContactState& s, int) {
    const double row[13] = {to_si(s.time, time),
                            to_si(s.slip.x(), length),
                            to_si(s.slip.y(), length),
                            to_si(s.slip_path, length),
                            to_si(s.traction_t.x(), stress),
                            to_si(s.traction_t.y(), stress),
                            to_si(s.traction_n, stress),
                            s.traction_ratio(),
                            s.law.mu,
                            s.r,
                            s.law.r_s,
                            to_si(s.vp_slip, length),
                            to_si(s.vp_rate, speed)};
    for (int k = 0; k < 13; ++k) out.columns[k].push_back(row[k]);
  });
  return out;
}

// The largest difference between two runs' series, each relative to the largest magnitude of
// its series (so that values passing through zero are compared at the series' scale).
double largest_difference(const std::vector<std::vector<double>>& a,
                          const std::vector<std::vector<double>>& b) {
  EXPECT_EQ(a.size(), b.size());
  double worst = 0.0;
  for (std::size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(a[k].size(), b[k].size()) << "series " << k;
    if (a[k].size() != b[k].size()) return INFINITY;
    double scale = 0.0;
    for (double x : a[k]) scale = std::max(scale, std::abs(x));
    for (std::size_t i = 0; i < a[k].size(); ++i) {
      const double d = std::abs(a[k][i] - b[k][i]);
      worst = std::max(worst, scale > 0.0 ? d / scale : d);
    }
  }
  return worst;
}

}  // namespace

// The units enter only through the inputs, whose conversions round differently (168.4 GPa is
// not 168400 MPa / 1000 to the last bit), so the runs agree to round-off, amplified where the
// problem amplifies it: the traction alpha_t (du - ds) of a stiff contact cancels du ~ ds, so its
// relative round-off is about eps alpha_t du / f_t (docs/integrators.md, "Adaptive backward Euler"). The bound is
// 8 eps times the larger of that amplification and the number of increments (sums of times and
// slips accumulate one rounding per increment).
TEST(UnitsPhysics, ContactSceneInThreeUnitSystemsGivesOneResult) {
  const ContactScene scene_a = contact_scene(kContactMpaMmS.text());
  const ContactSeries a = run_contact(scene_a);
  const ContactSeries b = run_contact(contact_scene(kContactGpaUmMin.text()));
  const ContactSeries c = run_contact(contact_scene(kContactGpaUmMinWithUnits.text()));
  ASSERT_EQ(a.columns[0].size(), 1u + 400u + 20u + 200u);
  // The history reaches the peak and slides on: the comparison covers the law's whole range.
  const auto& ratio = a.columns[7];
  EXPECT_GT(*std::max_element(ratio.begin(), ratio.end()), 0.12);

  const ContactCase& ca = scene_a.cases[0];
  double amplification = 0.0, increments = 0.0;
  for (const auto& seg : ca.segments) {
    const auto dt = contact::increment_lengths(seg);
    increments += static_cast<double>(dt.size());
    const double du = seg.velocity.norm() * *std::max_element(dt.begin(), dt.end());
    amplification = std::max(amplification,
                             ca.model.stiffness.alpha_t * du /
                                 (ca.model.law.friction.mu_k * ca.model.initial_normal_traction));
  }
  const double bound =
      8.0 * std::numeric_limits<double>::epsilon() * std::max(amplification, increments);
  const double ab = largest_difference(a.columns, b.columns);
  const double ac = largest_difference(a.columns, c.columns);
  const double bc = largest_difference(b.columns, c.columns);
  std::printf(
      "contact: largest relative differences MPa/mm/s vs GPa/um/min %.3g, vs GPa/um/min "
      "with units %.3g, between the two GPa/um/min %.3g (bound %.3g: amplification "
      "%.3g, %.0f increments)\n",
      ab, ac, bc, bound, amplification, increments);
  EXPECT_LT(ab, bound);
  EXPECT_LT(ac, bound);
  EXPECT_LT(bc, bound);
}

namespace {

// A crystal history: uniaxial tension under mixed control, a stress-controlled unloading and
// hold (relaxation with recovery, xi > 0), then simple shear under velocity control.
const std::string kCrystalMpaS = R"(scene: crystal
units: {stress: MPa, time: s}
phase:
  families: [fcc_111_110]
  elasticity: {type: cubic, C11: 168400, C12: 121400, C44: 75400}
  tau0: 10.0
  law:
    friction: {mu_s: 1.6, mu_k: 14.8, kappa: 20.0, xi: 1.5e-3}
    subloading: {function: cot, u_tilde: 200}
    overstress: {form: exponential, eta_v: 6.0e-3, n: 16, r_hat: 1.6}
orientations:
  random: {count: 6, seed: 3}
loading:
  - L: [[x, 0, 0], [0, x, 0], [0, 0, 1.0e-3]]
    stress: [[0, x, x], [x, 0, x], [x, x, x]]
    duration: 30
    increments: 60
  - L: [[x, 0, 0], [0, x, 0], [0, 0, x]]
    stress: [[0, x, x], [x, 0, x], [x, x, 20]]
    duration: 120
    increments: 30
    growth: 1.1
  - L: [[0, 2.0e-3, 0], [0, 0, 0], [0, 0, 0]]
    duration: 6
    increments: 30
integrator: {method: implicit, residual_tolerance: 1.0e-14}
)";

// By hand in GPa and min: xi 1.5e-3 /s = 0.09 /min, eta_v 6e-3 s = 1e-4 min, 1e-3 /s = 0.06
// /min, 30 s = 0.5 min, 20 MPa = 0.02 GPa.
const std::string kCrystalGpaMin = R"(scene: crystal
units: {stress: GPa, time: min}
phase:
  families: [fcc_111_110]
  elasticity: {type: cubic, C11: 168.4, C12: 121.4, C44: 75.4}
  tau0: 0.01
  law:
    friction: {mu_s: 1.6, mu_k: 14.8, kappa: 20.0, xi: 0.09}
    subloading: {function: cot, u_tilde: 200}
    overstress: {form: exponential, eta_v: 1.0e-4, n: 16, r_hat: 1.6}
orientations:
  random: {count: 6, seed: 3}
loading:
  - L: [[x, 0, 0], [0, x, 0], [0, 0, 0.06]]
    stress: [[0, x, x], [x, 0, x], [x, x, x]]
    duration: 0.5
    increments: 60
  - L: [[x, 0, 0], [0, x, 0], [0, 0, x]]
    stress: [[0, x, x], [x, 0, x], [x, x, 0.02]]
    duration: 2
    increments: 30
    growth: 1.1
  - L: [[0, 0.12, 0], [0, 0, 0], [0, 0, 0]]
    duration: 0.1
    increments: 30
integrator: {method: implicit, residual_tolerance: 1.0e-14}
)";

// GPa and min, with the values of kCrystalMpaS given in MPa and s.
const std::string kCrystalGpaMinWithUnits = R"(scene: crystal
units: {stress: GPa, time: min}
phase:
  families: [fcc_111_110]
  elasticity: {type: cubic, C11: 168400 MPa, C12: 121400 MPa, C44: 75400 MPa}
  tau0: 10.0 MPa
  law:
    friction: {mu_s: 1.6, mu_k: 14.8, kappa: 20.0, xi: 1.5e-3 1/s}
    subloading: {function: cot, u_tilde: 200}
    overstress: {form: exponential, eta_v: 6.0e-3 s, n: 16, r_hat: 1.6}
orientations:
  random: {count: 6, seed: 3}
loading:
  - L: [[x, 0, 0], [0, x, 0], [0, 0, 1.0e-3 1/s]]
    stress: [[0, x, x], [x, 0, x], [x, x, x]]
    duration: 30 s
    increments: 60
  - L: [[x, 0, 0], [0, x, 0], [0, 0, x]]
    stress: [[0, x, x], [x, 0, x], [x, x, 20 MPa]]
    duration: 120 s
    increments: 30
    growth: 1.1
  - L: [[0, 2.0e-3 1/s, 0], [0, 0, 0], [0, 0, 0]]
    duration: 6 s
    increments: 30
integrator: {method: implicit, residual_tolerance: 1.0e-14}
)";

// Macro time, stress, strain, F and the grains' CRSS and slip, in SI.
std::vector<std::vector<double>> run_crystal(const CrystalScene& scene) {
  const subslip::testing::SingleThread one_thread;
  const CrystalCase& c = scene.cases.at(0);
  const Scale time = scene.units.unit(dimension::time).scale;
  const Scale stress = scene.units.unit(dimension::stress).scale;
  std::vector<std::vector<double>> columns;
  auto aggregate = crystal::build_taylor_aggregate(c.phase, c.orientations);
  const int grains = aggregate->grain_count(), systems = aggregate->slip_count();
  std::vector<double> crss(static_cast<std::size_t>(grains * systems));
  std::vector<double> slip(crss.size());
  aggregate->run(c.segments, c.options,
                 [&](const crystal::MacroState& m, const crystal::GrainFields& f) {
                   std::vector<double> row = {to_si(m.time, time)};
                   for (int k = 0; k < 9; ++k) {
                     row.push_back(to_si(m.stress(k / 3, k % 3), stress));
                     row.push_back(m.strain(k / 3, k % 3));
                     row.push_back(m.deformation_gradient(k / 3, k % 3));
                   }
                   f.values(crystal::GrainField::crss, crss.data());
                   f.values(crystal::GrainField::slip, slip.data());
                   for (double x : crss) row.push_back(to_si(x, stress));
                   row.insert(row.end(), slip.begin(), slip.end());
                   if (columns.empty()) columns.resize(row.size());
                   for (std::size_t k = 0; k < row.size(); ++k) columns[k].push_back(row[k]);
                 });
  return columns;
}

}  // namespace

TEST(UnitsPhysics, CrystalSceneInThreeUnitSystemsGivesOneResult) {
  const auto a = run_crystal(crystal_scene(kCrystalMpaS));
  const auto b = run_crystal(crystal_scene(kCrystalGpaMin));
  const auto c = run_crystal(crystal_scene(kCrystalGpaMinWithUnits));
  ASSERT_FALSE(a.empty());
  ASSERT_EQ(a[0].size(), 1u + 60u + 30u + 30u);
  // The run yields (stress_33 near mu_s tau0 times a Taylor factor) and then relaxes.
  const auto& s33 = a[1 + 3 * 8];
  EXPECT_GT(*std::max_element(s33.begin(), s33.end()), 30e6);
  // Round-off: a few roundings per increment and series (the grain Newton solves converge to
  // 1e-14 in traction-ratio units, below the accumulated round-off).
  const double increments = static_cast<double>(a[0].size() - 1);
  const double bound = 8.0 * std::numeric_limits<double>::epsilon() * increments;
  const double ab = largest_difference(a, b);
  const double ac = largest_difference(a, c);
  const double bc = largest_difference(b, c);
  std::printf(
      "crystal: largest relative differences MPa/s vs GPa/min %.3g, vs GPa/min with "
      "units %.3g, between the two GPa/min %.3g (bound %.3g)\n",
      ab, ac, bc, bound);
  EXPECT_LT(ab, bound);
  EXPECT_LT(ac, bound);
  EXPECT_LT(bc, bound);
}
