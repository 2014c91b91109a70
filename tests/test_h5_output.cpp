// The HDF5 writer and the contact result file: layout, attributes, values equal to what
// run_history produced, thread-count independence, and a readable file after a crash.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "child_process.hpp"
#include "scene_text.hpp"
#include "scratch_dir.hpp"
#include "subslip/driver/checkpoint_policy.hpp"
#include "subslip/driver/contact_run.hpp"
#include "subslip/driver/crystal_run.hpp"
#include "subslip/history/contact_history.hpp"
#include "subslip/io/case_group.hpp"
#include "subslip/io/contact_output.hpp"
#include "subslip/io/contact_scene.hpp"
#include "subslip/io/crystal_output.hpp"
#include "subslip/io/crystal_scene.hpp"
#include "subslip/io/h5_writer.hpp"
#include "subslip/io/result_file.hpp"
#include "subslip/io/result_protocol.hpp"

namespace fs = std::filesystem;
using namespace subslip;
using namespace subslip::io;

namespace {

const std::string kScene =
    subslip::testing::contact_scene_start("title: \"h5 test\"\n") + R"(loading:
  - slide: {speed: 10, direction: [1, 0], distance: 0.2}
    increments: 300
    growth: 1.02
  - hold: {duration: 1}
    increments: 10
    output_every: 3
output:
  fields: [time, slip, traction, ratio, mu, segment]
)";

// A fresh directory per test (tests may run in parallel processes).
fs::path scratch_dir() {
  return subslip::testing::scratch_dir("h5");
}

struct Recorded {
  std::vector<contact::ContactState> states;
  std::vector<int> segments;
};

Recorded run_directly(const ContactCase& c) {
  Recorded r;
  history::run_history(c.model, c.segments, c.integrator,
                       [&](const contact::ContactState& s, int segment) {
                         r.states.push_back(s);
                         r.segments.push_back(segment);
                       });
  return r;
}

ContactScene scene_of(const std::string& text) {
  return parse_contact_scene(YamlDocument::from_string(text, "h5_test.yaml"));
}

fs::path write_run(const ContactScene& scene, const fs::path& path, int threads) {
  h5::File file = h5::File::create(path, false);
  driver::ContactRunOptions options;
  options.threads = threads;
  ContactResultSink sink(scene, file, {});
  const auto results = driver::run_contact_scene(scene, sink, options);
  for (const auto& r : results) EXPECT_TRUE(r.failure.empty()) << r.failure;
  close_and_finish(file);
  return path;
}

}  // namespace

TEST(H5Output, ContactFileHasTheDocumentedLayoutAndValues) {
  const fs::path dir = scratch_dir();
  const ContactScene scene = scene_of(kScene);
  const ContactCase& c = scene.cases.at(0);
  write_run(scene, dir / "out.h5", 1);
  const Recorded expected = run_directly(c);
  ASSERT_EQ(expected.states.size(), output_count(c.segments));

  const h5::File file = h5::File::open_read(dir / "out.h5");
  const h5::Group root = file.root();
  EXPECT_EQ(root.attribute_string("format"), "subslip");
  EXPECT_EQ(root.attribute_int("format_version"), h5::kFormatVersion);
  EXPECT_EQ(root.attribute_int("layout_complete"), 1);
  EXPECT_EQ(root.attribute_string("program_version"), SUBSLIP_VERSION);
  EXPECT_EQ(root.attribute_string("build"), SUBSLIP_BUILD);
  EXPECT_FALSE(root.has_attribute("simd_kernels"));  // the contact solver has no batches
  EXPECT_EQ(root.attribute_string("scene_kind"), "contact");
  EXPECT_EQ(root.attribute_string("scene_file"), "h5_test.yaml");
  EXPECT_EQ(root.attribute_string("title"), "h5 test");
  EXPECT_EQ(root.attribute_int("completed"), 1);
  EXPECT_EQ(root.attribute_int("finished"), 1);
  EXPECT_EQ(root.attribute_string("run_id").size(), 16u);
  EXPECT_FALSE(root.has("checkpoint"));
  const std::string created = root.attribute_string("created");
  EXPECT_EQ(created.size(), 20u);
  EXPECT_EQ(created.back(), 'Z');
  EXPECT_EQ(root.open_dataset("scene").read_string(), kScene);
  const h5::Group units = root.open_group("units");
  EXPECT_EQ(units.attribute_string("stress"), "MPa");
  EXPECT_EQ(units.attribute_string("length"), "mm");
  EXPECT_EQ(units.attribute_string("time"), "min");

  const h5::Group cases = root.open_group("cases");
  EXPECT_EQ(cases.members(), (std::vector<std::string>{"base"}));
  const h5::Group g = cases.open_group("base");
  // Only the requested fields, in output order.
  EXPECT_EQ(g.members(),
            (std::vector<std::string>{"time", "slip", "traction", "ratio", "mu", "segment"}));
  const std::size_t n = expected.states.size();
  for (const auto& name : g.members()) {
    SCOPED_TRACE(name);
    const h5::Dataset ds = g.open_dataset(name);
    EXPECT_TRUE(ds.has_attribute("unit"));
    EXPECT_FALSE(ds.attribute_string("description").empty());
    EXPECT_EQ(ds.shape().front(), n);
    // A finished file: chunked (extendible) as while the run went, but exactly its rows, and
    // compressed (output.compression: gzip by default; the live rows were written in place,
    // uncompressed).
    EXPECT_EQ(ds.filters(), (std::vector<std::string>{"shuffle", "deflate"}));
    ASSERT_FALSE(ds.chunk_shape().empty());
    EXPECT_LE(ds.chunk_shape().front(), n);
  }
  EXPECT_EQ(g.open_dataset("time").attribute_string("unit"), "min");
  EXPECT_EQ(g.open_dataset("slip").attribute_string("unit"), "mm");
  EXPECT_EQ(g.open_dataset("traction").attribute_string("unit"), "MPa");
  EXPECT_EQ(g.open_dataset("ratio").attribute_string("unit"), "1");
  EXPECT_EQ(g.open_dataset("slip").shape(), (std::vector<std::size_t>{n, 2}));
  EXPECT_EQ(g.open_dataset("traction").shape(), (std::vector<std::size_t>{n, 3}));
  EXPECT_EQ(g.open_dataset("slip").attribute_string("components"), "x y");
  EXPECT_EQ(g.open_dataset("traction").attribute_string("components"), "x y n");
  EXPECT_FALSE(g.open_dataset("ratio").has_attribute("components"));

  // Values: bit for bit what run_history reported.
  const auto time = g.open_dataset("time").read_doubles();
  const auto slip = g.open_dataset("slip").read_doubles();
  const auto traction = g.open_dataset("traction").read_doubles();
  const auto ratio = g.open_dataset("ratio").read_doubles();
  const auto mu = g.open_dataset("mu").read_doubles();
  const auto segment = g.open_dataset("segment").read_ints();
  for (std::size_t i = 0; i < n; ++i) {
    const auto& s = expected.states[i];
    ASSERT_EQ(time[i], s.time) << i;
    ASSERT_EQ(slip[2 * i], s.slip.x()) << i;
    ASSERT_EQ(slip[2 * i + 1], s.slip.y()) << i;
    ASSERT_EQ(traction[3 * i], s.traction_t.x()) << i;
    ASSERT_EQ(traction[3 * i + 1], s.traction_t.y()) << i;
    ASSERT_EQ(traction[3 * i + 2], s.traction_n) << i;
    ASSERT_EQ(ratio[i], s.traction_ratio()) << i;
    ASSERT_EQ(mu[i], s.law.mu) << i;
    ASSERT_EQ(segment[i], expected.segments[i]) << i;
  }
  EXPECT_EQ(segment.front(), -1);
  EXPECT_EQ(segment.back(), 1);

  // Attributes: parameters with units, and the summary.
  EXPECT_EQ(g.attribute_string("name"), "base");
  EXPECT_DOUBLE_EQ(g.attribute_double("eta_v"), 950.0);
  EXPECT_EQ(g.attribute_string("eta_v.unit"), "min/mm");
  EXPECT_EQ(g.attribute_string("kappa.unit"), "1/mm");
  EXPECT_EQ(g.attribute_string("xi.unit"), "1/min");
  EXPECT_EQ(g.attribute_string("alpha_t.unit"), "MPa/mm");
  EXPECT_EQ(g.attribute_string("overstress_form"), "exponential");
  const auto peak = std::max_element(ratio.begin(), ratio.end());
  EXPECT_EQ(g.attribute_double("peak_ratio"), *peak);
  const auto k_peak = static_cast<std::size_t>(peak - ratio.begin());
  EXPECT_EQ(g.attribute_double("slip_at_peak"), expected.states[k_peak].slip_path);
  EXPECT_EQ(g.attribute_double("bottom_ratio"), *std::min_element(peak + 1, ratio.end()));
  EXPECT_EQ(g.attribute_double("final_ratio"), ratio.back());
  EXPECT_EQ(g.attribute_string("slip_at_peak.unit"), "mm");
  EXPECT_DOUBLE_EQ(g.attribute_double("steady_speed"), 10.0);
  EXPECT_DOUBLE_EQ(g.attribute_double("steady_ratio_analytical"),
                   law::SubloadingFrictionLaw(c.model.law).steady_state(10.0).ratio);
  EXPECT_EQ(g.attribute_int("increments"), 310);
  EXPECT_GT(g.attribute_int("newton_iterations"), 0);
  EXPECT_GE(g.attribute_int("substeps"), 310);
  EXPECT_TRUE(g.has_attribute("cutbacks"));
  EXPECT_TRUE(g.has_attribute("wall_seconds"));
  EXPECT_EQ(h5::failure_message(g), "");  // reserved, empty: the case did not fail
  fs::remove_all(dir);
}

TEST(H5Output, SweepCasesCarryOverridesAndDoNotDependOnThreads) {
  const fs::path dir = scratch_dir();
  const ContactScene scene = scene_of(kScene + R"(sweep:
  "loading[0].slide.speed": [1, 10, 100]
  "law.subloading.function": [cot, reciprocal]
)");
  ASSERT_EQ(scene.cases.size(), 6u);
  write_run(scene, dir / "serial.h5", 1);
  write_run(scene, dir / "parallel.h5", 2);
  const h5::File serial = h5::File::open_read(dir / "serial.h5");
  const h5::File parallel = h5::File::open_read(dir / "parallel.h5");
  const h5::Group a = serial.root().open_group("cases");
  const h5::Group b = parallel.root().open_group("cases");
  std::vector<std::string> names;
  for (const auto& c : scene.cases) names.push_back(c.name);
  EXPECT_EQ(a.members(), names);  // creation order = sweep order, whatever the threads
  EXPECT_EQ(b.members(), names);
  EXPECT_EQ(a.attribute_strings("names"), names);
  for (const auto& name : names) {
    SCOPED_TRACE(name);
    const h5::Group ga = a.open_group(name), gb = b.open_group(name);
    for (const auto& field : ga.members()) {
      EXPECT_EQ(ga.open_dataset(field).read_doubles(), gb.open_dataset(field).read_doubles());
    }
    EXPECT_EQ(ga.attribute_double("peak_ratio"), gb.attribute_double("peak_ratio"));
  }
  const h5::Group g = a.open_group("speed=100,function=reciprocal");
  EXPECT_DOUBLE_EQ(g.attribute_double("sweep:loading[0].slide.speed"), 100.0);
  EXPECT_EQ(g.attribute_string("sweep:loading[0].slide.speed.unit"), "mm/min");
  EXPECT_EQ(g.attribute_string("sweep:law.subloading.function"), "reciprocal");
  EXPECT_FALSE(g.has_attribute("sweep:law.subloading.function.unit"));  // a name has no unit
  EXPECT_EQ(g.attribute_string("subloading_function"), "reciprocal");
  EXPECT_EQ(g.attribute_int("index"), 5);
  fs::remove_all(dir);
}

TEST(H5Writer, SeriesAppendInBlocksAndReadBack) {
  const fs::path dir = scratch_dir();
  {
    h5::File file = h5::File::create(dir / "s.h5", false);
    const h5::Group root = file.root();
    h5::Series one = root.create_series({"one", 0, h5::Type::float64, "s", "a 1-D series", 64, 7});
    h5::Series two = root.create_series({"two", 3, h5::Type::float64, "m", "a 2-D series", 64, 7});
    h5::Series ints = root.create_series({"ints", 0, h5::Type::int32, "index", "ints", 64, 7});
    EXPECT_EQ(one.capacity(), 64u);  // one chunk reserved
    for (int i = 0; i < 100; ++i) {
      one.append(0.5 * i);
      const double row[3] = {1.0 * i, 2.0 * i, 3.0 * i};
      two.append(row);
      ints.append_int(-i);
      if (i == 50) {  // a mid-run commit: the rows are in the reserved extent, the rest is NaN
        one.commit();
        EXPECT_EQ(one.dataset().shape().front(), 64u);
        const auto v = one.dataset().read_doubles();
        EXPECT_EQ(v[50], 25.0);
        EXPECT_TRUE(std::isnan(v[51]));
      }
    }
    EXPECT_EQ(one.rows(), 100u);
    one.commit();
    EXPECT_EQ(one.capacity(), 128u);  // the reservation doubled
    const auto ints_so_far = ints.dataset().read_ints();
    EXPECT_EQ(ints_so_far.back(), h5::kInt32Fill);  // not committed yet, or beyond the rows
    one.finish();  // commits; the reservation stays (a trim would change metadata mid-run)
    two.finish();
    ints.finish();
    EXPECT_EQ(one.dataset().shape().front(), 128u);
    EXPECT_THROW(one.append_int(1), h5::Error);
    const double wrong[2] = {1, 2};
    EXPECT_THROW(two.append(wrong), h5::Error);
    root.set_attribute("pi", 3.25);
    root.set_attribute("pi", 3.5);  // replaced, not duplicated
    root.set_attribute("list", std::vector<std::string>{"a", "bc"});
    const double xs[2] = {1.5, 2.5};
    root.set_attribute("xs", std::span<const double>(xs, 2));
  }
  const h5::File file = h5::File::open_read(dir / "s.h5");
  const h5::Group root = file.root();
  const auto one = root.open_dataset("one").read_doubles();
  const auto two = root.open_dataset("two").read_doubles();
  const auto ints = root.open_dataset("ints").read_ints();
  ASSERT_EQ(one.size(), 128u);
  ASSERT_EQ(two.size(), 3 * 128u);
  ASSERT_EQ(ints.size(), 128u);
  for (int i = 0; i < 100; ++i) {
    EXPECT_EQ(one[i], 0.5 * i);
    EXPECT_EQ(two[3 * i + 2], 3.0 * i);
    EXPECT_EQ(ints[i], -i);
  }
  for (int i = 100; i < 128; ++i) {  // reserved rows beyond the written ones
    EXPECT_TRUE(std::isnan(one[i]));
    EXPECT_EQ(ints[i], h5::kInt32Fill);
  }
  EXPECT_EQ(root.open_dataset("two").chunk_shape(), (std::vector<std::size_t>{64, 3}));
  EXPECT_EQ(root.open_dataset("one").attribute_string("unit"), "s");
  EXPECT_EQ(root.attribute_double("pi"), 3.5);
  EXPECT_EQ(root.attribute_strings("list"), (std::vector<std::string>{"a", "bc"}));
  EXPECT_EQ(root.attribute_doubles("xs"), (std::vector<double>{1.5, 2.5}));
  const auto names = root.attribute_names();
  EXPECT_EQ(std::count(names.begin(), names.end(), "pi"), 1);
  EXPECT_THROW(root.attribute_double("nope"), h5::Error);
  fs::remove_all(dir);
}

TEST(H5Writer, RefusesToOverwriteUnlessAsked) {
  const fs::path dir = scratch_dir();
  const fs::path path = dir / "x.h5";
  { h5::File::create(path, false); }
  EXPECT_THROW(h5::File::create(path, false), h5::Error);
  EXPECT_NO_THROW(h5::File::create(path, true));
  fs::remove_all(dir);
}

TEST(H5Writer, OutputPathIsCheckedBeforeAnyWork) {
  const fs::path dir = scratch_dir();
  // Missing directories are created.
  EXPECT_NO_THROW(h5::check_output_path(dir / "new/sub/out.h5", false));
  EXPECT_TRUE(fs::is_directory(dir / "new/sub"));
  EXPECT_TRUE(fs::is_empty(dir / "new/sub"));  // the probe file is gone
  // An existing file needs overwrite.
  std::ofstream(dir / "exists.h5") << "old";
  try {
    h5::check_output_path(dir / "exists.h5", false);
    FAIL() << "existing file accepted";
  } catch (const h5::OutputPathError& e) {
    EXPECT_NE(std::string(e.what()).find("--force"), std::string::npos);
  }
  EXPECT_NO_THROW(h5::check_output_path(dir / "exists.h5", true));
  // A directory, and a path under a regular file, are refused.
  EXPECT_THROW(h5::check_output_path(dir, true), h5::OutputPathError);
  EXPECT_THROW(h5::check_output_path(dir / "exists.h5" / "out.h5", true), h5::OutputPathError);
  // A read-only place (refused even for root).
  EXPECT_THROW(h5::check_output_path("/proc/subslip_test/out.h5", true), h5::OutputPathError);
  fs::remove_all(dir);
}

// A process that dies without closing its file (as a killed run does) leaves a file that
// opens and holds every committed row, without any flush after the rows were reserved, with
// completed = 0 and /progress counting the rows; rows gathered but not committed are not there.
TEST(H5Writer, CommittedRowsSurviveACrashWithoutFlush) {
  const fs::path dir = scratch_dir();
  const fs::path path = dir / "crash.h5";
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    h5::File file = h5::File::create(path, false);
    h5::write_result_header(file, {"contact", "crash.yaml", "scene: contact\n", "crash", {}, {}});
    h5::CaseProgress progress = h5::CaseProgress::create(file.root(), 1);
    h5::Series s = file.root().create_series({"x", 0, h5::Type::float64, "1", "x", 16, 64, 32});
    file.flush();  // the layout; from here on no flush at all
    progress.set_state(0, h5::CaseState::running);
    for (int i = 0; i < 10; ++i) s.append(1.0 * i);
    s.commit();
    progress.set_rows(0, s.rows());
    for (int i = 0; i < 10; ++i) s.append(-1.0);  // gathered, never committed
    ::_exit(0);  // no destructors, no HDF5 atexit close: like a kill
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  const h5::File file = h5::File::open_read(path);
  EXPECT_EQ(file.root().attribute_int("completed"), 0);
  const h5::CaseProgress progress = h5::CaseProgress::open(file.root());
  EXPECT_EQ(progress.rows(0), 10);
  EXPECT_EQ(progress.state(0), h5::CaseState::running);
  const auto x = file.root().open_dataset("x").read_doubles();
  ASSERT_EQ(x.size(), 32u);  // the reservation
  for (int i = 0; i < 10; ++i) EXPECT_EQ(x[i], 1.0 * i);
  for (std::size_t i = 10; i < x.size(); ++i) EXPECT_TRUE(std::isnan(x[i])) << i;
  fs::remove_all(dir);
}

// ---- a real `subslip run` killed at random moments

namespace {

// Two crystal cases of a few seconds at most, with macro and per-grain series.
const std::string kCrystalKillScene =
    subslip::testing::copper_scene_start("title: \"killed at random\"\n") + R"(orientations:
  random: {count: 24, seed: 3}
loading:
  - L: [[x, 0, 0], [0, x, 0], [0, 0, 1.0e-3]]
    stress: [[0, x, x], [x, 0, x], [x, x, x]]
    duration: 15
    increments: 150
output:
  grains: [stress, slip, r_s]
  checkpoint_every: 10
sweep:
  "phase.tau0": [10, 12]
)";

bool is_fill(double v, bool integer) {
  return integer ? v == static_cast<double>(h5::kInt32Fill) : std::isnan(v);
}

// What a file killed at any moment must hold: a working file (completed = 0, finished = 0) in
// which, for each case, /progress counts rows that are all present and equal (bit for bit) to
// the uninterrupted run's, and every row after them is either not written (fill) or also equal;
// or, when the kill came after the finished file replaced it, that finished file, equal to the
// reference. Adds the number of valid rows found to `valid`.
void check_killed_file(const fs::path& killed, const fs::path& reference, std::size_t& valid) {
  const auto ref = subslip::testing::case_datasets(reference);
  const h5::File file = h5::File::open_read(killed);  // readable
  const h5::Group root = file.root();
  if (root.attribute_int("finished") == 1) {
    EXPECT_EQ(root.attribute_int("completed"), 1);
    subslip::testing::expect_same_datasets(reference, killed);
    const h5::CaseProgress progress = h5::CaseProgress::open(root);
    for (std::size_t k = 0; k < progress.size(); ++k)
      valid += static_cast<std::size_t>(progress.rows(k));
    return;
  }
  EXPECT_EQ(root.attribute_int("completed"), 0);
  const auto names = root.open_group("cases").attribute_strings("names");
  const h5::CaseProgress progress = h5::CaseProgress::open(root);
  const auto got = subslip::testing::case_datasets(killed);
  for (std::size_t k = 0; k < names.size(); ++k) {
    SCOPED_TRACE(names[k]);
    const std::string prefix = "/cases/" + names[k] + "/";
    const auto state = progress.state(k);
    if (state == h5::CaseState::not_started) continue;
    const auto rows = static_cast<std::size_t>(progress.rows(k));
    valid += rows;
    for (const auto& [name, expected] : ref) {
      if (name.rfind(prefix, 0) != 0) continue;
      SCOPED_TRACE(name);
      const auto it = got.find(name);
      ASSERT_NE(it, got.end());
      const auto& actual = it->second;
      const bool fixed = name.ends_with("/weight") || name.ends_with("/initial_orientation") ||
                         name.ends_with("/slip_systems");  // written once, not series
      if (fixed) {
        ASSERT_EQ(actual.shape, expected.shape);
        for (std::size_t i = 0; i < expected.values.size(); ++i)
          ASSERT_TRUE(subslip::testing::same_bits(actual.values[i], expected.values[i])) << i;
        continue;
      }
      // A series: reserved rows, the first `rows` valid (all of them for a completed case).
      if (state == h5::CaseState::completed) {
        ASSERT_EQ(rows, expected.shape.front());
      }
      ASSERT_GE(actual.shape.front(), rows);
      std::size_t width = 1;
      for (std::size_t d = 1; d < expected.shape.size(); ++d) width *= expected.shape[d];
      for (std::size_t i = 0; i < actual.values.size(); ++i) {
        const std::size_t row = i / width;
        const bool known = row < expected.shape.front();
        const bool equal =
            known && subslip::testing::same_bits(actual.values[i], expected.values[i]);
        if (row < rows) {
          ASSERT_TRUE(equal) << "row " << row << " of " << rows << " valid";
        } else {
          ASSERT_TRUE(equal || is_fill(actual.values[i], actual.integer)) << "row " << row;
        }
      }
    }
  }
}

}  // namespace

// SIGKILL at random moments of a real run (fork + exec): the file is readable, says it did not
// complete, and every row it counts is complete and equal to the uninterrupted run's.
TEST(H5Output, RunKilledAtARandomMomentKeepsEveryCountedRow) {
  const fs::path dir = scratch_dir();
  std::ofstream(dir / "scene.yaml") << kCrystalKillScene;
  double seconds = 0.0;
  ASSERT_EQ(subslip::testing::run_subslip(dir, {"run", "scene.yaml", "-o", "ref.h5", "-q"},
                                          dir / "ref.log", &seconds),
            0)
      << subslip::testing::read_text(dir / "ref.log");
  const unsigned seed = subslip::testing::kill_seed();
  SCOPED_TRACE("SUBSLIP_KILL_SEED=" + std::to_string(seed));
  std::mt19937 rng(seed);
  std::size_t files = 0, valid = 0;
  // Three killed files are wanted, one kill in each third of the run's duration. That duration
  // is the reference run's on a shared machine, whose load changes between runs: a run that
  // ends before its kill shows it to be shorter, and the later kills aim within that.
  for (int trial = 0, third = 0; trial < 12 && third < 3; ++trial) {
    std::uniform_real_distribution<double> when((0.05 + 0.3 * third) * seconds,
                                                (0.35 + 0.3 * third) * seconds);
    const double delay = when(rng);
    SCOPED_TRACE("killed after " + std::to_string(delay) + " s of " + std::to_string(seconds));
    fs::remove(dir / "killed.h5");
    const int code = subslip::testing::run_and_kill(
        dir, {"run", "scene.yaml", "-o", "killed.h5", "-q", "--force"}, dir / "killed.log", delay);
    if (code == 0) {  // finished before the kill: the run is shorter than `delay`
      seconds = std::min(seconds, delay);
      continue;
    }
    ++third;
    ASSERT_EQ(code, 128 + SIGKILL) << subslip::testing::read_text(dir / "killed.log");
    // Before its header is complete the file has a temporary name: the result path is absent.
    if (!fs::exists(dir / "killed.h5")) continue;
    ++files;
    check_killed_file(dir / "killed.h5", dir / "ref.h5", valid);
  }
  EXPECT_GT(files, 0u);  // the test saw at least one killed file
  EXPECT_GT(valid, 0u);  // with rows in it
  fs::remove_all(dir);
}

// The attribute names of the root and of every case group, in creation order: an attribute
// deleted and created again moves to the end.
std::vector<std::vector<std::string>> attribute_orders(const h5::File& file) {
  std::vector<std::vector<std::string>> out{file.root().attribute_names()};
  const h5::Group cases = file.root().open_group("cases");
  for (const auto& name : cases.members()) out.push_back(cases.open_group(name).attribute_names());
  return out;
}

// The crash-safety design (h5_writer.hpp): once the layout is written, a run writes values
// only, in place. So the file does not grow after the layout (no object, attribute, heap or
// chunk space is allocated), and no attribute is replaced, through streaming, checkpoints,
// summaries and a failed case.
TEST(H5Output, RunAllocatesNothingAfterItsLayout) {
  const fs::path dir = scratch_dir();
  std::uintmax_t at_layout = 0;
  std::vector<std::vector<std::string>> orders;
  {
    const fs::path path = dir / "crystal.h5";
    h5::File file = h5::File::create(path, false);
    const CrystalScene scene =
        parse_crystal_scene(YamlDocument::from_string(kCrystalKillScene, "kill.yaml"));
    // Checkpoints go to the restart file, which does not grow either.
    CrystalSinkOptions options;
    options.restart_file = restart_file_for(path);
    options.checkpoint_capacity = driver::checkpoint_capacity(scene, std::nullopt);
    CrystalResultSink sink(scene, file, options);  // the layout
    at_layout = fs::file_size(path);
    orders = attribute_orders(file);
    const std::uintmax_t restart_at_layout = fs::file_size(options.restart_file);
    const auto results = driver::run_crystal_scene(scene, sink);
    ASSERT_EQ(results.size(), 2u);
    EXPECT_EQ(attribute_orders(file), orders);
    file.close();
    EXPECT_GT(at_layout, 0u);
    EXPECT_EQ(fs::file_size(path), at_layout);
    EXPECT_FALSE(h5::File::open_read(path).root().has("checkpoint"));
    EXPECT_GT(restart_at_layout, 0u);
    EXPECT_EQ(fs::file_size(options.restart_file), restart_at_layout);
    const h5::File restart = h5::File::open_read(options.restart_file);
    EXPECT_GT(restart.root()
                  .open_group("checkpoint")
                  .open_group("a")
                  .open_dataset("sequence")
                  .read_ints()
                  .front(),
              0);  // checkpoints were written
  }
  {
    // The slide in one step: the implicit case completes, forward Euler fails.
    const fs::path path = dir / "contact.h5";
    std::string text = kScene;
    text.replace(text.find("increments: 300"), 15, "increments: 1");
    text +=
        "integrator: {method: implicit, max_cutbacks: 0}\n"
        "sweep:\n  \"integrator.method\": [implicit, forward_euler]\n";
    h5::File file = h5::File::create(path, false);
    const ContactScene scene = scene_of(text);
    ContactResultSink sink(scene, file, {});  // the layout
    at_layout = fs::file_size(path);
    orders = attribute_orders(file);
    driver::ContactRunOptions options;
    options.threads = 1;
    const auto results = driver::run_contact_scene(scene, sink, options);
    ASSERT_EQ(results.size(), 2u);
    EXPECT_TRUE(results[0].failure.empty()) << results[0].failure;
    EXPECT_FALSE(results[1].failure.empty());
    EXPECT_EQ(attribute_orders(file), orders);
    file.close();
    EXPECT_EQ(fs::file_size(path), at_layout);
    const h5::File read = h5::File::open_read(path);
    const h5::Group failed = read.root().open_group("cases").open_group(results[1].name);
    EXPECT_NE(h5::failure_message(failed), "");
  }
  fs::remove_all(dir);
}

// The unit of every kind of swept value, in the scene's own units (`sweep:<path>.unit`).
TEST(CaseGroup, SweepUnitsFollowTheSceneUnits) {
  Units u;
  u.stress = "GPa";
  u.length = "um";
  u.time = "s";
  const std::pair<const char*, const char*> contact[] = {{"loading[0].slide.speed", "um/s"},
                                                         {"loading[*].slide.velocity", "um/s"},
                                                         {"loading[1].slide.distance", "um"},
                                                         {"loading[2].hold.duration", "s"},
                                                         {"loading[0].normal.traction", "GPa"},
                                                         {"loading[0].normal.velocity", "um/s"},
                                                         {"law.friction.kappa", "1/um"},
                                                         {"law.friction.xi", "1/s"},
                                                         {"law.overstress.eta_v", "s/um"},
                                                         {"law.overstress.n", "1"},
                                                         {"contact.alpha_t", "GPa/um"},
                                                         {"contact.normal_traction", "GPa"},
                                                         {"initial.mu", "1"},
                                                         {"loading[0].increments", "1"},
                                                         {"law.subloading.function", ""},
                                                         {"integrator.method", ""}};
  for (const auto& [path, unit] : contact)
    EXPECT_EQ(sweep_unit(SceneKind::contact, path, u), unit) << path;
  const std::pair<const char*, const char*> crystal[] = {
      {"loading[0].L[2][2]", "1/s"},
      {"loading[0].L", "1/s"},
      {"loading[0].stress[0][0]", "GPa"},
      {"loading[0].duration", "s"},
      {"loading[0].strain", "1"},
      {"phase.tau0", "GPa"},
      {"phase.elasticity.C44", "GPa"},
      {"phase.elasticity.nu", "1"},
      {"phase.law.friction.kappa", "1"},
      {"phase.law.overstress.eta_v", "s"},
      {"phase.per_family.fcc_111_110.law.friction.xi", "1/s"},
      {"phase.per_family.hcp_basal_a.tau0", "GPa"},
      {"orientations.component.spread_deg", "deg"},
      {"phase.kinematics", ""}};
  for (const auto& [path, unit] : crystal)
    EXPECT_EQ(sweep_unit(SceneKind::crystal, path, u), unit) << path;
}
