// subslip post (src/io/result_post.cpp, result_csv.cpp, result_table.cpp; src/cli/post.cpp): the
// summary names the cases, units and datasets; CSV export gives back every number of a dataset
// exactly (compared with reading the HDF5 file directly); bad names are one clear error; nothing
// is overwritten silently.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "shell_command.hpp"
#include "subslip/crystal/measures.hpp"
#include "subslip/driver/contact_run.hpp"
#include "subslip/driver/crystal_run.hpp"
#include "subslip/io/contact_output.hpp"
#include "subslip/io/contact_scene.hpp"
#include "subslip/io/crystal_output.hpp"
#include "subslip/io/crystal_scene.hpp"
#include "subslip/io/h5_writer.hpp"
#include "subslip/io/input_error.hpp"
#include "subslip/io/result_file.hpp"
#include "subslip/io/result_post.hpp"
#include "subslip/io/result_protocol.hpp"
#include "subslip/io/yaml_checked.hpp"

namespace fs = std::filesystem;
using namespace subslip;
using namespace subslip::io;

namespace {

const fs::path kSource = SUBSLIP_SOURCE_DIR;
const fs::path kData = kSource / "tests" / "data" / "post";

// The two small results the tests read, each written once per process (on first use: the
// crystal one takes a moment) into one directory per process, removed at exit.
struct ScratchRoot : ::testing::Environment {
  static fs::path path() {
    return fs::temp_directory_path() / ("subslip_post_" + std::to_string(::getpid()));
  }
  void TearDown() override { fs::remove_all(path()); }
};
const auto* const kScratchRoot = ::testing::AddGlobalTestEnvironment(new ScratchRoot);

const fs::path& contact_result() {
  static const fs::path path = [] {
    fs::create_directories(ScratchRoot::path());
    const fs::path out = ScratchRoot::path() / "contact.h5";
    const auto scene = parse_contact_scene(YamlDocument::from_file(kData / "contact_small.yaml"));
    h5::File file = h5::File::create(out, true);
    ContactResultSink sink(scene, file, {});
    for (const auto& c : driver::run_contact_scene(scene, sink)) EXPECT_TRUE(c.failure.empty());
    close_and_finish(file);
    return out;
  }();
  return path;
}

const fs::path& crystal_result() {
  static const fs::path path = [] {
    fs::create_directories(ScratchRoot::path());
    const fs::path out = ScratchRoot::path() / "crystal.h5";
    const auto scene = parse_crystal_scene(YamlDocument::from_file(kData / "crystal_small.yaml"));
    h5::File file = h5::File::create(out, true);
    CrystalResultSink sink(scene, file, {});
    for (const auto& c : driver::run_crystal_scene(scene, sink)) EXPECT_TRUE(c.failure.empty());
    close_and_finish(file);
    return out;
  }();
  return path;
}

fs::path scratch_dir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir = ScratchRoot::path() / info->name();
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

std::string summary(const fs::path& file, const std::string& case_name = "") {
  std::ostringstream out;
  post::print_summary(out, file, case_name);
  return out.str();
}

bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

// A CSV file: the header fields and the rows as text fields (quoted fields unquoted).
struct Csv {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
};

std::vector<std::string> csv_fields(const std::string& line) {
  std::vector<std::string> fields(1);
  bool quoted = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted && c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
      fields.back() += '"';
      ++i;
    } else if (c == '"') {
      quoted = !quoted;
    } else if (c == ',' && !quoted) {
      fields.emplace_back();
    } else {
      fields.back() += c;
    }
  }
  return fields;
}

Csv read_csv(const fs::path& p) {
  std::ifstream in(p);
  Csv csv;
  std::string line;
  if (std::getline(in, line)) csv.header = csv_fields(line);
  while (std::getline(in, line)) csv.rows.push_back(csv_fields(line));
  return csv;
}

double number(const std::string& text) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  EXPECT_EQ(*end, '\0') << "not a number: '" << text << "'";
  return v;
}

std::vector<double> read_dataset(const fs::path& file, const std::string& path) {
  const h5::File f = h5::File::open_read(file);
  return f.root().open_dataset(path).read_doubles();
}

post::CsvOptions csv_options(const fs::path& dir, const std::string& case_name,
                             std::vector<std::string> datasets) {
  post::CsvOptions o;
  o.directory = dir;
  o.case_name = case_name;
  o.datasets = std::move(datasets);
  return o;
}

const std::string kCrystalCase = "L[2][2]=1.0e-3";

}  // namespace

// ---------------------------------------------------------------- summary

TEST(PostSummary, ContactNamesCasesUnitsAndDatasets) {
  const std::string s = summary(contact_result());
  EXPECT_TRUE(
      contains(s, "format:      subslip, format_version " + std::to_string(h5::kFormatVersion)))
      << s;
  EXPECT_TRUE(contains(s, "computed:    " + std::string(SUBSLIP_BUILD) + " build\n")) << s;
  EXPECT_TRUE(contains(s, "scene kind:  contact")) << s;
  EXPECT_TRUE(contains(s, "title:       post test: figure 11a law")) << s;
  EXPECT_TRUE(contains(s, "completed:   yes")) << s;
  EXPECT_TRUE(contains(s, "units:       stress MPa, length mm, time min")) << s;
  EXPECT_TRUE(contains(s, "cases:       2: speed=1, speed=200")) << s;
  EXPECT_TRUE(contains(s, "\ncase speed=1 (index 0)\n")) << s;
  EXPECT_TRUE(contains(s, "\ncase speed=200 (index 1)\n")) << s;
  // Attributes carry their `.unit` sibling; the value is the attribute read directly.
  const h5::File f = h5::File::open_read(contact_result());
  const h5::Group g = f.root().open_group("cases/speed=200");
  char eta[32];
  std::snprintf(eta, sizeof eta, "%.6g", g.attribute_double("eta_v"));
  EXPECT_TRUE(contains(s, std::string("eta_v") + " ")) << s;
  EXPECT_TRUE(contains(s, std::string(" = ") + eta + " min/mm\n")) << s;
  EXPECT_FALSE(contains(s, "eta_v.unit")) << s;
  // Every dataset with its shape (101 rows: the initial state and 100 increments) and unit.
  for (const char* line : {"slip_path  [101]     [mm]", "slip       [101, 2]  [mm]",
                           "ratio      [101]     [1]", "time       [101]     [min]"}) {
    EXPECT_TRUE(contains(s, line)) << line << "\n" << s;
  }
}

TEST(PostSummary, CrystalListsGrainDatasetsWithTheirShapes) {
  // crystal_small.yaml: 20 increments (+ the initial state), 20 grains, 12 FCC systems.
  const std::string s = summary(crystal_result(), kCrystalCase);
  EXPECT_TRUE(contains(s, "scene kind:  crystal")) << s;
  EXPECT_TRUE(contains(s, "units:       stress MPa, time s")) << s;
  EXPECT_TRUE(contains(s, "case L[2][2]=1.0e-3 (index 0)")) << s;
  EXPECT_FALSE(contains(s, "case L[2][2]=1.0e-1 (index")) << "--case selects one case\n" << s;
  EXPECT_TRUE(contains(s, "macro/stress                [21, 3, 3]      [MPa]")) << s;
  EXPECT_TRUE(contains(s, "grains/stress               [21, 20, 3, 3]  [MPa]")) << s;
  EXPECT_TRUE(contains(s, "grains/crss                 [21, 20, 12]    [MPa]")) << s;
  EXPECT_TRUE(contains(s, "grains/orientation          [21, 20, 4]     [1]")) << s;
  EXPECT_TRUE(contains(s, "tau0                     = 10 (x12) MPa")) << s;
}

namespace {

// A run killed in its first case: case `a` wrote 5 valid rows of `time` and `ratio` after which
// its series hold reserved rows (NaN here), case `b` has a group but never started; /progress
// says so (docs/scenes.md). Written with the plain array API, as any writer could.
fs::path write_interrupted_run(const fs::path& dir) {
  const fs::path path = dir / "partial.h5";
  h5::File file = h5::File::create(path, false);
  h5::write_result_header(
      file, {"contact", "x.yaml", "scene: contact\n", "partial", {{"time", "min"}}, {}});
  const h5::Group cases = file.root().create_group("cases");
  cases.set_attribute("names", std::vector<std::string>{"a", "b"});
  {
    const h5::Group a = cases.create_group("a");
    h5::Series time = a.create_series({"time", 0, h5::Type::float64, "min", "time"});
    h5::Series ratio = a.create_series({"ratio", 0, h5::Type::float64, "1", "f_t / f_n"});
    for (int i = 0; i < 8; ++i) {
      time.append(i < 5 ? 0.5 * i : std::nan(""));
      ratio.append(i < 5 ? 0.1 * i : std::nan(""));
    }
    time.commit();
    ratio.commit();
  }
  cases.create_group("b");
  const h5::Group progress = file.root().create_group("progress");
  const std::size_t two[1] = {2};
  progress.write_array("rows", two, std::vector<double>{5, 0}, "1", "valid rows");
  progress.write_array("state", two, std::vector<double>{1, 0}, "1", "0 not started, 1 running");
  return path;
}

}  // namespace

TEST(PostSummary, AnInterruptedRunShowsItsValidRowsAndUnstartedCases) {
  const fs::path file = write_interrupted_run(scratch_dir());
  const std::string s = summary(file);
  EXPECT_TRUE(contains(s, "completed:   NO")) << s;
  EXPECT_TRUE(contains(s, "case a: RUNNING or interrupted, 5 valid rows\n")) << s;
  EXPECT_TRUE(contains(s, "ratio  [5]  [1]")) << s;
  EXPECT_TRUE(contains(s, "case b: not started")) << s;
}

// ---------------------------------------------------------------- CSV export

TEST(PostCsv, A2DSeriesRoundTripsExactly) {
  const fs::path dir = scratch_dir();
  const auto written =
      post::export_csv(crystal_result(), csv_options(dir, kCrystalCase, {"macro/stress"}));
  ASSERT_EQ(written.size(), 1u);
  EXPECT_EQ(written[0], dir / "L_2__2_=1.0e-3_macro_stress.csv");
  const Csv csv = read_csv(written[0]);
  const std::vector<std::string> header{"step",
                                        "time [s]",
                                        "stress_11 [MPa]",
                                        "stress_12 [MPa]",
                                        "stress_13 [MPa]",
                                        "stress_21 [MPa]",
                                        "stress_22 [MPa]",
                                        "stress_23 [MPa]",
                                        "stress_31 [MPa]",
                                        "stress_32 [MPa]",
                                        "stress_33 [MPa]"};
  EXPECT_EQ(csv.header, header);
  const std::string base = "cases/" + kCrystalCase + "/macro/";
  const auto stress = read_dataset(crystal_result(), base + "stress");
  const auto time = read_dataset(crystal_result(), base + "time");
  ASSERT_EQ(csv.rows.size(), time.size());
  for (std::size_t i = 0; i < csv.rows.size(); ++i) {
    ASSERT_EQ(csv.rows[i].size(), 11u);
    EXPECT_EQ(number(csv.rows[i][0]), static_cast<double>(i));
    EXPECT_EQ(number(csv.rows[i][1]), time[i]);
    for (std::size_t k = 0; k < 9; ++k) EXPECT_EQ(number(csv.rows[i][2 + k]), stress[9 * i + k]);
  }
}

// A per-grain tensor [n, G, 3, 3]: nine columns 11 ... 33 per (step, grain), or per step for one
// grain; [step, grain, i, j] of the file is column ij.
TEST(PostCsv, PerGrainTensorIsNineColumnsOfItsComponents) {
  const fs::path dir = scratch_dir();
  const std::string path = "cases/" + kCrystalCase + "/grains/stress";
  const auto stress = read_dataset(crystal_result(), path);  // [21, 20, 3, 3]
  const std::size_t n = 21, grains = 20;
  ASSERT_EQ(stress.size(), n * grains * 9);
  const auto all =
      post::export_csv(crystal_result(), csv_options(dir, kCrystalCase, {"grains/stress"}));
  ASSERT_EQ(all.size(), 1u);
  const Csv csv = read_csv(all[0]);
  const std::vector<std::string> header{"step",
                                        "time [s]",
                                        "grain",
                                        "stress_11 [MPa]",
                                        "stress_12 [MPa]",
                                        "stress_13 [MPa]",
                                        "stress_21 [MPa]",
                                        "stress_22 [MPa]",
                                        "stress_23 [MPa]",
                                        "stress_31 [MPa]",
                                        "stress_32 [MPa]",
                                        "stress_33 [MPa]"};
  EXPECT_EQ(csv.header, header);
  ASSERT_EQ(csv.rows.size(), n * grains);
  for (std::size_t r = 0; r < csv.rows.size(); ++r) {
    for (std::size_t c = 0; c < 9; ++c) EXPECT_EQ(number(csv.rows[r][3 + c]), stress[9 * r + c]);
  }
  // Symmetric: 12 = 21, 13 = 31, 23 = 32.
  for (const auto& row : csv.rows) {
    EXPECT_EQ(row[4], row[6]);
    EXPECT_EQ(row[5], row[9]);
    EXPECT_EQ(row[8], row[10]);
  }
  auto options = csv_options(dir, kCrystalCase, {"grains/stress"});
  options.grain = 3;
  const auto one = post::export_csv(crystal_result(), options);
  ASSERT_EQ(one.size(), 1u);
  const Csv g3 = read_csv(one[0]);
  ASSERT_EQ(g3.header.size(), 2u + 9u);
  ASSERT_EQ(g3.rows.size(), n);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t c = 0; c < 9; ++c)
      EXPECT_EQ(number(g3.rows[i][2 + c]), stress[(i * grains + 3) * 9 + c]);
  }
}

// Per-grain rows at a coarser spacing (output.grains_at): the steps of a per-grain CSV are the
// output rows its rows are at (grains/row), with their times; the summary shows each series
// with its own valid rows.
TEST(PostCsv, PerGrainRowsAtCoarserPointsCarryTheirOutputRowsAndTimes) {
  const fs::path dir = scratch_dir();
  const fs::path file = dir / "grains_at.h5";
  {
    const auto scene =
        parse_crystal_scene(YamlDocument::from_file(kData / "crystal_grains_at.yaml"));
    h5::File f = h5::File::create(file, true);
    CrystalResultSink sink(scene, f, {});
    for (const auto& c : driver::run_crystal_scene(scene, sink)) EXPECT_TRUE(c.failure.empty());
    close_and_finish(f);
  }
  const auto written = post::export_csv(file, csv_options(dir, "base", {"grains/slip"}));
  ASSERT_EQ(written.size(), 1u);
  const Csv csv = read_csv(written[0]);
  ASSERT_GE(csv.header.size(), 3u);
  EXPECT_EQ(csv.header[1], "time [s]");
  const auto time = read_dataset(file, "cases/base/macro/time");
  ASSERT_EQ(time.size(), 21u);
  const std::size_t grains = 8;
  ASSERT_EQ(csv.rows.size(), 4 * grains);
  const double steps[] = {0, 5, 10, 20};
  for (std::size_t r = 0; r < csv.rows.size(); ++r) {
    const double step = steps[r / grains];
    EXPECT_EQ(number(csv.rows[r][0]), step);
    EXPECT_EQ(number(csv.rows[r][1]), time[static_cast<std::size_t>(step)]);
  }
  const std::string s = summary(file, "base");
  EXPECT_TRUE(contains(s, "macro/time                  [21]          [s]")) << s;
  EXPECT_TRUE(contains(s, "grains/slip                 [4, 8, 12]    [1]")) << s;
}

TEST(PostCsv, PerGrainSeriesRoundTripInLongFormatAndForOneGrain) {
  const fs::path dir = scratch_dir();
  const std::string path = "cases/" + kCrystalCase + "/grains/";
  const auto crss = read_dataset(crystal_result(), path + "crss");  // [21, 20, 12]
  const std::size_t n = 21, grains = 20, k = 12;
  ASSERT_EQ(crss.size(), n * grains * k);
  const h5::File f = h5::File::open_read(crystal_result());
  const auto labels = f.root().open_dataset(path + "slip_systems").attribute_strings("labels");
  ASSERT_EQ(labels.size(), k);

  // Long: one row per (step, grain), columns step, time, grain, then one per slip system.
  const auto long_files = post::export_csv(
      crystal_result(), csv_options(dir, "", {"/cases/" + kCrystalCase + "/grains/crss"}));
  ASSERT_EQ(long_files.size(), 1u);
  const Csv csv = read_csv(long_files[0]);
  ASSERT_EQ(csv.header.size(), 3 + k);
  EXPECT_EQ(csv.header[2], "grain");
  for (std::size_t a = 0; a < k; ++a) EXPECT_EQ(csv.header[3 + a], "crss_" + labels[a] + " [MPa]");
  ASSERT_EQ(csv.rows.size(), n * grains);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t g = 0; g < grains; ++g) {
      const auto& row = csv.rows[i * grains + g];
      EXPECT_EQ(number(row[0]), static_cast<double>(i));
      EXPECT_EQ(number(row[2]), static_cast<double>(g));
      for (std::size_t a = 0; a < k; ++a)
        EXPECT_EQ(number(row[3 + a]), crss[(i * grains + g) * k + a]);
    }
  }

  // One grain: one row per step, no grain column.
  auto options = csv_options(dir, kCrystalCase, {"grains/crss"});
  options.grain = 7;
  const auto one = post::export_csv(crystal_result(), options);
  ASSERT_EQ(one.size(), 1u);
  EXPECT_EQ(one[0].filename(), "L_2__2_=1.0e-3_grains_crss_grain7.csv");
  const Csv g7 = read_csv(one[0]);
  ASSERT_EQ(g7.header.size(), 2 + k);
  ASSERT_EQ(g7.rows.size(), n);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t a = 0; a < k; ++a)
      EXPECT_EQ(number(g7.rows[i][2 + a]), crss[(i * grains + 7) * k + a]);
  }
}

TEST(PostCsv, ContactSeriesOfEveryCaseWithNamedColumns) {
  const fs::path dir = scratch_dir();
  const auto written = post::export_csv(contact_result(), csv_options(dir, "", {"slip", "ratio"}));
  ASSERT_EQ(written.size(), 4u);  // two datasets of two cases
  const Csv slip = read_csv(dir / "speed=200_slip.csv");
  EXPECT_EQ(slip.header,
            (std::vector<std::string>{"step", "time [min]", "slip_x [mm]", "slip_y [mm]"}));
  const Csv ratio = read_csv(dir / "speed=200_ratio.csv");
  EXPECT_EQ(ratio.header, (std::vector<std::string>{"step", "time [min]", "ratio [1]"}));
  const auto expected = read_dataset(contact_result(), "cases/speed=200/ratio");
  ASSERT_EQ(ratio.rows.size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i)
    EXPECT_EQ(number(ratio.rows[i][2]), expected[i]);
}

TEST(PostCsv, BadNamesAreOneClearErrorAndWriteNothing) {
  const fs::path dir = scratch_dir() / "out";
  const auto expect_input_error = [&](const fs::path& file, const post::CsvOptions& o,
                                      const std::string& part) {
    try {
      post::export_csv(file, o);
      ADD_FAILURE() << "no error; expected one containing: " << part;
    } catch (const InputError& e) {
      EXPECT_TRUE(contains(e.what(), part)) << e.what();
    }
    EXPECT_FALSE(fs::exists(dir)) << "nothing may be written before every name is checked";
  };
  expect_input_error(crystal_result(), csv_options(dir, "", {"macro/stress", "macro/stres"}),
                     "--dataset: no dataset 'macro/stres' in case 'L[2][2]=1.0e-3'");
  expect_input_error(crystal_result(), csv_options(dir, "", {"/cases/nope/macro/stress"}),
                     "no dataset or group '/cases/nope/macro/stress'");
  expect_input_error(crystal_result(), csv_options(dir, "", {"/scene"}), "holds text");
  expect_input_error(crystal_result(), csv_options(dir, "nope", {}), "--case: no case 'nope'");
  auto grain = csv_options(dir, kCrystalCase, {"grains/crss"});
  grain.grain = 20;
  expect_input_error(crystal_result(), grain, "--grain: grain 20 is out of range");
  expect_input_error(kData / "crystal_small.yaml", csv_options(dir, "", {}), "not an HDF5 file");
  expect_input_error(dir.parent_path() / "missing.h5", csv_options(dir, "", {}), "no such file");
  // An HDF5 file that subslip did not write.
  { h5::File other = h5::File::create(dir.parent_path() / "other.h5", false); }
  expect_input_error(dir.parent_path() / "other.h5", csv_options(dir, "", {}),
                     "not a subslip result file");
}

TEST(PostCsv, ExistingFilesAreNotOverwrittenWithoutForce) {
  const fs::path dir = scratch_dir();
  const auto options = csv_options(dir, "speed=1", {"ratio", "mu"});
  const auto written = post::export_csv(contact_result(), options);
  ASSERT_EQ(written.size(), 2u);
  std::ofstream(written[1]) << "sentinel\n";
  fs::remove(written[0]);
  try {
    post::export_csv(contact_result(), options);
    ADD_FAILURE() << "overwrote " << written[1];
  } catch (const h5::OutputPathError& e) {
    EXPECT_TRUE(contains(e.what(), written[1].string() + ": already exists; use --force"))
        << e.what();
  }
  EXPECT_EQ(read_csv(written[1]).header, std::vector<std::string>{"sentinel"});
  EXPECT_FALSE(fs::exists(written[0])) << "all files are checked before the first is written";
  auto forced = options;
  forced.force = true;
  EXPECT_EQ(post::export_csv(contact_result(), forced), written);
  EXPECT_EQ(read_csv(written[1]).header,
            (std::vector<std::string>{"step", "time [min]", "mu [1]"}));
}

TEST(PostCsv, AnInterruptedRunExportsOnlyItsValidRows) {
  const fs::path dir = scratch_dir();
  const fs::path file = write_interrupted_run(dir);
  const auto written = post::export_csv(file, csv_options(dir / "csv", "", {"ratio"}));
  ASSERT_EQ(written.size(), 1u) << "case b never started";
  const Csv csv = read_csv(written[0]);
  EXPECT_EQ(csv.header, (std::vector<std::string>{"step", "time [min]", "ratio [1]"}));
  ASSERT_EQ(csv.rows.size(), 5u);
  for (std::size_t i = 0; i < 5; ++i) {
    EXPECT_EQ(number(csv.rows[i][1]), 0.5 * static_cast<double>(i));
    EXPECT_EQ(number(csv.rows[i][2]), 0.1 * static_cast<double>(i));
  }
  try {
    post::export_csv(file, csv_options(dir / "csv", "b", {}));
    ADD_FAILURE() << "case b was exported";
  } catch (const InputError& e) {
    EXPECT_TRUE(contains(e.what(), "--case: case 'b' was not started")) << e.what();
  }
}

// ---------------------------------------------------------------- the command line

namespace {

struct Outcome {
  int code;
  std::string out, err;
};

Outcome run_subslip(const fs::path& dir, const std::string& args) {
  const fs::path err = dir / "stderr.txt";
  // append(): GCC 12 gives a false -Wrestrict warning on "literal" + std::string&&.
  std::string command = "cd '";
  command.append(dir.string()).append("' && '").append(SUBSLIP_BINARY).append("' ");
  command.append(args).append(" 2>'").append(err.string()).append("'");
  const auto [code, out] = subslip::testing::run_command(command);
  std::ifstream in(err);
  std::stringstream e;
  e << in.rdbuf();
  return {code, out, e.str()};
}

}  // namespace

TEST(PostCli, SummaryExportAndErrorsWithExitCodes) {
  const fs::path dir = scratch_dir();
  const std::string file = std::string("'").append(contact_result().string()).append("'");
  const Outcome s = run_subslip(dir, "post " + file + " --case speed=1");
  EXPECT_EQ(s.code, 0) << s.err;
  EXPECT_TRUE(contains(s.out, "case speed=1 (index 0)")) << s.out;

  const Outcome e = run_subslip(dir, "post " + file + " --csv csv --dataset ratio");
  EXPECT_EQ(e.code, 0) << e.err;
  EXPECT_TRUE(fs::exists(dir / "csv" / "speed=1_ratio.csv"));
  EXPECT_TRUE(fs::exists(dir / "csv" / "speed=200_ratio.csv"));

  const Outcome again = run_subslip(dir, "post " + file + " --csv csv --dataset ratio");
  EXPECT_EQ(again.code, 2);
  EXPECT_EQ(again.err,
            "subslip: error: csv/speed=1_ratio.csv: already exists; use --force to "
            "overwrite it\n");
  EXPECT_EQ(run_subslip(dir, "post " + file + " --csv csv --dataset ratio --force").code, 0);

  const Outcome bad = run_subslip(dir, "post " + file + " --csv csv --dataset ratoi");
  EXPECT_EQ(bad.code, 2);
  EXPECT_TRUE(contains(bad.err, "--dataset: no dataset 'ratoi' in case 'speed=1'")) << bad.err;
  EXPECT_EQ(std::count(bad.err.begin(), bad.err.end(), '\n'), 1) << "one line\n" << bad.err;

  EXPECT_EQ(run_subslip(dir, "post missing.h5").code, 2);
  EXPECT_EQ(run_subslip(dir, "post " + file + " --dataset ratio").code, 2)
      << "--dataset needs --csv";
}

// ---------------------------------------------------------------- one table per case

namespace {

post::TableOptions table_options(const fs::path& dir, const std::string& case_name,
                                 std::vector<std::string> quantities) {
  post::TableOptions o;
  o.directory = dir;
  o.case_name = case_name;
  o.quantities = std::move(quantities);
  return o;
}

// The column of `csv` named `name`, as numbers.
std::vector<double> column(const Csv& csv, const std::string& name) {
  const auto it = std::find(csv.header.begin(), csv.header.end(), name);
  EXPECT_NE(it, csv.header.end()) << "no column " << name;
  std::vector<double> out;
  if (it == csv.header.end()) return out;
  const auto k = static_cast<std::size_t>(it - csv.header.begin());
  for (const auto& row : csv.rows) out.push_back(number(row.at(k)));
  return out;
}

const char* const kComponents[] = {"11", "12", "13", "21", "22", "23", "31", "32", "33"};

}  // namespace

// A stress-strain table in one go: strain and stress tensors and their von Mises measures,
// every case in its own file, the values the file's own (bit for bit) and the measures those
// of crystal/measures.hpp, whose last row is the run summary's attribute exactly.
TEST(PostTable, StressStrainAndVonMisesOfEveryCaseInOneFileEach) {
  const fs::path dir = scratch_dir();
  const auto written = post::export_table(
      crystal_result(), table_options(dir, "",
                                      {"macro/strain", "macro/stress", "macro/von_mises_stress",
                                       "macro/von_mises_strain"}));
  ASSERT_EQ(written.size(), 2u);
  EXPECT_EQ(written[0], dir / "L_2__2_=1.0e-3.csv");
  EXPECT_EQ(written[1], dir / "L_2__2_=1.0e-1.csv");
  const Csv csv = read_csv(written[0]);
  std::vector<std::string> header{"step", "time [s]"};
  for (const char* c : kComponents) header.push_back(std::string("strain_") + c + " [1]");
  for (const char* c : kComponents) header.push_back(std::string("stress_") + c + " [MPa]");
  header.push_back("von_mises_stress [MPa]");
  header.push_back("von_mises_strain [1]");
  EXPECT_EQ(csv.header, header);
  const std::string path = "cases/" + kCrystalCase + "/";
  const auto stress = read_dataset(crystal_result(), path + "macro/stress");
  const auto strain = read_dataset(crystal_result(), path + "macro/strain");
  const auto time = read_dataset(crystal_result(), path + "macro/time");
  ASSERT_EQ(csv.rows.size(), 21u);
  const auto vm_stress = column(csv, "von_mises_stress [MPa]");
  const auto vm_strain = column(csv, "von_mises_strain [1]");
  for (std::size_t i = 0; i < 21; ++i) {
    EXPECT_EQ(number(csv.rows[i][0]), static_cast<double>(i));
    EXPECT_EQ(number(csv.rows[i][1]), time[i]);
    for (std::size_t c = 0; c < 9; ++c) {
      EXPECT_EQ(number(csv.rows[i][2 + c]), strain[9 * i + c]);
      EXPECT_EQ(number(csv.rows[i][11 + c]), stress[9 * i + c]);
    }
    const Eigen::Matrix3d s =
        Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(&stress[9 * i]);
    EXPECT_EQ(vm_stress[i], crystal::von_mises_stress(s));
  }
  const h5::File f = h5::File::open_read(crystal_result());
  const h5::Group g = f.root().open_group(path.substr(0, path.size() - 1));
  EXPECT_EQ(vm_stress.back(), g.attribute_double("final_von_mises_stress"));
  EXPECT_EQ(vm_strain.back(), g.attribute_double("final_von_mises_strain"));
  EXPECT_GT(vm_stress.back(), 30.0) << "2 % tension of copper: well past yield";
}

// Per-grain quantities: long format (a row per step and grain) or one grain; macro columns
// beside them repeat the row's value; the equivalent plastic strain starts at 0, never
// decreases, and its grain-weighted mean is the macro one.
TEST(PostTable, PerGrainQuantitiesInLongFormatAndForOneGrain) {
  const fs::path dir = scratch_dir();
  const std::vector<std::string> quantities{"macro/von_mises_strain", "grains/von_mises_stress",
                                            "grains/equivalent_plastic_strain"};
  const auto written =
      post::export_table(crystal_result(), table_options(dir / "all", kCrystalCase, quantities));
  ASSERT_EQ(written.size(), 1u);
  const Csv all = read_csv(written[0]);
  EXPECT_EQ(all.header,
            (std::vector<std::string>{"step", "time [s]", "grain", "von_mises_strain [1]",
                                      "von_mises_stress [MPa]", "equivalent_plastic_strain [1]"}));
  const std::size_t n = 21, grains = 20;
  ASSERT_EQ(all.rows.size(), n * grains);
  const std::string path = "cases/" + kCrystalCase + "/grains/";
  const auto stress = read_dataset(crystal_result(), path + "stress");
  const auto eps = column(all, "equivalent_plastic_strain [1]");
  const auto vm = column(all, "von_mises_stress [MPa]");
  const auto macro = column(all, "von_mises_strain [1]");
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t g = 0; g < grains; ++g) {
      const std::size_t r = i * grains + g;
      EXPECT_EQ(number(all.rows[r][0]), static_cast<double>(i));
      EXPECT_EQ(number(all.rows[r][2]), static_cast<double>(g));
      EXPECT_EQ(macro[r], macro[i * grains]);
      const Eigen::Matrix3d s = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(
          &stress[9 * (i * grains + g)]);
      EXPECT_EQ(vm[r], crystal::von_mises_stress(s));
      if (i == 0) {
        EXPECT_EQ(eps[r], 0.0);
      } else {
        EXPECT_GE(eps[r], eps[r - grains]);
      }
    }
  }
  // Plastic: within 4 % of the total strain at 2 % (the elastic part is stress / E).
  for (std::size_t g = 0; g < grains; ++g) {
    EXPECT_GT(eps[(n - 1) * grains + g], 0.96 * macro.back());
    EXPECT_LT(eps[(n - 1) * grains + g], macro.back());
  }
  auto one = table_options(dir / "one", kCrystalCase,
                           {"grains/equivalent_plastic_strain", "macro/equivalent_plastic_strain"});
  one.grain = 7;
  const auto g7_files = post::export_table(crystal_result(), one);
  ASSERT_EQ(g7_files.size(), 1u);
  const Csv g7 = read_csv(g7_files[0]);
  // The two share a name: each is named by its path; no grain column for one grain.
  EXPECT_EQ(g7.header,
            (std::vector<std::string>{"step", "time [s]", "grains_equivalent_plastic_strain [1]",
                                      "macro_equivalent_plastic_strain [1]"}));
  ASSERT_EQ(g7.rows.size(), n);
  const auto weights = read_dataset(crystal_result(), path + "weight");
  const auto mean = column(g7, "macro_equivalent_plastic_strain [1]");
  for (std::size_t i = 0; i < n; ++i) {
    EXPECT_EQ(number(g7.rows[i][2]), eps[i * grains + 7]);
    double weighted = 0.0, total = 0.0;
    for (std::size_t g = 0; g < grains; ++g) {
      weighted += weights[g] * eps[i * grains + g];
      total += weights[g];
    }
    EXPECT_NEAR(mean[i], weighted / total, 1e-15) << i;
  }
}

// Output at strains with per-grain rows at a coarser spacing: a table mixing macro and
// per-grain quantities has the per-grain rows, each with its output row and time.
TEST(PostTable, MacroAndPerGrainQuantitiesShareThePerGrainRows) {
  const fs::path dir = scratch_dir();
  const fs::path file = dir / "grains_at.h5";
  {
    const auto scene =
        parse_crystal_scene(YamlDocument::from_file(kData / "crystal_grains_at.yaml"));
    h5::File f = h5::File::create(file, true);
    CrystalResultSink sink(scene, f, {});
    for (const auto& c : driver::run_crystal_scene(scene, sink)) EXPECT_TRUE(c.failure.empty());
    close_and_finish(f);
  }
  auto options = table_options(dir / "csv", "", {"macro/strain", "macro/slip_activity"});
  options.grain = 0;  // needless for aggregate quantities, and harmless
  const auto written = post::export_table(file, options);
  ASSERT_EQ(written.size(), 1u);
  const Csv csv = read_csv(written[0]);
  const auto time = read_dataset(file, "cases/base/macro/time");
  const auto strain = read_dataset(file, "cases/base/macro/strain");
  ASSERT_EQ(csv.rows.size(), 4u);
  const std::size_t steps[] = {0, 5, 10, 20};
  for (std::size_t r = 0; r < 4; ++r) {
    EXPECT_EQ(number(csv.rows[r][0]), static_cast<double>(steps[r]));
    EXPECT_EQ(number(csv.rows[r][1]), time[steps[r]]);
    EXPECT_EQ(column(csv, "strain_33 [1]")[r], strain[9 * steps[r] + 8]);
  }
  // 2 + 9 strain + 12 slip systems, each named by its label.
  ASSERT_EQ(csv.header.size(), 23u);
  EXPECT_EQ(csv.header[11].rfind("slip_activity_fcc_111_110 ", 0), 0u) << csv.header[11];
  EXPECT_TRUE(contains(csv.header[11], "[1/s]")) << csv.header[11];
}

TEST(PostTable, BadRequestsAreOneClearErrorAndWriteNothing) {
  const fs::path dir = scratch_dir() / "out";
  const auto expect_error = [&](const fs::path& file, const post::TableOptions& o,
                                const std::string& part) {
    try {
      post::export_table(file, o);
      ADD_FAILURE() << "no error; expected one containing: " << part;
    } catch (const InputError& e) {
      EXPECT_TRUE(contains(e.what(), part)) << e.what();
    }
    EXPECT_FALSE(fs::exists(dir)) << "nothing may be written before every name is checked";
  };
  expect_error(crystal_result(), table_options(dir, "", {"macro/stress", "von_mises"}),
               "--quantity: case 'L[2][2]=1.0e-3': no quantity 'von_mises'; stored series and "
               "derived quantities: macro/time,");
  expect_error(crystal_result(), table_options(dir, "", {"grains/weight"}),
               "'grains/weight' is no time series");
  expect_error(contact_result(), table_options(dir, "", {"ratio", "macro/von_mises_stress"}),
               "'macro/von_mises_stress' is derived from a crystal run's series; this is a "
               "contact result");
  auto grain = table_options(dir, kCrystalCase, {"grains/slip_activity"});
  grain.grain = 20;
  expect_error(crystal_result(), grain, "--grain: grain 20 is out of range");
  expect_error(crystal_result(), table_options(dir, "", {}), "name at least one quantity");
}

// Without grain slips the derived quantities that need them say which output setting writes
// them; the summary lists the derived quantities a case offers.
TEST(PostTable, MissingInputsNameTheOutputSettingAndTheSummaryListsWhatIsOffered) {
  const fs::path dir = scratch_dir();
  const fs::path file = dir / "macro_only.h5";
  {
    auto only_macro = parse_crystal_scene(YamlDocument::from_file(kData / "crystal_small.yaml"));
    for (auto& c : only_macro.cases) c.output.grains.clear();
    h5::File f = h5::File::create(file, true);
    CrystalResultSink sink(only_macro, f, {});
    for (const auto& c : driver::run_crystal_scene(only_macro, sink))
      EXPECT_TRUE(c.failure.empty());
    close_and_finish(f);
  }
  try {
    post::export_table(file, table_options(dir / "csv", "", {"grains/equivalent_plastic_strain"}));
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_TRUE(contains(e.what(),
                         "the equivalent plastic strain needs grains/slip, which the "
                         "file does not hold; ask the scene for it: output: {grains: "
                         "[slip]}"))
        << e.what();
  }
  const std::string s = summary(file, kCrystalCase);
  EXPECT_TRUE(contains(s,
                       "derived (post --quantity): macro/von_mises_stress, "
                       "macro/von_mises_strain\n"))
      << s;
  const std::string full = summary(crystal_result(), kCrystalCase);
  EXPECT_TRUE(contains(full, " grains/equivalent_plastic_strain,\n")) << full;
  EXPECT_TRUE(contains(full, " grains/slip_activity\n")) << full;
}

TEST(PostCli, QuantityTableAndItsErrors) {
  const fs::path dir = scratch_dir();
  const std::string file = std::string("'").append(crystal_result().string()).append("'");
  const Outcome t = run_subslip(dir, "post " + file + " --csv csv --case '" + kCrystalCase +
                                         "' --quantity macro/strain --quantity "
                                         "macro/von_mises_stress");
  EXPECT_EQ(t.code, 0) << t.err;
  EXPECT_EQ(t.out, "csv/L_2__2_=1.0e-3.csv\n");
  EXPECT_EQ(read_csv(dir / "csv" / "L_2__2_=1.0e-3.csv").header.size(), 12u);
  const Outcome both =
      run_subslip(dir, "post " + file + " --csv csv --quantity macro/strain --dataset ratio");
  EXPECT_EQ(both.code, 2) << "--quantity excludes --dataset";
  const Outcome bad = run_subslip(dir, "post " + file + " --csv x --quantity macro/stres");
  EXPECT_EQ(bad.code, 2);
  EXPECT_TRUE(contains(bad.err, "no quantity 'macro/stres'")) << bad.err;
  EXPECT_EQ(std::count(bad.err.begin(), bad.err.end(), '\n'), 1) << "one line\n" << bad.err;
}
