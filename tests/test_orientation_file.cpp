// Orientation files: every malformed file names itself and the offending line; good files read
// back what was written; the files shipped in orientations/ are what the generator produces.
//
// Regenerate the shipped files (after a deliberate change of the generator):
//   SUBSLIP_REGENERATE_ORIENTATIONS=1 build/tests/subslip_tests
//       --gtest_filter=OrientationFiles.ShippedFilesMatchTheGenerator   (one command line)
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include "subslip/crystal/texture.hpp"
#include "subslip/io/orientation_file.hpp"

using namespace subslip::crystal;
using subslip::InputError;
using subslip::io::format_orientations;
using subslip::io::OrientationConvention;
using subslip::io::OrientationFileFormat;
using subslip::io::read_orientation_file;
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
