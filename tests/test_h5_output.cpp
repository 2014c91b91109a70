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

#include "subslip/io/contact_output.hpp"
#include "subslip/io/contact_scene.hpp"
#include "subslip/io/h5_writer.hpp"

namespace fs = std::filesystem;
using namespace subslip;
using namespace subslip::io;

namespace {

const std::string kScene = R"(scene: contact
title: "h5 test"
units: {stress: MPa, length: mm, time: min}
law:
  friction: {mu_s: 0.097, mu_k: 0.085, kappa: 0.2, xi: 0.009}
  subloading: {function: cot, u_tilde: 80}
  overstress: {form: exponential, eta_v: 950, n: 16, r_hat: 1.8}
contact: {alpha_n: 1.0e6, alpha_t: 1.0e6, normal_traction: 5.56}
loading:
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
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir = fs::temp_directory_path() / ("subslip_h5_" + std::string(info->name()) +
                                                    "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

struct Recorded {
  std::vector<contact::ContactState> states;
  std::vector<int> segments;
};

Recorded run_directly(const ContactCase& c) {
  Recorded r;
  contact::run_history(c.model, c.segments, c.integrator,
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
  ContactRunOptions options;
  options.threads = threads;
  const auto results = run_contact_scene(scene, file, options);
  for (const auto& r : results) EXPECT_TRUE(r.failure.empty()) << r.failure;
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
  EXPECT_EQ(root.attribute_int("format_version"), 1);
  EXPECT_EQ(root.attribute_string("program_version"), SUBSLIP_VERSION);
  EXPECT_EQ(root.attribute_string("scene_kind"), "contact");
  EXPECT_EQ(root.attribute_string("scene_file"), "h5_test.yaml");
  EXPECT_EQ(root.attribute_string("title"), "h5 test");
  EXPECT_EQ(root.attribute_int("completed"), 1);
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
    EXPECT_EQ(ds.filters(), (std::vector<std::string>{"shuffle", "deflate"}));
    EXPECT_FALSE(ds.chunk_shape().empty());
  }
  EXPECT_EQ(g.open_dataset("time").attribute_string("unit"), "min");
  EXPECT_EQ(g.open_dataset("slip").attribute_string("unit"), "mm");
  EXPECT_EQ(g.open_dataset("traction").attribute_string("unit"), "MPa");
  EXPECT_EQ(g.open_dataset("ratio").attribute_string("unit"), "1");
  EXPECT_EQ(g.open_dataset("slip").shape(), (std::vector<std::size_t>{n, 2}));
  EXPECT_EQ(g.open_dataset("traction").shape(), (std::vector<std::size_t>{n, 3}));

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
  EXPECT_FALSE(g.has_attribute("failed"));
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
  EXPECT_EQ(g.attribute_string("sweep:law.subloading.function"), "reciprocal");
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
    for (int i = 0; i < 100; ++i) {
      one.append(0.5 * i);
      const double row[3] = {1.0 * i, 2.0 * i, 3.0 * i};
      two.append(row);
      ints.append_int(-i);
      if (i == 50) {  // a mid-run commit, as a flush does
        one.commit();
        EXPECT_EQ(one.dataset().shape().front(), 51u);
      }
    }
    EXPECT_EQ(one.rows(), 100u);
    one.commit();
    two.commit();
    ints.commit();
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
  ASSERT_EQ(one.size(), 100u);
  ASSERT_EQ(two.size(), 300u);
  ASSERT_EQ(ints.size(), 100u);
  for (int i = 0; i < 100; ++i) {
    EXPECT_EQ(one[i], 0.5 * i);
    EXPECT_EQ(two[3 * i + 2], 3.0 * i);
    EXPECT_EQ(ints[i], -i);
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
// opens and holds every row up to its last flush, with completed = 0.
TEST(H5Writer, FileFlushedBeforeACrashIsReadable) {
  const fs::path dir = scratch_dir();
  const fs::path path = dir / "crash.h5";
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    h5::File file = h5::File::create(path, false);
    h5::write_result_header(file, {"contact", "crash.yaml", "scene: contact\n", "crash", {}});
    h5::Series s = file.root().create_series({"x", 0, h5::Type::float64, "1", "x", 16, 4});
    for (int i = 0; i < 10; ++i) s.append(1.0 * i);
    s.commit();
    file.flush();
    for (int i = 0; i < 10; ++i) s.append(-1.0);  // never flushed
    ::_exit(0);  // no destructors, no HDF5 atexit close: like a kill
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  const h5::File file = h5::File::open_read(path);
  EXPECT_EQ(file.root().attribute_int("completed"), 0);
  const auto x = file.root().open_dataset("x").read_doubles();
  ASSERT_EQ(x.size(), 10u);
  EXPECT_EQ(x[9], 9.0);
  fs::remove_all(dir);
}
