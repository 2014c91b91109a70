// Output at chosen points: `output.at` names times, loading strains or sliding
// distances (a list, or a linear or logarithmic spacing); fixed increments are split and
// adaptive steps shortened so that a step ends on every point, and the rows are exactly there
// (no interpolation); per-grain rows at the coarser `output.grains_at`; bad input is one error
// naming file, line and key.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "child_process.hpp"
#include "scene_text.hpp"
#include "scratch_dir.hpp"
#include "subslip/driver/crystal_run.hpp"
#include "subslip/history/contact_history.hpp"
#include "subslip/integrators/step_control.hpp"
#include "subslip/io/contact_output.hpp"
#include "subslip/io/contact_scene.hpp"
#include "subslip/io/crystal_output.hpp"
#include "subslip/io/crystal_scene.hpp"
#include "subslip/io/h5_writer.hpp"
#include "subslip/io/output_points.hpp"
#include "subslip/io/result_file.hpp"
#include "subslip/io/result_protocol.hpp"

namespace fs = std::filesystem;
using namespace subslip;
using namespace subslip::io;
using subslip::integrators::AdaptiveSegment;
using subslip::integrators::fixed_steps;

namespace {

fs::path scratch_dir() {
  return subslip::testing::scratch_dir("output_points");
}

// ---- scenes

// Copper in uniaxial tension along z at 1e-3 /s to 2 % (lateral stresses free), then a hold of
// 10 s (the loading strain stands still) and 1 % more; `kinematics`, `integrator` and `output`
// vary.
std::string crystal_scene(const std::string& kinematics, const std::string& integrator,
                          const std::string& output) {
  return subslip::testing::copper_scene_start() + "  kinematics: " + kinematics + R"(
orientations:
  random: {count: 3, seed: 11}
loading:
  - L: [[x, 0, 0], [0, x, 0], [0, 0, 1.0e-3]]
    stress: [[0, x, x], [x, 0, x], [x, x, x]]
    strain: 0.02
    increments: 25
    growth: 1.05
  - L: [[x, 0, 0], [0, x, 0], [0, 0, 0]]
    stress: [[0, x, x], [x, 0, x], [x, x, x]]
    duration: 10
    increments: 4
  - L: [[x, 0, 0], [0, x, 0], [0, 0, 1.0e-3]]
    stress: [[0, x, x], [x, 0, x], [x, x, x]]
    strain: 0.01
    increments: 10
)" + integrator +
         output;
}

CrystalScene parsed(const std::string& text) {
  return parse_crystal_scene(YamlDocument::from_string(text, "points.yaml"));
}

// Runs a crystal scene into a finished file.
fs::path run_crystal(const CrystalScene& scene, const fs::path& path) {
  h5::File file = h5::File::create(path, true);
  CrystalResultSink sink(scene, file, {});
  for (const auto& r : driver::run_crystal_scene(scene, sink))
    EXPECT_TRUE(r.failure.empty()) << r.failure;
  close_and_finish(file);
  return path;
}

std::vector<double> read(const fs::path& file, const std::string& path) {
  return h5::File::open_read(file).root().open_dataset(path).read_doubles();
}

// The strains asked for (the 2 % of the first segment falls on its end, the hold has none).
const std::vector<double> kStrains = {0.0001, 0.0015, 0.005, 0.0123, 0.02, 0.021, 0.0299, 0.03};

std::string strains_output() {
  std::string list;
  for (double e : kStrains) list += (list.empty() ? "" : ", ") + std::to_string(e);
  return "output: {macro: [time, strain, stress], at: {strain: [" + list + "]}}\n";
}

// The time of loading strain e: 1000 e in the first segment, 10 s later after the hold.
double time_of_strain(double e) {
  return e <= 0.02 ? e / 1.0e-3 : 20.0 + 10.0 + (e - 0.02) / 1.0e-3;
}

void expect_rows_at_the_strains(const fs::path& file, bool small_strain) {
  const std::string base = "cases/base/macro/";
  const auto time = read(file, base + "time");
  const auto strain = read(file, base + "strain");
  ASSERT_EQ(time.size(), kStrains.size() + 1);  // the initial state, then one row per point
  EXPECT_EQ(time[0], 0.0);
  // ln V under the Cayley (midpoint) map of F: ln F_33 = sum over steps of a + a^3/12 + ...,
  // a = L_33 dt, so it exceeds the loading strain by at most (L_33 dt_max)^2 / 12 relative; a
  // step is never longer than the time between two rows.
  double longest = 0.0;
  for (std::size_t k = 1; k < time.size(); ++k) longest = std::max(longest, time[k] - time[k - 1]);
  const double cayley = 1.01 * (1.0e-3 * longest) * (1.0e-3 * longest) / 12.0;
  for (std::size_t k = 0; k < kStrains.size(); ++k) {
    SCOPED_TRACE("strain " + std::to_string(kStrains[k]));
    // The row is the state at that loading strain: its time is where it is reached ...
    EXPECT_NEAR(time[k + 1], time_of_strain(kStrains[k]), 1e-13 * time_of_strain(kStrains[k]));
    // ... and eps_33 (the integral of D_33 in small strain) is that strain to round-off.
    const double eps33 = strain[9 * (k + 1) + 8];
    EXPECT_NEAR(eps33, kStrains[k], (small_strain ? 1e-13 : cayley + 1e-13) * kStrains[k]);
  }
}

}  // namespace

// ---- the step clocks

TEST(OutputPoints, FixedIncrementsAreSplitAtOutputTimes) {
  const std::vector<double> increments = {1.0, 2.0, 3.0};
  // No output times: the increments themselves, ends the running sum.
  const auto plain = fixed_steps(increments, {}, 6.0);
  ASSERT_EQ(plain.size(), 3u);
  EXPECT_EQ(plain[1].length, 2.0);
  EXPECT_EQ(plain[1].end, 3.0);
  EXPECT_TRUE(plain[2].increment_end);
  EXPECT_EQ(plain[2].end, 6.0);
  // 0.25 and 2.5 inside increments 1 and 2, 3 on the end of increment 2, 6 on the end.
  const std::vector<double> times = {0.25, 2.5, 3.0, 6.0};
  const auto steps = fixed_steps(increments, times, 6.0);
  ASSERT_EQ(steps.size(), 5u);
  const double ends[] = {0.25, 1.0, 2.5, 3.0, 6.0};
  const bool outputs[] = {true, false, true, true, true};
  double sum = 0.0;
  for (std::size_t k = 0; k < steps.size(); ++k) {
    EXPECT_EQ(steps[k].end, ends[k]) << k;
    EXPECT_EQ(steps[k].output_time, outputs[k]) << k;
    sum += steps[k].length;
  }
  EXPECT_DOUBLE_EQ(sum, 6.0);
  EXPECT_FALSE(steps[0].increment_end);
  EXPECT_EQ(steps[2].increment, 2);
  // An output time within round-off of an increment end is that end, not a step of 1e-16.
  const auto near = fixed_steps(increments, std::vector<double>{1.0 + 1e-16}, 6.0);
  ASSERT_EQ(near.size(), 3u);
  EXPECT_TRUE(near[0].output_time);
}

TEST(OutputPoints, AdaptiveStepsEndOnEveryStopWithoutShrinking) {
  AdaptiveSegment clock(10.0, 0.3, 1e-3);
  const std::vector<double> stops = {0.5, 0.7, 10.0};
  clock.set_stops(stops);
  std::vector<double> ends;
  int steps = 0;
  while (true) {
    const bool last = clock.last();
    const bool stop = clock.accept(0.0);  // error 0: the step grows by the largest factor
    ++steps;
    if (stop) ends.push_back(clock.time());
    if (last) break;
  }
  EXPECT_EQ(ends, stops);  // exactly the stops, in order
  EXPECT_LT(steps, 8);
  // A step of 1.0 planned, shortened to the stop at 0.1 with a small error (factor 1.8): the
  // next step is the 1.0 planned, not 1.8 x 0.1.
  const std::vector<double> early = {0.1};
  AdaptiveSegment grow(10.0, 1.0, 1e-3);
  grow.set_stops(early);
  EXPECT_TRUE(grow.accept(0.25e-3));
  EXPECT_EQ(grow.time(), 0.1);
  EXPECT_EQ(grow.planned_step(), 1.0);
  // ... unless its error asks for a shorter one (factor 0.9): then 0.9 x 0.1.
  AdaptiveSegment shrink(10.0, 1.0, 1e-3);
  shrink.set_stops(early);
  EXPECT_TRUE(shrink.accept(1e-3));
  EXPECT_DOUBLE_EQ(shrink.planned_step(), 0.09);
  // Resumed part-way (a restart), the stops already passed are not stops again.
  AdaptiveSegment resumed(10.0, 0.1, 1e-3, 2, 0.7, 2);
  resumed.set_stops(stops);
  EXPECT_FALSE(resumed.at_stop());
  EXPECT_DOUBLE_EQ(resumed.end_time(), 0.8);
}

// A planned step can land exactly on a stop without being shortened to it: from t = 0.1 a step
// of 0.2 ends at 0.1 + 0.2, while 0.2 < (0.1 + 0.2) - 0.1 in floating point. That step ended on
// the stop: it is reported, and the next step is not one of length 0 (which failed the grain
// solve of a reference computed at a run's times).
TEST(OutputPoints, AStepLandingExactlyOnAStopEndsThere) {
  const std::vector<double> stops = {0.1 + 0.2, 10.0};
  AdaptiveSegment clock(10.0, 0.2, 1e-3, 2, 0.1, 1);
  clock.set_stops(stops);
  EXPECT_TRUE(clock.accept(0.0));
  EXPECT_EQ(clock.time(), stops[0]);
  EXPECT_GT(clock.step(), 0.0);
  EXPECT_EQ(clock.end_time(), clock.time() + clock.step());
  // A stop an ulp beyond a planned step's end is that end: no step of 1e-161 s after it.
  const double t = 2.7305e-145;
  const std::vector<double> near = {std::nextafter(t, 1.0), 1.0};
  AdaptiveSegment tiny(1.0, t / 2.0, 1e-3, 2, t / 2.0, 1);
  tiny.set_stops(near);
  EXPECT_TRUE(tiny.accept(0.0));
  EXPECT_EQ(tiny.time(), near[0]);
  EXPECT_GT(tiny.step(), t);
}

TEST(OutputPoints, SpacingsGiveTheirPoints) {
  const std::vector<ClockSegment> one{{2.0, 5.0}};  // a clock of 0 .. 10
  auto points = [&](const std::string& yaml) {
    const YamlDocument d = YamlDocument::from_string("at: " + yaml + "\n", "p.yaml");
    return parse_output_points(
               d.root().required("at"), {"time", "strain"}, [&](const std::string&) { return one; },
               [](const std::string& clock) {
                 Units u;
                 u.time = "s";
                 return u.unit(clock == "time" ? dimension::time : dimension::none);
               })
        .values;
  };
  EXPECT_EQ(points("{strain: [0, 1, 2.5]}"), (std::vector<double>{1, 2.5}));  // 0 is row 0
  EXPECT_EQ(points("{strain: {every: 3}}"), (std::vector<double>{3, 6, 9, 10}));
  EXPECT_EQ(points("{strain: {every: 2.5}}"), (std::vector<double>{2.5, 5, 7.5, 10}));
  EXPECT_EQ(points("{strain: {every: 1, from: 7.5, to: 9}}"), (std::vector<double>{7.5, 8.5, 9}));
  EXPECT_EQ(points("{strain: {count: 5}}"), (std::vector<double>{2.5, 5, 7.5, 10}));
  const auto log = points("{strain: {count: 5, from: 0.001, spacing: log}}");
  ASSERT_EQ(log.size(), 5u);
  EXPECT_EQ(log.front(), 0.001);
  EXPECT_EQ(log.back(), 10.0);
  for (std::size_t k = 1; k < log.size(); ++k) EXPECT_NEAR(log[k] / log[k - 1], 10.0, 1e-12);
  // Points written with their own unit are converted into the scene's (here: time in s).
  EXPECT_EQ(points("{time: [0.05 min, 4500 ms, 9]}"), (std::vector<double>{3, 4.5, 9}));
  EXPECT_EQ(points("{time: {every: 2500 ms}}"), (std::vector<double>{2.5, 5, 7.5, 10}));
  EXPECT_THROW(points("{strain: [1 mm]}"), InputError);  // a strain has no unit
  EXPECT_THROW(points("{time: [1 mm]}"), InputError);    // not a time
  // Points become times into the segments; a point in a hold is the end of the segment before.
  const std::vector<ClockSegment> three{{1.0, 2.0}, {0.0, 5.0}, {0.5, 4.0}};  // 0..2, 2, 2..4
  const auto times = segment_times({1.0, 2.0, 3.0, 4.0}, three);
  EXPECT_EQ(times[0], (std::vector<double>{1.0, 2.0}));
  EXPECT_TRUE(times[1].empty());
  EXPECT_EQ(times[2], (std::vector<double>{2.0, 4.0}));
}

// Two points are one time only where the clock cannot tell them apart at their value: 2.6e-17
// apart 4.6e-11 into a segment of 0.2 (an impact's first steps) are two times, and two points
// 2.6e-17 apart 0.1 into the second segment (within 8 ulp of the clock there) are one.
TEST(OutputPoints, PointsAreTheSameTimeOnlyWithinTheClocksRoundOff) {
  const std::vector<ClockSegment> two{{1.0, 0.2}, {1.0, 0.2}};
  const double early = 4.553591220602946e-11, early_next = 4.5535937970036674e-11;
  const double late = 0.3, late_next = std::nextafter(std::nextafter(0.3, 1.0), 1.0);
  const auto times = segment_times({early, early_next, late, late_next}, two);
  EXPECT_EQ(times[0], (std::vector<double>{early, early_next}));
  ASSERT_EQ(times[1].size(), 1u);
  EXPECT_NEAR(times[1][0], 0.1, 1e-15);
}

// ---- bad input: one error naming file, line and key

TEST(OutputPoints, BadPointsNameFileLineAndKey) {
  struct Case {
    std::string output;
    std::string key;
    std::string message;
    int line;  // in the output block (1: its `output:` line)
  };
  const Case cases[] = {
      {"output:\n  at: {strain: [0.01, 0.05]}\n", "output.at.strain[1]",
       "0.05 is beyond the end of the loading (strain 0.03)", 2},
      {"output:\n  at: {strain: [0.01, 0.005]}\n", "output.at.strain[1]",
       "must be larger than the point before it (0.01)", 2},
      {"output:\n  at: {strain: [0.01], time: [1]}\n", "output.at.strain",
       "give either 'time' or 'strain', not both", 2},
      {"output:\n  at: {distance: [1]}\n", "output.at.distance",
       "unknown key 'distance'; expected one of: time, strain", 2},
      {"output:\n  at: {strain: {every: 1.0e-12}}\n", "output.at.strain.every",
       "at most 10000000 (use a larger spacing)", 2},
      {"output:\n  at: {strain: {count: 10, spacing: log}}\n", "output.at.strain.from",
       "log spacing needs 'from' > 0", 2},
      {"output:\n  at: {strain: {every: 0.01, spacing: log}}\n", "output.at.strain.spacing",
       "log spacing needs 'count'", 2},
      {"output:\n  at: {strain: {every: 0.01, count: 3}}\n", "output.at.strain.count",
       "give either 'every' or 'count', not both", 2},
      {"output:\n  at: {strain: 0.01}\n", "output.at.strain",
       "must be a list of points or a spacing", 2},
      {"output:\n  at:\n    time: {count: 3, from: 50}\n", "output.at.time.from",
       "must be below 'to' (40)", 3},
      {"output:\n  grains: [stress]\n  grains_at: {time: [1]}\n", "output.grains_at",
       "needs output.at", 3},
  };
  const std::string scene = crystal_scene("small_strain", "", "");
  const int before = static_cast<int>(std::count(scene.begin(), scene.end(), '\n'));
  for (const Case& c : cases) {
    SCOPED_TRACE(c.output);
    try {
      parsed(scene + c.output);
      ADD_FAILURE() << "accepted";
    } catch (const InputError& e) {
      EXPECT_EQ(e.file, "points.yaml");
      EXPECT_EQ(e.line, before + c.line);
      EXPECT_EQ(e.key, c.key) << e.what();
      EXPECT_NE(std::string(e.what()).find(c.message), std::string::npos) << e.what();
    }
  }
  // output_every and output.at both choose the rows of a segment: refused at output_every.
  std::string text = crystal_scene("small_strain", "", "output: {at: {strain: [0.01]}}\n");
  text.replace(text.find("    increments: 4\n"), 18, "    increments: 4\n    output_every: 2\n");
  try {
    parsed(text);
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.key, "loading[1].output_every");
    EXPECT_NE(std::string(e.what()).find("drop output_every"), std::string::npos) << e.what();
  }
}

// ---- rows at exactly the strains asked for, fixed and adaptive

TEST(OutputPoints, CrystalRowsAreAtTheStrainsFixedAndAdaptive) {
  const fs::path dir = scratch_dir();
  for (const std::string& kinematics :
       std::vector<std::string>{"small_strain", "finite_rotation"}) {
    for (const std::string& integrator :
         {std::string(), std::string("integrator: {tolerance: 1.0e-2}\n")}) {
      SCOPED_TRACE(kinematics + (integrator.empty() ? ", fixed" : ", adaptive"));
      const CrystalScene scene = parsed(crystal_scene(kinematics, integrator, strains_output()));
      expect_rows_at_the_strains(run_crystal(scene, dir / "points.h5"),
                                 kinematics == "small_strain");
    }
  }
  fs::remove_all(dir);
}

// Points exactly on increment ends split nothing: those rows are the plain run's rows, bit for
// bit (the rows of output.at are states of the same run, not interpolated or re-stepped).
TEST(OutputPoints, PointsOnIncrementEndsAreThePlainRunsRows) {
  const fs::path dir = scratch_dir();
  const std::string out = "output: {macro: [time, stress]}\n";
  const auto plain = run_crystal(parsed(crystal_scene("finite_rotation", "", out)), dir / "a.h5");
  const auto t = read(plain, "cases/base/macro/time");
  ASSERT_EQ(t.size(), 1u + 25u + 4u + 10u);
  auto exact = [](double v) {
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.17g", v);
    return std::string(buf);
  };
  const std::size_t picked[] = {1, 2, 17, 26, 39};  // (26: in the hold, 39: the end)
  std::string list;
  for (std::size_t k : picked) list += (list.empty() ? "" : ", ") + exact(t[k]);
  const auto points = run_crystal(
      parsed(crystal_scene("finite_rotation", "",
                           "output: {macro: [time, stress], at: {time: [" + list + "]}}\n")),
      dir / "b.h5");
  const auto s_plain = read(plain, "cases/base/macro/stress");
  const auto s_points = read(points, "cases/base/macro/stress");
  const auto t_points = read(points, "cases/base/macro/time");
  ASSERT_EQ(t_points.size(), 6u);
  for (std::size_t r = 1; r < t_points.size(); ++r) {
    const std::size_t k = picked[r - 1];
    SCOPED_TRACE("row " + std::to_string(k));
    EXPECT_NEAR(t_points[r], t[k], 1e-13 * t[k]);  // (planned time vs the sum of the steps)
    for (std::size_t c = 0; c < 9; ++c) EXPECT_EQ(s_points[9 * r + c], s_plain[9 * k + c]);
  }
  fs::remove_all(dir);
}

// Contact: rows at given sliding distances (fixed increments and adaptive), the slip path at
// each equal to it to round-off; a time point in the hold.
TEST(OutputPoints, ContactRowsAreAtTheDistancesAndTimes) {
  const std::string start = subslip::testing::contact_scene_start() + R"(loading:
  - slide: {speed: 2, direction: [1, 0], distance: 1.0}
    increments: 40
    growth: 1.1
  - hold: {duration: 10}
    increments: 3
  - slide: {speed: 1, direction: [0, 1], distance: 0.5}
    increments: 7
)";
  const std::vector<double> distances = {1e-5, 3e-4, 0.04, 0.5, 1.0, 1.2, 1.5};
  for (const std::string& integrator :
       {std::string(), std::string("integrator: {tolerance: 1.0e-4}\n")}) {
    SCOPED_TRACE(integrator.empty() ? "fixed" : "adaptive");
    const ContactScene scene = parse_contact_scene(YamlDocument::from_string(
        start + integrator +
            "output: {fields: [time, slip_path, ratio], at: {distance: [1.0e-5, 3.0e-4, 0.04, 0.5, "
            "1.0, 1.2, 1.5]}}\n",
        "c.yaml"));
    std::vector<contact::ContactState> rows;
    history::run_history(scene.cases[0].model, scene.cases[0].segments, scene.cases[0].integrator,
                         [&](const contact::ContactState& s, int) { rows.push_back(s); });
    ASSERT_EQ(rows.size(), distances.size() + 1);
    EXPECT_EQ(rows.size(), output_count(scene.cases[0].segments));
    for (std::size_t k = 0; k < distances.size(); ++k) {
      EXPECT_NEAR(rows[k + 1].slip_path, distances[k], 1e-14 * distances[k]) << k;
      // Distance 1.0 ends the first slide (time 0.5); 1.2 is 0.2 into the second, after the hold.
      const double time = distances[k] <= 1.0 ? distances[k] / 2.0 : 10.5 + (distances[k] - 1.0);
      EXPECT_NEAR(rows[k + 1].time, time, 1e-14 * time) << k;
    }
    // Times: a point inside the hold is a row there (the slip path stands still).
    const ContactScene held = parse_contact_scene(YamlDocument::from_string(
        start + integrator + "output: {at: {time: {every: 2.0}}}\n", "c.yaml"));
    std::vector<double> times;
    history::run_history(held.cases[0].model, held.cases[0].segments, held.cases[0].integrator,
                         [&](const contact::ContactState& s, int) { times.push_back(s.time); });
    EXPECT_EQ(times, (std::vector<double>{0, 2, 4, 6, 8, 10, 11}));
  }
}

// Per-grain fields at a coarser spacing: the grain rows are those of grains_at, each the state of
// its output row (grains/row), equal bit for bit to a run writing grains at every point.
TEST(OutputPoints, GrainRowsAtTheCoarserPoints) {
  const fs::path dir = scratch_dir();
  const std::string at = "  at: {strain: {every: 0.002}}\n";
  const auto every =
      run_crystal(parsed(crystal_scene("finite_rotation", "integrator: {tolerance: 1.0e-2}\n",
                                       "output:\n  grains: [stress, slip]\n" + at +
                                           "  grains_at: {strain: [0.01, 0.03]}\n")),
                  dir / "coarse.h5");
  const auto all =
      run_crystal(parsed(crystal_scene("finite_rotation", "integrator: {tolerance: 1.0e-2}\n",
                                       "output:\n  grains: [stress, slip]\n" + at)),
                  dir / "all.h5");
  const auto time = read(every, "cases/base/macro/time");
  ASSERT_EQ(time.size(), 16u);  // 0, 0.002 ... 0.03: the initial state and 15 points
  const h5::File f = h5::File::open_read(every);
  const h5::Group g = f.root().open_group("cases/base/grains");
  const auto rows = g.open_dataset("row").read_ints();
  EXPECT_EQ(rows, (std::vector<long long>{0, 5, 15}));  // the initial state, 1 % and 3 %
  EXPECT_EQ(g.open_dataset("stress").shape(), (std::vector<std::size_t>{3, 3, 3, 3}));
  EXPECT_EQ(h5::CaseProgress::open(f.root()).grain_rows(0), 3);
  EXPECT_EQ(h5::CaseProgress::open(f.root()).rows(0), 16);
  // The same stepping (the points of `at` include those of grains_at): the same states.
  EXPECT_EQ(read(all, "cases/base/macro/time"), time);
  const auto coarse_slip = read(every, "cases/base/grains/slip");
  const auto all_slip = read(all, "cases/base/grains/slip");
  const std::size_t width = 3 * 12;  // grains x slip systems
  for (std::size_t k = 0; k < rows.size(); ++k) {
    for (std::size_t i = 0; i < width; ++i) {
      ASSERT_EQ(coarse_slip[k * width + i], all_slip[static_cast<std::size_t>(rows[k]) * width + i])
          << k;
    }
  }
  fs::remove_all(dir);
}
