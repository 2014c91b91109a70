// Finished result files (io/result_file.hpp): once every case ended, a result holds exactly
// its rows (no NaN or INT_MIN reservation, no checkpoint); the copy that replaces the working
// file is atomic, so a failure (or a kill) while it is written leaves the working file, which
// --restart finishes; checkpoints live in the restart file next to the result, deleted at the
// end unless --keep-restart.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include "child_process.hpp"
#include "scene_text.hpp"
#include "scratch_dir.hpp"
#include "subslip/driver/contact_run.hpp"
#include "subslip/io/contact_output.hpp"
#include "subslip/io/contact_scene.hpp"
#include "subslip/io/h5_writer.hpp"
#include "subslip/io/result_file.hpp"
#include "subslip/io/result_protocol.hpp"

namespace fs = std::filesystem;
using namespace subslip;
using namespace subslip::io;
using subslip::testing::read_text;
using subslip::testing::run_subslip;

namespace {

const fs::path kSource = SUBSLIP_SOURCE_DIR;

fs::path scratch_dir() {
  return subslip::testing::scratch_dir("result_file");
}

// The extents and values of every series (chunked dataset) of every case: counts the series
// whose extent is not the case's /progress rows, and the values that are NaN (float) or
// INT_MIN (int32), the fills of reserved rows. `series` counts the series looked at.
struct Padding {
  std::size_t series = 0;
  std::size_t wrong_extent = 0;
  std::size_t fill_values = 0;
  std::string first_wrong;  // the first series whose extent is wrong
};

void scan(const h5::Group& g, std::size_t rows, Padding& p, const std::string& path) {
  for (const auto& name : g.members()) {
    SCOPED_TRACE(path + "/" + name);
    if (g.is_group(name)) {
      scan(g.open_group(name), rows, p, path + "/" + name);
      continue;
    }
    const h5::Dataset d = g.open_dataset(name);
    if (d.chunk_shape().empty()) continue;  // a fixed array (weights, slip systems)
    ++p.series;
    if (d.shape().front() != rows) {
      ++p.wrong_extent;
      p.first_wrong = path + "/" + name + ": " + std::to_string(d.shape().front()) +
                      " rows, /progress " + std::to_string(rows);
    }
    if (d.value_class() == h5::ValueClass::integer) {
      for (long long v : d.read_ints()) p.fill_values += v == h5::kInt32Fill ? 1 : 0;
    } else {
      for (double v : d.read_doubles()) p.fill_values += std::isnan(v) ? 1 : 0;
    }
  }
}

Padding padding_of(const fs::path& file) {
  const h5::File f = h5::File::open_read(file);
  const h5::Group root = f.root();
  const auto names = root.open_group("cases").attribute_strings("names");
  const h5::CaseProgress progress = h5::CaseProgress::open(root);
  Padding p;
  for (std::size_t k = 0; k < names.size(); ++k) {
    const h5::Group c = root.open_group("cases").open_group(names[k]);
    scan(c, static_cast<std::size_t>(progress.rows(k)), p, "/cases/" + names[k]);
  }
  return p;
}

// A finished file: finished = 1, completed = 1, no checkpoint, every series exactly its rows
// and not one fill value in them.
void expect_exact(const fs::path& file) {
  SCOPED_TRACE(file.string());
  const h5::File f = h5::File::open_read(file);
  EXPECT_EQ(f.root().attribute_int("finished"), 1);
  EXPECT_EQ(f.root().attribute_int("completed"), 1);
  EXPECT_FALSE(f.root().has("checkpoint"));
  const Padding p = padding_of(file);
  EXPECT_GT(p.series, 0u);
  EXPECT_EQ(p.wrong_extent, 0u) << p.first_wrong;
  EXPECT_EQ(p.fill_values, 0u);
}

// A small copper polycrystal in tension (4 grains, 20 increments).
std::string small_crystal(const std::string& extra) {
  return subslip::testing::copper_scene_start() + R"(orientations:
  random: {count: 4, seed: 3}
loading:
  - L: [[x, 0, 0], [0, x, 0], [0, 0, 1.0e-3]]
    stress: [[0, x, x], [x, 0, x], [x, x, x]]
    duration: 5
    increments: 20
)" + extra;
}

int run_logged(const fs::path& dir, const std::vector<std::string>& args) {
  return run_subslip(dir, args, dir / "run.log");
}

}  // namespace

// The shipped adaptive contact scene (5 segments given as one increment each, hundreds of
// adaptive steps: the series outgrow their planned rows and double) and an adaptive crystal
// scene with per-grain series (fewer steps than its increments plan): every series of the
// finished file holds exactly the rows /progress counts, with no NaN or INT_MIN fill.
TEST(FinishedFile, AdaptiveScenesHoldExactlyTheirRows) {
  const fs::path dir = scratch_dir();
  for (const fs::path& scene : {kSource / "inputs/adaptive_hold_and_impact.yaml",
                                kSource / "tests/data/post/crystal_adaptive.yaml"}) {
    const std::string out = scene.stem().string() + ".h5";
    ASSERT_EQ(run_logged(dir, {"run", scene.string(), "-o", out, "-q"}), 0)
        << read_text(dir / "run.log");
    expect_exact(dir / out);
    EXPECT_FALSE(fs::exists(dir / (out + ".finishing")));
    EXPECT_FALSE(fs::exists(restart_file_for(dir / out)));
  }
  fs::remove_all(dir);
}

// The series of a finished file as output.compression says: shuffled and deflated at the level
// asked (by default too), or stored plain with `none`; the values read back are the same bits.
TEST(FinishedFile, SeriesAreCompressedAsTheSceneSays) {
  const fs::path dir = scratch_dir();
  const std::string scene = subslip::testing::copper_scene_start("title: compression\n") +
                            R"(orientations:
  random: {count: 40, seed: 3}
loading:
  - L: [[x, 0, 0], [0, x, 0], [0, 0, 1.0e-3]]
    stress: [[0, x, x], [x, 0, x], [x, x, x]]
    duration: 10
    increments: 20
output:
  grains: [stress, slip, r_s]
)";
  // (the level each file asks for; 0: none)
  const std::vector<std::pair<std::string, int>> variants{
      {"", 1}, {"  compression: none\n", 0}, {"  compression: gzip\n  compression_level: 7\n", 7}};
  for (std::size_t k = 0; k < variants.size(); ++k) {
    const auto& [extra, level] = variants[k];
    SCOPED_TRACE(extra);
    const std::string name = std::array{"v0", "v1", "v2"}.at(k);
    std::ofstream(dir / (name + ".yaml")) << scene << extra;
    ASSERT_EQ(run_logged(dir, {"run", name + ".yaml", "-o", name + ".h5", "-q"}), 0)
        << read_text(dir / "run.log");
    const h5::File f = h5::File::open_read(dir / (name + ".h5"));
    EXPECT_EQ(f.root().attribute_int("gzip_level"), level);
    const h5::Group base = f.root().open_group("cases").open_group("base");
    for (const h5::Dataset& series :
         {base.open_group("grains").open_dataset("stress"),
          base.open_group("macro").open_dataset("stress")}) {
      const std::vector<std::string> expected =
          level > 0 ? std::vector<std::string>{"shuffle", "deflate"} : std::vector<std::string>{};
      EXPECT_EQ(series.filters(), expected);
    }
    expect_exact(dir / (name + ".h5"));
    if (k > 0) subslip::testing::expect_same_datasets(dir / "v0.h5", dir / (name + ".h5"));
  }
  fs::remove_all(dir);
}

// The working file of the same kind of run (closed without finishing) does have reserved rows:
// the check above is not vacuous; finishing it removes them and keeps every valid value.
TEST(FinishedFile, FinishingDropsTheReservationAndKeepsTheRows) {
  const fs::path dir = scratch_dir();
  const ContactScene scene =
      load_contact_scene((kSource / "inputs/adaptive_hold_and_impact.yaml").string());
  const fs::path path = dir / "working.h5";
  {
    h5::File file = h5::File::create(path, false);
    ContactResultSink sink(scene, file, {});
    const auto results = driver::run_contact_scene(scene, sink);
    ASSERT_TRUE(results.at(0).failure.empty());
    file.close();
  }
  const Padding working = padding_of(path);
  EXPECT_GT(working.wrong_extent, 0u);
  EXPECT_GT(working.fill_values, 0u);
  const auto before = subslip::testing::case_datasets(path);
  EXPECT_EQ(h5::File::open_read(path).root().attribute_int("finished"), 0);
  EXPECT_TRUE(every_case_ended(path));
  EXPECT_TRUE(finish_result(path));
  expect_exact(path);
  const auto after = subslip::testing::case_datasets(path);
  ASSERT_EQ(before.size(), after.size());
  const auto rows =
      static_cast<std::size_t>(h5::CaseProgress::open(h5::File::open_read(path).root()).rows(0));
  for (const auto& [name, got] : after) {
    SCOPED_TRACE(name);
    const auto& was = before.at(name);
    ASSERT_EQ(got.shape.front(), rows);
    ASSERT_EQ(std::vector<std::size_t>(got.shape.begin() + 1, got.shape.end()),
              std::vector<std::size_t>(was.shape.begin() + 1, was.shape.end()));
    for (std::size_t i = 0; i < got.values.size(); ++i)
      ASSERT_TRUE(subslip::testing::same_bits(got.values[i], was.values[i])) << i;
  }
  // Attributes come along in their order; the reserved `failed` becomes a plain string.
  const h5::File f = h5::File::open_read(path);
  const h5::Group c = f.root().open_group("cases").open_group("base");
  EXPECT_EQ(c.attribute_names().front(), "name");
  EXPECT_EQ(c.attribute_class("failed"), h5::ValueClass::string);
  EXPECT_EQ(h5::failure_message(c), "");
  EXPECT_EQ(f.root().attribute_string("write_error"), "");
  fs::remove_all(dir);
}

// The finished file cannot be written (here: its temporary name is taken by a directory; a full
// disk or a kill while it is written leaves the same state): the run says so, the working file
// is kept as it was with every row, and --restart finishes it into what an uninterrupted run
// writes. A stale temporary file (a kill while it was written) is simply replaced.
TEST(FinishedFile, FailedFinishKeepsTheWorkingFileAndRestartFinishesIt) {
  const fs::path dir = scratch_dir();
  // (order 1: many steps from the 2 increments, rows that outgrow the planned ones)
  std::ofstream(dir / "scene.yaml") << subslip::testing::contact_scene_start() +
                                           "integrator: {method: implicit, tolerance: 1.0e-5, "
                                           "order: 1}\n"
                                           "loading:\n"
                                           "  - slide: {speed: 1.0, distance: 1.0}\n"
                                           "    increments: 2\n";
  ASSERT_EQ(run_logged(dir, {"run", "scene.yaml", "-o", "ref.h5", "-q"}), 0)
      << read_text(dir / "run.log");
  fs::create_directories(dir / "out.h5.finishing/blocked");
  EXPECT_EQ(run_logged(dir, {"run", "scene.yaml", "-o", "out.h5", "-q"}), 1);
  const std::string log = read_text(dir / "run.log");
  EXPECT_EQ(log.rfind("subslip: error: out.h5: cannot write the finished file (", 0), 0u) << log;
  EXPECT_NE(log.find("finish it with --restart out.h5"), std::string::npos) << log;
  {
    const h5::File f = h5::File::open_read(dir / "out.h5");
    EXPECT_EQ(f.root().attribute_int("finished"), 0);
    EXPECT_EQ(f.root().attribute_int("completed"), 0);
    EXPECT_NE(f.root().attribute_string("write_error").find("cannot write the finished file"),
              std::string::npos);
    EXPECT_EQ(h5::CaseProgress::open(f.root()).state(0), h5::CaseState::completed);
  }
  EXPECT_GT(padding_of(dir / "out.h5").fill_values, 0u);  // the working file
  fs::remove_all(dir / "out.h5.finishing");
  std::ofstream(dir / "out.h5.finishing") << "a copy cut short by a kill\n";
  ASSERT_EQ(run_logged(dir, {"run", "--restart", "out.h5", "-q"}), 0) << read_text(dir / "run.log");
  expect_exact(dir / "out.h5");
  EXPECT_FALSE(fs::exists(dir / "out.h5.finishing"));
  EXPECT_EQ(h5::File::open_read(dir / "out.h5").root().attribute_string("write_error"), "");
  subslip::testing::expect_same_datasets(dir / "ref.h5", dir / "out.h5");
  // Now finished: nothing is left to restart.
  EXPECT_EQ(run_logged(dir, {"run", "--restart", "out.h5", "-q"}), 2);
  EXPECT_NE(read_text(dir / "run.log").find("cannot restart: the run completed"),
            std::string::npos);
  fs::remove_all(dir);
}

TEST(RestartFile, NamedAfterTheResult) {
  EXPECT_EQ(restart_file_for("results/default.h5"), fs::path("results/default.restart.h5"));
  EXPECT_EQ(restart_file_for("out"), fs::path("out.restart.h5"));
  EXPECT_EQ(restart_file_for("a.hdf5"), fs::path("a.hdf5.restart.h5"));
  EXPECT_EQ(finishing_file_for("r/x.h5"), fs::path("r/x.h5.finishing"));
}

// A crystal run with checkpoints: the restart file is deleted when the run finishes, kept with
// --keep-restart (a subslip restart file of the result's run), and a file at its path that is
// not a restart file is never replaced; one of an interrupted run only with --force.
TEST(RestartFile, DeletedAtTheEndUnlessKept) {
  const fs::path dir = scratch_dir();
  std::ofstream(dir / "scene.yaml") << small_crystal("output:\n  checkpoint_every: 2\n");
  ASSERT_EQ(run_logged(dir, {"run", "scene.yaml", "-o", "a.h5", "-q"}), 0)
      << read_text(dir / "run.log");
  EXPECT_FALSE(fs::exists(dir / "a.restart.h5"));
  ASSERT_EQ(run_logged(dir, {"run", "scene.yaml", "-o", "b.h5", "-q", "--keep-restart"}), 0)
      << read_text(dir / "run.log");
  std::string run_id;
  ASSERT_TRUE(is_restart_file(dir / "b.restart.h5", &run_id));
  EXPECT_EQ(run_id, h5::File::open_read(dir / "b.h5").root().attribute_string("run_id"));
  EXPECT_FALSE(h5::File::open_read(dir / "b.h5").root().has("checkpoint"));
  {
    const h5::File r = h5::File::open_read(dir / "b.restart.h5");
    EXPECT_GT(r.root().open_group("checkpoint").attribute_int("capacity"), 0);
  }
  subslip::testing::expect_same_datasets(dir / "a.h5", dir / "b.h5");

  // b.restart.h5 is left from b.h5's run: a new run into b.h5 replaces it only with --force.
  EXPECT_EQ(run_logged(dir, {"run", "scene.yaml", "-o", "b.h5", "-q", "--force"}), 0)
      << read_text(dir / "run.log");
  EXPECT_FALSE(fs::exists(dir / "b.restart.h5"));
  ASSERT_EQ(run_logged(dir, {"run", "scene.yaml", "-o", "c.h5", "-q", "--keep-restart"}), 0);
  fs::remove(dir / "c.h5");
  EXPECT_EQ(run_logged(dir, {"run", "scene.yaml", "-o", "c.h5", "-q"}), 2);
  EXPECT_NE(read_text(dir / "run.log").find("c.restart.h5: already exists"), std::string::npos)
      << read_text(dir / "run.log");
  // Not a restart file: refused, --force or not, and left alone.
  std::ofstream(dir / "d.restart.h5") << "my notes\n";
  EXPECT_EQ(run_logged(dir, {"run", "scene.yaml", "-o", "d.h5", "-q", "--force"}), 2);
  EXPECT_NE(read_text(dir / "run.log").find("d.restart.h5: exists and is not a subslip restart"),
            std::string::npos)
      << read_text(dir / "run.log");
  EXPECT_EQ(read_text(dir / "d.restart.h5"), "my notes\n");
  EXPECT_FALSE(fs::exists(dir / "d.h5"));
  fs::remove_all(dir);
}
