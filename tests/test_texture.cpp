// Orientation generators: uniformity on SO(3), reproducibility, texture components and their
// spread, single crystals.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <vector>

#include "subslip/crystal/texture.hpp"

using namespace subslip::crystal;

namespace {

constexpr double kPi = std::numbers::pi;

}  // namespace

TEST(Texture, UniformOrientationsHaveTheMomentsOfSO3) {
  // For g uniform on SO(3) every entry g_ij is distributed like one coordinate of a uniform unit
  // vector: mean 0, E[g_ij^2] = 1/3, E[g_ij^4] = 1/5, so Var(g_ij) = 1/3 and
  // Var(g_ij^2) = 1/5 - 1/9 = 4/45. With N = 10000 samples the standard error of the mean is
  // sqrt(1/(3N)) = 0.0058 for g_ij and sqrt(4/(45N)) = 0.0030 for g_ij^2; the tolerances are 5
  // standard errors (a false alarm for one of the 18 checks has probability ~1e-5, and the seed
  // is fixed anyway). The second moment catches non-uniform samplers whose mean is also zero
  // (e.g. uniform Euler angles give E[g33^2] = 1/2).
  const int n = 10000;
  const auto orientations = random_orientations(n, 2024);
  Eigen::Matrix3d mean = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d mean_square = Eigen::Matrix3d::Zero();
  double mean_angle = 0.0;
  for (const Orientation& o : orientations) {
    mean += o.g / n;
    mean_square += o.g.cwiseProduct(o.g) / n;
    mean_angle += quaternion_to_axis_angle(o.q).angle / n;
  }
  const double mean_tolerance = 5.0 * std::sqrt(1.0 / (3.0 * n));
  const double square_tolerance = 5.0 * std::sqrt(4.0 / (45.0 * n));
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      EXPECT_NEAR(mean(i, j), 0.0, mean_tolerance) << i << j;
      EXPECT_NEAR(mean_square(i, j), 1.0 / 3.0, square_tolerance) << i << j;
    }
  }
  // Rotation angle density (1 - cos w)/pi on [0, pi]: mean pi/2 + 2/pi, variance
  // pi^2/3 + 2 - (pi/2 + 2/pi)^2 = 0.417.
  const double expected_angle = kPi / 2.0 + 2.0 / kPi;
  const double angle_sd = std::sqrt(kPi * kPi / 3.0 + 2.0 - expected_angle * expected_angle);
  EXPECT_NEAR(mean_angle, expected_angle, 5.0 * angle_sd / std::sqrt(double(n)));
}

TEST(Texture, SeededGenerationIsReproducible) {
  const auto a = random_orientations(50, 7);
  const auto b = random_orientations(50, 7);
  const auto c = random_orientations(50, 8);
  for (int i = 0; i < 50; ++i) {
    EXPECT_EQ(a[i].q.w, b[i].q.w);
    EXPECT_EQ(a[i].q.x, b[i].q.x);
    EXPECT_EQ(a[i].q.y, b[i].q.y);
    EXPECT_EQ(a[i].q.z, b[i].q.z);
    EXPECT_NEAR(a[i].q.norm(), 1.0, 1e-15);
    EXPECT_GE(a[i].q.w, 0.0);
  }
  EXPECT_NE(a[0].q.w, c[0].q.w);
  const auto goss1 = component_orientations(TextureComponent::goss, 20, 5.0, 3);
  const auto goss2 = component_orientations(TextureComponent::goss, 20, 5.0, 3);
  for (int i = 0; i < 20; ++i) EXPECT_EQ(goss1[i].q.x, goss2[i].q.x);
  // mt19937_64 is fully specified: its 10000th output is fixed by the standard.
  std::mt19937_64 engine;
  engine.discard(9999);
  EXPECT_EQ(engine(), 9981545732273789042ull);
}

// A rank that keeps only its block visits a generated set one orientation at a time; it must
// see the set a process holding it whole sees, bit for bit and in order.
TEST(Texture, VisitedSetIsTheStoredSet) {
  for (const auto& request :
       {OrientationRequest{40, 11, std::nullopt, 0.0},
        OrientationRequest{40, 11, TextureComponent::copper, 8.0}}) {
    const auto stored = generate_orientations(request);
    std::vector<Orientation> visited;
    for_each_generated_orientation(request, [&](const Orientation& o) { visited.push_back(o); });
    ASSERT_EQ(visited.size(), stored.size());
    for (std::size_t i = 0; i < stored.size(); ++i) {
      EXPECT_EQ(visited[i].q.w, stored[i].q.w);
      EXPECT_EQ(visited[i].q.x, stored[i].q.x);
      EXPECT_EQ(visited[i].q.y, stored[i].q.y);
      EXPECT_EQ(visited[i].q.z, stored[i].q.z);
      EXPECT_TRUE(visited[i].g == stored[i].g);
      EXPECT_EQ(visited[i].weight, stored[i].weight);
    }
  }
  EXPECT_THROW(for_each_generated_orientation(OrientationRequest{0, 1, std::nullopt, 0.0},
                                              [](const Orientation&) {}),
               std::invalid_argument);
}

TEST(Texture, ComponentsReproduceTheTabulatedEulerAngles) {
  struct Tabulated {
    TextureComponent component;
    double phi1, Phi, phi2;
  };
  const Tabulated table[] = {{TextureComponent::cube, 0.0, 0.0, 0.0},
                             {TextureComponent::goss, 0.0, 45.0, 0.0},
                             {TextureComponent::brass, 35.26, 45.0, 0.0},
                             {TextureComponent::copper, 90.0, 35.26, 45.0},
                             {TextureComponent::s, 58.98, 36.70, 63.43}};
  for (const Tabulated& row : table) {
    const Eigen::Vector3d euler =
        radians_to_degrees(quaternion_to_euler(ideal_orientation(row.component).q));
    EXPECT_NEAR(euler[0], row.phi1, 0.01) << to_string(row.component);
    EXPECT_NEAR(euler[1], row.Phi, 0.01) << to_string(row.component);
    EXPECT_NEAR(euler[2], row.phi2, 0.01) << to_string(row.component);
  }
}

TEST(Texture, ComponentPlaneIsAlongNdAndDirectionAlongRd) {
  // Goss {011}<100>: sample z (ND) is the crystal [011], sample x (RD) the crystal [100].
  const Eigen::Matrix3d g = ideal_orientation(TextureComponent::goss).g;
  EXPECT_LT((g * Eigen::Vector3d::UnitZ() - Eigen::Vector3d(0, 1, 1).normalized()).norm(), 1e-15);
  EXPECT_LT((g * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitX()).norm(), 1e-15);
  EXPECT_THROW(
      orientation_from_plane_and_direction(Eigen::Vector3d(1, 1, 1), Eigen::Vector3d(1, 0, 0)),
      std::invalid_argument);
}

TEST(Texture, SpreadIsTheRmsMisorientationToTheIdealComponent) {
  // The rotation vector has 3 independent N(0, s^2/3) components, so w^2 = (s^2/3) chi^2_3:
  // E[w^2] = s^2 and Var(w^2) = 2 s^4 / 3. With N = 4000 the relative standard error of the mean
  // of w^2 is sqrt(2/3 / N) = 1.3 %, i.e. 0.65 % on the rms; tolerance 5 standard errors.
  const int n = 4000;
  const double spread_deg = 5.0;
  const Quaternion ideal = ideal_orientation(TextureComponent::copper).q;
  double mean_square = 0.0;
  for (const Orientation& o : component_orientations(TextureComponent::copper, n, spread_deg, 11)) {
    const double angle = misorientation_angle(o.q, ideal) * 180.0 / kPi;
    mean_square += angle * angle / n;
  }
  EXPECT_NEAR(std::sqrt(mean_square), spread_deg,
              spread_deg * 5.0 * 0.5 * std::sqrt(2.0 / 3.0 / n));

  for (const Orientation& o : component_orientations(TextureComponent::brass, 5, 0.0, 1)) {
    EXPECT_NEAR(misorientation_angle(o.q, ideal_orientation(TextureComponent::brass).q), 0.0,
                1e-12);
  }
  EXPECT_THROW(component_orientations(TextureComponent::cube, 5, -1.0, 1), std::invalid_argument);
  EXPECT_THROW(component_orientations(TextureComponent::cube, 5, 200.0, 1), std::invalid_argument);
}

TEST(Texture, SingleCrystalPutsTheChosenDirectionAlongSampleX) {
  const Orientation o =
      single_crystal_orientation(Eigen::Vector3d(-1, 2, 3), Eigen::Vector3d(2, 1, 0));
  EXPECT_LT(
      (o.g.transpose() * Eigen::Vector3d(-1, 2, 3).normalized() - Eigen::Vector3d::UnitX()).norm(),
      1e-15);
  EXPECT_LT(
      (o.g.transpose() * Eigen::Vector3d(2, 1, 0).normalized() - Eigen::Vector3d::UnitY()).norm(),
      1e-15);
  EXPECT_TRUE(is_rotation(o.g, 1e-14));
  EXPECT_THROW(single_crystal_orientation(Eigen::Vector3d(1, 1, 1), Eigen::Vector3d(1, 0, 0)),
               std::invalid_argument);
  EXPECT_THROW(single_crystal_orientation(Eigen::Vector3d::Zero(), Eigen::Vector3d(1, 0, 0)),
               std::invalid_argument);
}

TEST(Texture, ComponentNamesAndRequests) {
  for (TextureComponent c :
       {TextureComponent::cube, TextureComponent::goss, TextureComponent::brass,
        TextureComponent::copper, TextureComponent::s}) {
    EXPECT_EQ(parse_texture_component(to_string(c)), c);
  }
  try {
    parse_texture_component("rotated_cube");
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("cube, goss, brass, copper, s"), std::string::npos);
  }
  OrientationRequest request;
  request.count = 3;
  request.seed = 9;
  EXPECT_EQ(describe(request), "random count=3 seed=9");
  EXPECT_EQ(generate_orientations(request).size(), 3u);
  request.component = TextureComponent::goss;
  request.spread_deg = 5.0;
  EXPECT_EQ(describe(request), "component=goss spread_deg=5 count=3 seed=9");
  request.count = 0;
  EXPECT_THROW(generate_orientations(request), std::invalid_argument);
}
