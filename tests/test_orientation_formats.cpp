// Orientation files written as other tools write them (docs/orientations.md): a headerless Bunge
// Euler list, MTEX's text export (quaternion/export.m, EBSD/export.m) and DAMASK's ASCII table
// (Table.save). Each holding the same numbers as a file in subslip's own format gives bitwise the
// same orientations, and a crystal run the same result file; each bad file gets one message
// naming file, line and key.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include "child_process.hpp"
#include "scene_text.hpp"
#include "scratch_dir.hpp"
#include "subslip/io/orientation_file.hpp"

namespace {

namespace fs = std::filesystem;
using subslip::InputError;
using subslip::crystal::Orientation;
using subslip::io::AngleUnit;
using subslip::io::OrientationFileKind;
using subslip::io::OrientationFileLayout;

using Row = std::vector<std::string>;

// The first `count` data lines of a shipped file (6 significant digits, as MTEX's %g writes).
std::vector<Row> shipped_euler_rows(std::size_t count) {
  std::ifstream in(std::string(SUBSLIP_SOURCE_DIR) + "/orientations/random_100.txt");
  std::vector<Row> rows;
  std::string line;
  while (rows.size() < count && std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream words(line);
    Row row(3);
    words >> row[0] >> row[1] >> row[2];
    rows.push_back(row);
  }
  return rows;
}

double number(const std::string& text) {
  double value = 0.0;
  std::from_chars(text.data(), text.data() + text.size(), value);
  return value;
}

// The shortest text that reads back as `value`: what Python's repr, hence DAMASK's Table.save
// (pandas to_csv), writes for a float.
std::string shortest(double value) {
  char buffer[64];
  const auto end = std::to_chars(buffer, buffer + sizeof buffer, value).ptr;
  return std::string(buffer, end);
}

std::string lines(const std::vector<Row>& rows) {
  std::string text;
  for (const Row& row : rows) {
    for (std::size_t i = 0; i < row.size(); ++i) text += (i ? " " : "") + row[i];
    text += "\n";
  }
  return text;
}

std::string subslip_file(const std::string& convention, const std::vector<Row>& rows) {
  return "# subslip-orientations convention=" + convention + " passive P=-1\n" + lines(rows);
}

// MTEX's cprintf(d, '-Lc', labels): one line of labels, then the numbers (%g), every cell
// right-aligned to the widest cell and separated by a space; no comment lines.
std::string mtex_table(const Row& labels, const std::vector<Row>& rows) {
  std::size_t width = 0;
  for (const auto& label : labels) width = std::max(width, label.size());
  for (const Row& row : rows)
    for (const auto& cell : row) width = std::max(width, cell.size());
  auto line = [&](const Row& cells) {
    std::string text;
    for (std::size_t i = 0; i < cells.size(); ++i) {
      if (i > 0) text.push_back(' ');
      text.append(width - std::min(width, cells[i].size()), ' ').append(cells[i]);
    }
    text.push_back('\n');
    return text;
  };
  std::string text = line(labels);
  for (const Row& row : rows) text += line(row);
  return text;
}

// DAMASK's Table.save: '# ' comment lines, the labels (a vector column v as 1_v 2_v ...), then
// the values separated by single spaces.
std::string damask_table(const std::vector<std::string>& comments, const Row& labels,
                         const std::vector<Row>& rows) {
  std::string text;
  for (const auto& comment : comments) text += "# " + comment + "\n";
  return text + lines({labels}) + lines(rows);
}

std::vector<Orientation> read(const std::string& text, const OrientationFileLayout& layout = {},
                              double* largest_euler_deg = nullptr) {
  std::istringstream in(text);
  return subslip::io::read_orientations(in, "given.txt", largest_euler_deg, layout);
}

OrientationFileLayout layout(OrientationFileKind kind, std::optional<AngleUnit> angles = {},
                             std::string column = "O") {
  OrientationFileLayout l;
  l.kind = kind;
  l.angles = angles;
  l.column = std::move(column);
  return l;
}

bool same_bits(double a, double b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

void expect_bitwise(const std::vector<Orientation>& expected,
                    const std::vector<Orientation>& actual) {
  ASSERT_EQ(expected.size(), actual.size());
  for (std::size_t i = 0; i < expected.size(); ++i) {
    SCOPED_TRACE("orientation " + std::to_string(i));
    const auto& a = expected[i].q;
    const auto& b = actual[i].q;
    EXPECT_TRUE(same_bits(a.w, b.w) && same_bits(a.x, b.x) && same_bits(a.y, b.y) &&
                same_bits(a.z, b.z))
        << a.w << " " << a.x << " " << a.y << " " << a.z << " vs " << b.w << " " << b.x << " "
        << b.y << " " << b.z;
    EXPECT_TRUE(same_bits(expected[i].weight, actual[i].weight));
  }
}

// The rows in radians as numpy's radians() computes them (x * (pi / 180)), written in full.
std::vector<Row> in_radians(const std::vector<Row>& degrees) {
  std::vector<Row> rows;
  for (const Row& row : degrees) {
    Row r;
    for (const auto& cell : row) r.push_back(shortest(number(cell) * (std::numbers::pi / 180.0)));
    rows.push_back(r);
  }
  return rows;
}

// The rows as the quaternions subslip reads from them, written in full.
std::vector<Row> as_quaternions(const std::vector<Row>& degrees) {
  std::vector<Row> rows;
  for (const Orientation& o : read(subslip_file("bunge-euler-deg", degrees))) {
    rows.push_back({shortest(o.q.w), shortest(o.q.x), shortest(o.q.y), shortest(o.q.z)});
  }
  return rows;
}

// Appends columns (a phase, coordinates) the reader must pass over.
std::vector<Row> with_other_columns(const std::vector<Row>& rows, const Row& before,
                                    const Row& after) {
  std::vector<Row> out;
  for (const Row& row : rows) {
    Row r = before;
    r.insert(r.end(), row.begin(), row.end());
    r.insert(r.end(), after.begin(), after.end());
    out.push_back(r);
  }
  return out;
}

}  // namespace

TEST(OrientationFormats, HeaderlessEulerListInDegreesIsTheSubslipFile) {
  const auto rows = shipped_euler_rows(20);
  const auto expected = read(subslip_file("bunge-euler-deg", rows));
  expect_bitwise(expected,
                 read(lines(rows), layout(OrientationFileKind::euler, AngleUnit::degrees)));
  // Comment lines and a weight column are read as in subslip's format.
  std::vector<Row> weighted = rows;
  for (Row& row : weighted) row.push_back("0.5");
  const auto with_weights = read("# from an EBSD export\n" + lines(weighted),
                                 layout(OrientationFileKind::euler, AngleUnit::degrees));
  expect_bitwise(read(subslip_file("bunge-euler-deg", weighted)), with_weights);
}

TEST(OrientationFormats, HeaderlessEulerListInRadiansIsTheSubslipFileInDegrees) {
  const auto rows = shipped_euler_rows(20);
  double largest = 0.0;
  const auto radians = read(lines(in_radians(rows)),
                            layout(OrientationFileKind::euler, AngleUnit::radians), &largest);
  expect_bitwise(read(subslip_file("bunge-euler-deg", rows)), radians);
  EXPECT_EQ(largest, -1.0) << "angles declared radians need no check for radians";
}

TEST(OrientationFormats, RadiansReadAsDegreesAreStillFlagged) {
  double largest = 0.0;
  const auto read_back = read(lines(in_radians(shipped_euler_rows(5))),
                              layout(OrientationFileKind::euler, AngleUnit::degrees), &largest);
  EXPECT_TRUE(subslip::io::euler_angles_look_like_radians(largest, read_back.size()));
}

TEST(OrientationFormats, MtexBungeExportInDegreesIsTheSubslipFile) {
  const auto rows = shipped_euler_rows(20);
  const auto expected = read(subslip_file("bunge-euler-deg", rows));
  // export(ori, fname): MTEX's default, Bunge angles in degrees.
  expect_bitwise(
      expected, read(mtex_table({"phi1", "Phi", "phi2"}, rows), layout(OrientationFileKind::mtex)));
  // EBSD export: phase and the EBSD properties follow the angles.
  expect_bitwise(expected, read(mtex_table({"phi1", "Phi", "phi2", "phase", "x", "y"},
                                           with_other_columns(rows, {}, {"1", "0.5", "-2.25"})),
                                layout(OrientationFileKind::mtex, AngleUnit::degrees)));
}

// MTEX's quaternion for Bunge angles (geometry/geometry_tools/euler2quat.m: Bunge to Matthies by
// alpha = phi1 - pi/2, gamma = phi2 - 3 pi/2, then q = z(alpha) y(beta) z(gamma), Hamilton
// products of (cos(t/2), sin(t/2) axis)) has the components of subslip's quaternion: its
// a b c d columns are read as w x y z.
TEST(OrientationFormats, MtexQuaternionOfBungeAnglesIsSubslips) {
  using Q = std::array<double, 4>;
  const auto product = [](const Q& p, const Q& q) {
    return Q{p[0] * q[0] - p[1] * q[1] - p[2] * q[2] - p[3] * q[3],
             p[0] * q[1] + p[1] * q[0] + p[2] * q[3] - p[3] * q[2],
             p[0] * q[2] - p[1] * q[3] + p[2] * q[0] + p[3] * q[1],
             p[0] * q[3] + p[1] * q[2] - p[2] * q[1] + p[3] * q[0]};
  };
  const double pi = std::numbers::pi;
  for (const Row& row : shipped_euler_rows(50)) {
    const double phi1 = number(row[0]) * pi / 180, Phi = number(row[1]) * pi / 180,
                 phi2 = number(row[2]) * pi / 180;
    const double alpha = phi1 - pi / 2, gamma = phi2 - 3 * pi / 2;
    const Q mtex = product(product(Q{std::cos(alpha / 2), 0, 0, std::sin(alpha / 2)},
                                   Q{std::cos(Phi / 2), 0, std::sin(Phi / 2), 0}),
                           Q{std::cos(gamma / 2), 0, 0, std::sin(gamma / 2)});
    const auto q = subslip::crystal::euler_to_quaternion(Eigen::Vector3d(phi1, Phi, phi2));
    const double sign = mtex[0] < 0 ? -1.0 : 1.0;  // subslip keeps w >= 0
    EXPECT_NEAR(sign * mtex[0], q.w, 1e-14);
    EXPECT_NEAR(sign * mtex[1], q.x, 1e-14);
    EXPECT_NEAR(sign * mtex[2], q.y, 1e-14);
    EXPECT_NEAR(sign * mtex[3], q.z, 1e-14);
  }
}

TEST(OrientationFormats, MtexQuaternionExportIsTheSubslipQuaternionFile) {
  const auto quaternions = as_quaternions(shipped_euler_rows(20));
  expect_bitwise(
      read(subslip_file("quaternion", quaternions)),
      read(mtex_table({"a", "b", "c", "d"}, quaternions), layout(OrientationFileKind::mtex)));
}

TEST(OrientationFormats, MtexRadiansKeepTheirSixDigits) {
  // export(ori, fname, 'radians') writes %g: 2 pi becomes 6.28319, pi 3.14159, both accepted.
  const auto read_back = read(mtex_table({"phi1", "Phi", "phi2"}, {{"6.28319", "3.14159", "0"}}),
                              layout(OrientationFileKind::mtex, AngleUnit::radians));
  ASSERT_EQ(read_back.size(), 1u);
  const auto expected = read(subslip_file("bunge-euler-deg", {{"0", "180", "0"}}));
  const auto& a = read_back[0].q;
  const auto& b = expected[0].q;
  // q and -q are one rotation: |q_a . q_b| = cos(half the angle between them).
  EXPECT_GT(std::abs(a.w * b.w + a.x * b.x + a.y * b.y + a.z * b.z), std::cos(1e-5));
}

TEST(OrientationFormats, DamaskQuaternionTableIsTheSubslipQuaternionFile) {
  const auto quaternions = as_quaternions(shipped_euler_rows(20));
  const std::string table =
      damask_table({"written by damask.Table.save", "O: orientation (quaternion)"},
                   {"1_pos", "2_pos", "3_pos", "1_O", "2_O", "3_O", "4_O", "phase"},
                   with_other_columns(quaternions, {"0.0", "1.0", "2.0"}, {"Aluminum"}));
  expect_bitwise(read(subslip_file("quaternion", quaternions)),
                 read(table, layout(OrientationFileKind::damask)));
}

TEST(OrientationFormats, DamaskEulerColumnsInRadiansAreTheSubslipFileInDegrees) {
  const auto rows = shipped_euler_rows(20);
  const std::string table = damask_table({}, {"1_eu", "2_eu", "3_eu"}, in_radians(rows));
  expect_bitwise(read(subslip_file("bunge-euler-deg", rows)),
                 read(table, layout(OrientationFileKind::damask, {}, "eu")));
  // Degrees when said so (Rotation.as_Euler_angles(degrees=True)).
  expect_bitwise(read(subslip_file("bunge-euler-deg", rows)),
                 read(damask_table({}, {"1_eu", "2_eu", "3_eu"}, rows),
                      layout(OrientationFileKind::damask, AngleUnit::degrees, "eu")));
}

namespace {

struct BadText {
  const char* what;
  OrientationFileLayout layout;
  std::string text;
  int line;
  std::string key;
  std::string fragment;
};

std::vector<BadText> bad_texts() {
  const auto euler_deg = layout(OrientationFileKind::euler, AngleUnit::degrees);
  const auto euler_rad = layout(OrientationFileKind::euler, AngleUnit::radians);
  const auto mtex = layout(OrientationFileKind::mtex);
  const auto damask = layout(OrientationFileKind::damask);
  return {
      {"euler: a fourth and a fifth column", euler_deg, "10 20 30\n10 20 30 1 2\n", 2, "columns",
       "expected 3 numbers"},
      {"euler: Phi beyond 180 deg", euler_deg, "# c\n10 200 30\n", 2, "Phi", "outside [0, 180]"},
      {"euler: degrees read as radians", euler_rad, "0.1 0.2 0.3\n1 90 0\n", 2, "Phi",
       "were the angles written in degrees?"},
      {"euler: no unit", layout(OrientationFileKind::euler), "10 20 30\n", 0, "angles",
       "angles deg or rad"},
      {"euler: subslip's own header", euler_deg,
       "# subslip-orientations convention=quaternion\n1 0 0 0\n", 1, "header",
       "leave out the format"},
      {"euler: only comments", euler_deg, "# nothing\n\n", 0, "orientations",
       "every line is blank or a comment"},
      {"euler: not a number", euler_deg, "10 20 30\n10 x 30\n", 2, "Phi", "'x' is not a number"},
      {"mtex: Matthies angles", mtex, " alpha beta gamma\n 1 2 3\n", 1, "header",
       "export with the option 'Bunge'"},
      {"mtex: unknown labels", mtex, "u v w\n1 2 3\n", 1, "header", "phi1 Phi phi2"},
      {"mtex: a cell missing", mtex, "phi1 Phi phi2 phase\n10 20 30 1\n10 20 30\n", 3, "columns",
       "one per column label on line 1"},
      {"mtex: NaN of an unindexed point", mtex, "phi1 Phi phi2\n10 20 30\nNaN NaN NaN\n", 3, "phi1",
       "not finite"},
      {"mtex: quaternion far from unit", mtex, "a b c d\n1 0 0 0\n0.5 0.5 0.5 0.4\n", 3,
       "quaternion", "differs from 1"},
      {"mtex: only labels", mtex, "phi1 Phi phi2\n", 0, "orientations", "no orientations"},
      {"damask: no column O", damask, "# c\n1_eu 2_eu 3_eu\n1 2 3\n", 2, "header",
       "orientations.column"},
      {"damask: column O of 2 components", damask, "1_O 2_O\n1 0\n", 1, "header", "2 components"},
      {"damask: a component not a number", damask,
       "# c\n# d\n1_O 2_O 3_O 4_O\n1 0 0 0\n1 zero 0 0\n", 5, "2_O", "'zero' is not a number"},
      {"damask: Euler degrees read as radians", layout(OrientationFileKind::damask, {}, "eu"),
       "1_eu 2_eu 3_eu\n270 45 10\n", 2, "1_eu", "were the angles written in degrees?"},
      {"damask: empty", damask, "# only a comment\n", 0, "orientations", "empty file"},
  };
}

}  // namespace

TEST(OrientationFormats, EachBadFileGetsOneMessageNamingFileLineAndKey) {
  for (const BadText& bad : bad_texts()) {
    SCOPED_TRACE(bad.what);
    try {
      read(bad.text, bad.layout);
      ADD_FAILURE() << "accepted";
    } catch (const InputError& e) {
      const std::string message = e.what();
      EXPECT_EQ(e.file, "given.txt");
      EXPECT_EQ(e.line, bad.line) << message;
      EXPECT_EQ(e.key, bad.key) << message;
      const std::string location = bad.line > 0 ? "given.txt:" + std::to_string(bad.line) + ": "
                                                : std::string("given.txt: ");
      EXPECT_EQ(message.rfind(location + bad.key + ": ", 0), 0u) << message;
      EXPECT_NE(message.find(bad.fragment), std::string::npos) << message;
    }
  }
}

namespace {

std::string scene_with(const std::string& orientations) {
  return subslip::testing::copper_scene_start("title: \"orientation formats\"\n") +
         "orientations: " + orientations + R"(
loading:
  - L: [[x, 0, 0], [0, x, 0], [0, 0, 1.0e-3]]
    stress: [[0, x, x], [x, 0, x], [x, x, x]]
    duration: 2
    increments: 4
)";
}

void write(const fs::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

// Runs the scene in `dir` and returns its result file.
fs::path run(const fs::path& dir, const std::string& name, const std::string& orientations) {
  write(dir / (name + ".yaml"), scene_with(orientations));
  const fs::path out = dir / (name + ".h5");
  EXPECT_EQ(subslip::testing::run_subslip(
                dir, {"run", (dir / (name + ".yaml")).string(), "-o", out.string(), "-q"},
                dir / (name + ".log")),
            0)
      << subslip::testing::read_text(dir / (name + ".log"));
  return out;
}

}  // namespace

// The same orientations written by MTEX or DAMASK give the same
// result file as subslip's own format, bit for bit.
TEST(OrientationFormats, CrystalRunsFromOtherToolsFilesAreBitwiseTheSame) {
  const fs::path dir = subslip::testing::scratch_dir("orientation_formats");
  const auto rows = shipped_euler_rows(6);
  write(dir / "own.txt", subslip_file("bunge-euler-deg", rows));
  write(dir / "list.txt", lines(rows));
  write(dir / "mtex.txt", mtex_table({"phi1", "Phi", "phi2"}, rows));
  write(dir / "damask_eu.txt",
        damask_table({"eu: Bunge Euler angles"}, {"1_eu", "2_eu", "3_eu"}, in_radians(rows)));
  const fs::path reference = run(dir, "own", "{file: own.txt}");
  subslip::testing::expect_same_datasets(
      reference, run(dir, "list", "{file: list.txt, format: euler, angles: deg}"));
  subslip::testing::expect_same_datasets(reference,
                                         run(dir, "mtex", "{file: mtex.txt, format: mtex}"));
  subslip::testing::expect_same_datasets(
      reference, run(dir, "damask_eu", "{file: damask_eu.txt, format: damask, column: eu}"));

  const auto quaternions = as_quaternions(rows);
  write(dir / "own_q.txt", subslip_file("quaternion", quaternions));
  write(dir / "damask_q.txt", damask_table({}, {"1_O", "2_O", "3_O", "4_O"}, quaternions));
  write(dir / "mtex_q.txt", mtex_table({"a", "b", "c", "d"}, quaternions));
  const fs::path reference_q = run(dir, "own_q", "{file: own_q.txt}");
  subslip::testing::expect_same_datasets(
      reference_q, run(dir, "damask_q", "{file: damask_q.txt, format: damask}"));
  subslip::testing::expect_same_datasets(reference_q,
                                         run(dir, "mtex_q", "{file: mtex_q.txt, format: mtex}"));
}

TEST(OrientationFormats, SceneKeysAreChecked) {
  const fs::path dir = subslip::testing::scratch_dir("orientation_formats_keys");
  write(dir / "list.txt", "10 20 30\n");
  struct Case {
    std::string orientations;
    std::string fragment;
  };
  const std::vector<Case> cases{
      {"{file: list.txt, format: euler}", "orientations: format euler needs the unit"},
      {"{file: list.txt, format: ebsd}", "orientations.format: "},
      {"{file: list.txt, angles: deg}", "orientations.angles: applies to format euler"},
      {"{file: list.txt, format: euler, angles: grad}", "orientations.angles: "},
      {"{file: list.txt, format: mtex, column: O}",
       "orientations.column: applies to format damask"},
      {"{random: {count: 3}, format: euler}", "orientations.format: applies to orientations.file"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.orientations);
    write(dir / "scene.yaml", scene_with(c.orientations));
    EXPECT_NE(subslip::testing::run_subslip(
                  dir, {"run", (dir / "scene.yaml").string(), "-o", (dir / "x.h5").string(), "-q"},
                  dir / "scene.log"),
              0);
    const std::string log = subslip::testing::read_text(dir / "scene.log");
    EXPECT_NE(log.find((dir / "scene.yaml").string() + ":"), std::string::npos) << log;
    EXPECT_NE(log.find(c.fragment), std::string::npos) << log;
  }
}
