// Orientation files: every malformed file names itself and the offending line; good files read
// back what was written; the files shipped in orientations/ are what the generator produces.
//
// Regenerate the shipped files (after a deliberate change of the generator):
//   SUBSLIP_REGENERATE_ORIENTATIONS=1 build/tests/subslip_tests
//       --gtest_filter=OrientationFiles.ShippedFilesMatchTheGenerator   (one command line)
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <numbers>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "scratch_dir.hpp"
#include "subslip/crystal/texture.hpp"
#include "subslip/io/orientation_file.hpp"

using namespace subslip::crystal;
using subslip::InputError;
using subslip::io::format_orientations;
using subslip::io::OrientationConvention;
using subslip::io::OrientationFileFormat;
using subslip::io::OrientationFileKind;
using subslip::io::OrientationFileLayout;
using subslip::io::read_orientation_file;
using subslip::io::read_orientation_file_lines;
using subslip::io::read_orientation_file_start;
using subslip::io::read_orientations;
using subslip::io::write_orientation_file;

namespace {

std::string data_path(const std::string& name) {
  return std::string(SUBSLIP_SOURCE_DIR) + "/tests/data/orientations/" + name;
}

struct BadFile {
  std::string name;
  int line;         // 0: the error has no line
  std::string key;  // what the message must blame
};

const std::vector<BadFile> kBadFiles{
    {"missing_header.txt", 1, "header"},
    {"comment_before_header.txt", 1, "header"},
    {"unknown_convention.txt", 1, "convention"},
    {"missing_convention.txt", 2, "convention"},
    {"active_convention.txt", 1, "header"},
    {"wrong_column_count.txt", 5, "columns"},
    {"inconsistent_weights.txt", 3, "columns"},
    {"not_a_number.txt", 3, "Phi"},
    {"trailing_garbage.txt", 2, "phi2"},
    {"nan_value.txt", 2, "phi1"},
    {"inf_value.txt", 3, "w"},
    {"quaternion_not_unit.txt", 4, "quaternion"},
    {"zero_quaternion.txt", 2, "quaternion"},
    {"euler_Phi_out_of_range.txt", 2, "Phi"},
    {"euler_phi1_out_of_range.txt", 2, "phi1"},
    {"negative_weight.txt", 3, "weight"},
    {"zero_weight.txt", 2, "weight"},
    {"empty.txt", 0, "orientations"},
    {"header_only.txt", 0, "orientations"},
    {"does_not_exist.txt", 0, "file"},
};

}  // namespace

namespace {

// What a read gives: every orientation's bits, or the error's what() and line.
struct ReadOutcome {
  std::vector<double> values;  // q, g and weight of each orientation, in order
  std::string error;
  int line = 0;
  double largest_euler_deg = -1.0;
};
void append_values(const Orientation& o, std::vector<double>& out) {
  out.insert(out.end(), {o.q.w, o.q.x, o.q.y, o.q.z, o.weight});
  out.insert(out.end(), o.g.data(), o.g.data() + 9);
}

ReadOutcome read_whole(const std::string& path, const OrientationFileLayout& layout) {
  ReadOutcome out;
  try {
    read_orientation_file(
        path, [&](const Orientation& o) { append_values(o, out.values); }, &out.largest_euler_deg,
        layout);
  } catch (const InputError& e) {
    out = {{}, e.what(), e.line, -1.0};
  }
  return out;
}

// The file read as ranks read it: its start, then the ranges [start, cuts[0]), [cuts[0],
// cuts[1]), ..., [cuts.back(), size) in order, each on its own; the first problem with its line
// counted from the file's start.
ReadOutcome read_by_ranges(const std::string& path, const OrientationFileLayout& layout,
                           const std::string& start, const std::vector<std::uint64_t>& cuts) {
  ReadOutcome out;
  const auto each = [&](const Orientation& o) { append_values(o, out.values); };
  read_orientation_file_start(path, each, layout);
  std::vector<std::uint64_t> edges{start.size()};
  edges.insert(edges.end(), cuts.begin(), cuts.end());
  edges.push_back(std::filesystem::file_size(path));
  int lines_before = static_cast<int>(std::count(start.begin(), start.end(), '\n'));
  for (std::size_t r = 0; r + 1 < edges.size(); ++r) {
    try {
      const auto read =
          read_orientation_file_lines(path, start, edges[r], edges[r + 1], each, layout);
      EXPECT_TRUE(read.complete);
      lines_before += static_cast<int>(read.lines);
      out.largest_euler_deg = std::max(out.largest_euler_deg, read.largest_euler_deg);
    } catch (const InputError& e) {
      const int line = e.line + lines_before;
      return {{}, InputError(e.file, line, e.key, e.message).what(), line, -1.0};
    }
  }
  return out;
}

// Every split of the file's lines after its start into two ranges (at every byte) and into
// three (at every pair of bytes 7 apart) reads what the whole file reads: the same bits, or the
// same first error at the same line; a problem of the whole file is the start's.
void expect_ranges_read_the_whole(const std::string& path, const OrientationFileLayout& layout) {
  SCOPED_TRACE(path);
  const ReadOutcome whole = read_whole(path, layout);
  std::optional<std::string> start;
  try {
    start = read_orientation_file_start(
        path, [](const Orientation&) {}, layout);
  } catch (const InputError& e) {
    EXPECT_EQ(e.what(), whole.error);
    return;
  }
  ASSERT_TRUE(start.has_value());
  const std::uint64_t size = std::filesystem::file_size(path);
  for (std::uint64_t cut = start->size(); cut <= size; ++cut) {
    for (const auto& cuts : {std::vector<std::uint64_t>{cut},
                             std::vector<std::uint64_t>{cut, std::min(cut + 7, size)}}) {
      SCOPED_TRACE("cut at byte " + std::to_string(cut) + " of " + std::to_string(size));
      const ReadOutcome ranges = read_by_ranges(path, layout, *start, cuts);
      EXPECT_EQ(ranges.error, whole.error);
      EXPECT_EQ(ranges.line, whole.line);
      EXPECT_EQ(ranges.largest_euler_deg, whole.largest_euler_deg);
      ASSERT_EQ(ranges.values.size(), whole.values.size());
      if (whole.values.empty()) continue;  // a bad file: memcmp takes no null pointers
      EXPECT_EQ(std::memcmp(ranges.values.data(), whole.values.data(),
                            whole.values.size() * sizeof(double)),
                0);
    }
  }
}

}  // namespace

// MPI ranks read a file by byte ranges (driver/orientation_sharing.hpp): whatever the ranges,
// they read the whole file's orientations bit for bit, and a bad file gives the whole read's
// first error, file, line, key and message.
TEST(OrientationFile, ByteRangesReadWhatTheWholeFileReads) {
  for (const BadFile& bad : kBadFiles) {
    if (bad.name != "does_not_exist.txt") expect_ranges_read_the_whole(data_path(bad.name), {});
  }
  for (const char* good : {"good_euler_weights.txt", "good_quaternion.txt"})
    expect_ranges_read_the_whole(data_path(good), {});
  const std::filesystem::path dir = subslip::testing::scratch_dir("orientation_ranges");
  // Comments, blank lines, CR LF, a long line, and no newline at the end.
  std::ofstream(dir / "mixed.txt", std::ios::binary)
      << "# subslip-orientations convention=bunge-euler-deg\r\n# a comment\r\n\r\n"
         "10 20 30 2 # first\r\n\n  40   50  60 1\r\n# between\n"
         "70.00000000000000000000000000000000000000000000001 80 90 0.5\n\n"
         "1e1,2e1 , 3e1 4\n5 6 7 8";
  expect_ranges_read_the_whole((dir / "mixed.txt").string(), {});
  // A bad line after good ones, then another bad line: the first is the error.
  std::ofstream(dir / "two_bad.txt", std::ios::binary)
      << "# subslip-orientations convention=quaternion\n1 0 0 0\n0 1 0 0\n0 0 1 0\n"
         "0 0 0 1\n1 1 0 0\n0.5 0.5 0.5 0.5\n2 0 0 0\n";
  expect_ranges_read_the_whole((dir / "two_bad.txt").string(), {});
  // Tables of other tools: the column labels are in the start.
  std::ofstream(dir / "damask.txt", std::ios::binary)
      << "# written by damask.Table.save\n1_O 2_O 3_O 4_O phase\n1.0 0.0 0.0 0.0 Cu\n"
         "0.5 0.5 0.5 0.5 Cu\n0.7071067811865476 0 0.7071067811865476 0 Cu\n1 0 0 Cu\n";
  expect_ranges_read_the_whole((dir / "damask.txt").string(),
                               {OrientationFileKind::damask, std::nullopt, "O"});
  std::ofstream(dir / "euler.txt", std::ios::binary)
      << "# header-less\n10 20 30\n40 50 60\n70 80 90\n# subslip-orientations comment\n"
         "1 2 3\n4 5 6 7\n";
  expect_ranges_read_the_whole((dir / "euler.txt").string(),
                               {OrientationFileKind::euler, subslip::io::AngleUnit::degrees, "O"});
}

// A file whose first byte may begin a byte-order mark is converted whole before it is read:
// its start says so (nullopt) and nothing is read.
TEST(OrientationFile, ByteOrderMarkedFileIsNotReadByByteRanges) {
  const std::filesystem::path dir = subslip::testing::scratch_dir("orientation_ranges");
  std::ofstream(dir / "bom.txt", std::ios::binary)
      << "\xEF\xBB\xBF# subslip-orientations convention=bunge-euler-deg\n10 20 30\n";
  int visited = 0;
  EXPECT_FALSE(read_orientation_file_start((dir / "bom.txt").string(), [&](const Orientation&) {
                 ++visited;
               }).has_value());
  EXPECT_EQ(visited, 0);
  EXPECT_EQ(read_orientation_file((dir / "bom.txt").string()).size(), 1u);
}

TEST(OrientationFile, EachBadFileNamesItselfAndTheLine) {
  for (const BadFile& bad : kBadFiles) {
    const std::string path = data_path(bad.name);
    try {
      read_orientation_file(path);
      ADD_FAILURE() << bad.name << ": expected an InputError";
    } catch (const InputError& e) {
      const std::string message = e.what();
      EXPECT_EQ(e.file, path);
      EXPECT_EQ(e.line, bad.line) << message;
      EXPECT_EQ(e.key, bad.key) << message;
      const std::string location =
          bad.line > 0 ? path + ":" + std::to_string(bad.line) + ": " : path + ": ";
      EXPECT_EQ(message.rfind(location, 0), 0u)
          << "message should start with '" << location << "': " << message;
      EXPECT_NE(message.find(bad.key + ": "), std::string::npos) << message;
    }
  }
}

TEST(OrientationFile, MessagesExplainTheProblem) {
  auto message_of = [](const std::string& name) -> std::string {
    try {
      read_orientation_file(data_path(name));
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_NE(message_of("quaternion_not_unit.txt").find("1e-3"), std::string::npos);
  EXPECT_NE(message_of("unknown_convention.txt").find("bunge-euler-deg, quaternion"),
            std::string::npos);
  EXPECT_NE(message_of("missing_header.txt").find("# subslip-orientations convention="),
            std::string::npos);
  EXPECT_NE(message_of("inconsistent_weights.txt").find("line 2"), std::string::npos);
  EXPECT_NE(message_of("euler_Phi_out_of_range.txt").find("[0, 180]"), std::string::npos);
  EXPECT_NE(message_of("not_a_number.txt").find("'abc'"), std::string::npos);
}

TEST(OrientationFile, ReadsEulerDegreesWithWeightsCommentsAndCommas) {
  const auto orientations = read_orientation_file(data_path("good_euler_weights.txt"));
  ASSERT_EQ(orientations.size(), 4u);
  EXPECT_EQ(orientations[0].weight, 2.0);
  EXPECT_LT((orientations[0].g - Eigen::Matrix3d::Identity()).norm(), 1e-15);
  // Euler (90, 0, 0): crystal [100] along sample +y.
  EXPECT_LT(
      (orientations[1].g.transpose() * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm(),
      1e-15);
  EXPECT_EQ(orientations[2].weight, 0.5);
  const Eigen::Vector3d expected(10.0, 20.5, -30.0);
  EXPECT_LT((orientations[3].g - euler_to_matrix(degrees_to_radians(expected))).norm(), 1e-14);
  EXPECT_EQ(orientations[3].weight, 1.0);
}

TEST(OrientationFile, ReadsQuaternionsNormalisingSmallDeviationsAndSign) {
  const auto orientations = read_orientation_file(data_path("good_quaternion.txt"));
  ASSERT_EQ(orientations.size(), 3u);
  // (-0.7071, 0, 0, -0.7071) is the same rotation as (0.7071, 0, 0, 0.7071): Euler (90, 0, 0).
  EXPECT_GT(orientations[1].q.w, 0.0);
  EXPECT_LT(
      (orientations[1].g - euler_to_matrix(Eigen::Vector3d(std::numbers::pi / 2, 0, 0))).norm(),
      1e-8);
  EXPECT_NEAR(orientations[2].q.norm(), 1.0, 1e-15);
  EXPECT_EQ(orientations[2].q.w, 1.0);
}

TEST(OrientationFile, ToleratesWindowsLineEndings) {
  std::istringstream in(
      "# subslip-orientations convention=quaternion passive P=-1\r\n1 0 0 0\r\n0 1 0 0 3\r\n");
  EXPECT_THROW(read_orientations(in, "crlf.txt"), InputError);  // 4 then 5 columns
  std::istringstream good("# subslip-orientations convention=quaternion\r\n1 0 0 0\r\n0 1 0 0\r\n");
  EXPECT_EQ(read_orientations(good, "crlf.txt").size(), 2u);
}

TEST(OrientationFile, WriteThenReadRoundTrips) {
  auto orientations = random_orientations(200, 5);
  orientations[3].weight = 2.5;
  for (const auto convention :
       {OrientationConvention::bunge_euler_deg, OrientationConvention::quaternion}) {
    OrientationFileFormat format;
    format.convention = convention;
    format.significant_digits = 15;
    format.comments = {"round trip"};
    std::istringstream in(format_orientations(orientations, format));
    const auto back = read_orientations(in, "memory");
    ASSERT_EQ(back.size(), orientations.size());
    for (std::size_t i = 0; i < back.size(); ++i) {
      EXPECT_LT(misorientation_angle(back[i].q, orientations[i].q), 1e-11);
      EXPECT_EQ(back[i].weight, orientations[i].weight);
    }
  }
  // Gimbal-lock orientations survive the Euler text form too (Phi = 0 and 180 exactly).
  const std::vector<Orientation> locked{
      Orientation::from_euler(Eigen::Vector3d(0.5, 0.0, 0.7)),
      Orientation::from_euler(Eigen::Vector3d(0.5, std::numbers::pi, 0.7))};
  OrientationFileFormat precise;
  precise.significant_digits = 15;
  std::istringstream in(format_orientations(locked, precise));
  const auto back = read_orientations(in, "memory");
  for (std::size_t i = 0; i < locked.size(); ++i) {
    EXPECT_LT(misorientation_angle(back[i].q, locked[i].q), 1e-12);
  }
}

TEST(OrientationFile, RequestWriterRecordsHowTheFileWasMade) {
  OrientationRequest request;
  request.count = 5;
  request.seed = 7;
  const std::string text = write_orientation_file("", request);
  EXPECT_EQ(text.rfind("# subslip-orientations convention=bunge-euler-deg passive P=-1\n", 0), 0u);
  EXPECT_NE(text.find("# generated by subslip: random count=5 seed=7\n"), std::string::npos);
  std::istringstream in(text);
  EXPECT_EQ(read_orientations(in, "memory").size(), 5u);

  const auto path = std::filesystem::temp_directory_path() / "subslip_test_goss.txt";
  request.component = TextureComponent::goss;
  request.spread_deg = 5.0;
  write_orientation_file(path.string(), request);
  EXPECT_EQ(read_orientation_file(path.string()).size(), 5u);
  std::filesystem::remove(path);
  EXPECT_THROW(write_orientation_file("/nonexistent-directory/x.txt", request), std::runtime_error);
}

namespace {

struct ShippedFile {
  std::string name;
  std::vector<Orientation> orientations;
  double tolerance;  // misorientation (rad) allowed by the digits written
  std::function<void(const std::string& path)> write;
};

ShippedFile random_file(std::size_t count) {
  OrientationRequest request;
  request.count = count;
  request.seed = count;
  // 6 significant digits: at most 5e-4 deg per angle, so below 3e-5 rad per rotation.
  return {"random_" + std::to_string(count) + ".txt", generate_orientations(request), 3e-5,
          [request](const std::string& path) {
            OrientationFileFormat format;
            format.comments = {"uniformly random (Shoemake), regenerate: see docs/orientations.md"};
            write_orientation_file(path, request, format);
          }};
}

ShippedFile single_crystal_file(const std::string& name, const Eigen::Vector3d& along_x,
                                const Eigen::Vector3d& along_y, const std::string& x_indices,
                                const std::string& y_indices) {
  const std::vector<Orientation> orientation{single_crystal_orientation(along_x, along_y)};
  return {name, orientation, 1e-8, [=](const std::string& path) {
            OrientationFileFormat format;
            format.significant_digits = 10;
            format.comments = {"single crystal: crystal " + x_indices +
                                   " is along sample x (the tension axis), crystal " + y_indices +
                                   " along sample y",
                               "regenerate: see docs/orientations.md"};
            write_orientation_file(path, orientation, format);
          }};
}

std::vector<ShippedFile> shipped_files() {
  return {random_file(100),
          random_file(1000),
          random_file(10000),
          single_crystal_file("single_001.txt", {0, 0, 1}, {1, 0, 0}, "[0 0 1]", "[1 0 0]"),
          single_crystal_file("single_011.txt", {0, 1, 1}, {1, 0, 0}, "[0 1 1]", "[1 0 0]"),
          single_crystal_file("single_111.txt", {1, 1, 1}, {-1, 1, 0}, "[1 1 1]", "[-1 1 0]"),
          single_crystal_file("single_-123.txt", {-1, 2, 3}, {2, 1, 0}, "[-1 2 3]", "[2 1 0]")};
}

}  // namespace

TEST(OrientationFiles, ShippedFilesMatchTheGenerator) {
  const bool regenerate = std::getenv("SUBSLIP_REGENERATE_ORIENTATIONS") != nullptr;
  for (const ShippedFile& file : shipped_files()) {
    const std::string path = std::string(SUBSLIP_SOURCE_DIR) + "/orientations/" + file.name;
    if (regenerate) file.write(path);
    const auto shipped = read_orientation_file(path);
    ASSERT_EQ(shipped.size(), file.orientations.size()) << file.name;
    for (std::size_t i = 0; i < shipped.size(); ++i) {
      ASSERT_LT(misorientation_angle(shipped[i].q, file.orientations[i].q), file.tolerance)
          << file.name << " orientation " << i;
    }
  }
  EXPECT_LT(std::filesystem::file_size(std::string(SUBSLIP_SOURCE_DIR) +
                                       "/orientations/random_10000.txt"),
            400u * 1024u);
}

TEST(OrientationFiles, SingleCrystalFilesPutTheirDirectionAlongSampleX) {
  const std::vector<std::pair<std::string, Eigen::Vector3d>> files{{"single_001.txt", {0, 0, 1}},
                                                                   {"single_011.txt", {0, 1, 1}},
                                                                   {"single_111.txt", {1, 1, 1}},
                                                                   {"single_-123.txt", {-1, 2, 3}}};
  for (const auto& [name, direction] : files) {
    const auto o = read_orientation_file(std::string(SUBSLIP_SOURCE_DIR) + "/orientations/" + name);
    ASSERT_EQ(o.size(), 1u);
    EXPECT_LT((o[0].g.transpose() * direction.normalized() - Eigen::Vector3d::UnitX()).norm(), 1e-8)
        << name;
  }
}
