// Slip-system generation: counts, geometry, symmetry closure and an independent brute-force
// enumeration of the cubic families.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <numbers>
#include <set>
#include <vector>

#include "subslip/crystal/slip_systems.hpp"

using namespace subslip::crystal;

namespace {

const std::map<SlipFamily, int> kExpectedCounts{
    {SlipFamily::fcc_111_110, 12},      {SlipFamily::bcc_110_111, 12},
    {SlipFamily::bcc_112_111, 12},      {SlipFamily::bcc_123_111, 24},
    {SlipFamily::hcp_basal_a, 3},       {SlipFamily::hcp_prismatic_a, 3},
    {SlipFamily::hcp_pyramidal_a, 6},   {SlipFamily::hcp_pyramidal2_ca, 6},
    {SlipFamily::hcp_pyramidal_ca, 12},
};

constexpr double kTitanium = 1.587;
constexpr double kMagnesium = 1.624;

std::vector<Eigen::Matrix3d> point_group_of(SlipFamily family) {
  return lattice_of(family) == LatticeKind::hcp ? hexagonal_rotations() : cubic_rotations();
}

int find_system(const std::vector<SlipSystem>& systems, const Eigen::Vector3d& s,
                const Eigen::Vector3d& m) {
  for (const SlipSystem& candidate : systems) {
    if (candidate.m.cross(m).norm() < 1e-9 && candidate.s.cross(s).norm() < 1e-9) {
      return candidate.index;
    }
  }
  return -1;
}

// All integer vectors whose absolute entries are a permutation of `pattern` (signs free).
std::vector<Eigen::Vector3i> signed_permutations(std::array<int, 3> pattern) {
  std::set<std::array<int, 3>> found;
  std::sort(pattern.begin(), pattern.end());
  do {
    for (int bits = 0; bits < 8; ++bits) {
      found.insert({bits & 1 ? -pattern[0] : pattern[0], bits & 2 ? -pattern[1] : pattern[1],
                    bits & 4 ? -pattern[2] : pattern[2]});
    }
  } while (std::next_permutation(pattern.begin(), pattern.end()));
  std::vector<Eigen::Vector3i> vectors;
  for (const auto& v : found) vectors.emplace_back(v[0], v[1], v[2]);
  return vectors;
}

}  // namespace

TEST(SlipSystems, CountsPerFamily) {
  ASSERT_EQ(all_slip_families().size(), kExpectedCounts.size());
  for (const auto& [family, count] : kExpectedCounts) {
    EXPECT_EQ(slip_system_count(family), count) << to_string(family);
    const auto systems = slip_systems(family, kMagnesium);
    ASSERT_EQ(int(systems.size()), count) << to_string(family);
    for (int i = 0; i < count; ++i) {
      EXPECT_EQ(systems[i].index, i);
      EXPECT_EQ(systems[i].family, family);
    }
  }
}

TEST(SlipSystems, UnitVectorsAndDirectionInPlane) {
  for (double c_over_a : {kTitanium, kMagnesium, kIdealCOverA}) {
    for (SlipFamily family : all_slip_families()) {
      for (const SlipSystem& system : slip_systems(family, c_over_a)) {
        EXPECT_NEAR(system.s.norm(), 1.0, 1e-15) << system.label;
        EXPECT_NEAR(system.m.norm(), 1.0, 1e-15) << system.label;
        EXPECT_NEAR(system.s.dot(system.m), 0.0, 1e-15) << system.label;
      }
    }
  }
}

TEST(SlipSystems, NoDuplicateSystems) {
  for (SlipFamily family : all_slip_families()) {
    const auto systems = slip_systems(family, kTitanium);
    for (std::size_t i = 0; i < systems.size(); ++i) {
      for (std::size_t j = i + 1; j < systems.size(); ++j) {
        EXPECT_FALSE(same_slip_system(systems[i], systems[j]))
            << to_string(family) << ": " << systems[i].label << " and " << systems[j].label;
      }
    }
  }
}

TEST(SlipSystems, PointGroupsAreGroupsOfRotations) {
  for (const auto& group : {cubic_rotations(), hexagonal_rotations()}) {
    for (const Eigen::Matrix3d& a : group) {
      EXPECT_LT((a * a.transpose() - Eigen::Matrix3d::Identity()).norm(), 1e-14);
      EXPECT_NEAR(a.determinant(), 1.0, 1e-14);
      for (const Eigen::Matrix3d& b : group) {
        const bool closed = std::any_of(group.begin(), group.end(), [&](const Eigen::Matrix3d& c) {
          return (a * b - c).norm() < 1e-12;
        });
        EXPECT_TRUE(closed);
      }
    }
  }
  EXPECT_EQ(cubic_rotations().size(), 24u);
  EXPECT_EQ(hexagonal_rotations().size(), 12u);
}

TEST(SlipSystems, EveryFamilyIsClosedUnderItsPointGroup) {
  // The Cartesian point-group matrices are independent of the index arithmetic that generated
  // the systems: each image of each system must be a system of the set (and, the action being
  // transitive, every system is an image of the first one).
  for (SlipFamily family : all_slip_families()) {
    const auto systems = slip_systems(family, kMagnesium);
    std::set<int> images_of_first;
    for (const Eigen::Matrix3d& R : point_group_of(family)) {
      for (const SlipSystem& system : systems) {
        EXPECT_GE(find_system(systems, R * system.s, R * system.m), 0)
            << to_string(family) << " " << system.label;
      }
      images_of_first.insert(find_system(systems, R * systems[0].s, R * systems[0].m));
    }
    EXPECT_EQ(int(images_of_first.size()), int(systems.size())) << to_string(family);
  }
}

TEST(SlipSystems, CubicFamiliesMatchBruteForceEnumeration) {
  struct Pattern {
    SlipFamily family;
    std::array<int, 3> plane;
    std::array<int, 3> direction;
  };
  const std::vector<Pattern> patterns{{SlipFamily::fcc_111_110, {1, 1, 1}, {0, 1, 1}},
                                      {SlipFamily::bcc_110_111, {0, 1, 1}, {1, 1, 1}},
                                      {SlipFamily::bcc_112_111, {1, 1, 2}, {1, 1, 1}},
                                      {SlipFamily::bcc_123_111, {1, 2, 3}, {1, 1, 1}}};
  for (const Pattern& pattern : patterns) {
    // Every (plane, direction) with direction in plane, counted once up to both signs.
    std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> enumerated;
    for (const Eigen::Vector3i& n : signed_permutations(pattern.plane)) {
      for (const Eigen::Vector3i& d : signed_permutations(pattern.direction)) {
        if (n.dot(d) != 0) continue;
        const Eigen::Vector3d m = n.cast<double>().normalized();
        const Eigen::Vector3d s = d.cast<double>().normalized();
        const bool seen = std::any_of(enumerated.begin(), enumerated.end(), [&](const auto& e) {
          return e.first.cross(s).norm() < 1e-12 && e.second.cross(m).norm() < 1e-12;
        });
        if (!seen) enumerated.emplace_back(s, m);
      }
    }
    const auto systems = slip_systems(pattern.family);
    EXPECT_EQ(enumerated.size(), systems.size()) << to_string(pattern.family);
    for (const auto& [s, m] : enumerated) {
      EXPECT_GE(find_system(systems, s, m), 0) << to_string(pattern.family);
    }
  }
}

TEST(SlipSystems, HexagonalGeometryFollowsCOverA) {
  for (double c_over_a : {kTitanium, kMagnesium}) {
    for (const SlipSystem& basal : slip_systems(SlipFamily::hcp_basal_a, c_over_a)) {
      EXPECT_NEAR(std::abs(basal.m.z()), 1.0, 1e-15);
    }
    for (const SlipSystem& prismatic : slip_systems(SlipFamily::hcp_prismatic_a, c_over_a)) {
      EXPECT_NEAR(prismatic.m.z(), 0.0, 1e-15);
      EXPECT_NEAR(prismatic.s.z(), 0.0, 1e-15);
    }
    // {10-11}: tan(angle to c) = 2 (c/a) / sqrt3 (61.9 deg for Mg).
    for (const SlipSystem& pyramidal : slip_systems(SlipFamily::hcp_pyramidal_a, c_over_a)) {
      const double angle = std::acos(std::abs(pyramidal.m.z()));
      EXPECT_NEAR(std::tan(angle), 2.0 * c_over_a / std::sqrt(3.0), 1e-12);
      EXPECT_NEAR(pyramidal.s.z(), 0.0, 1e-15);  // <a> slip
    }
    // {11-22}: tan(angle to c) = c/a (58.4 deg for Mg); <c+a>: tan(angle to c) = 1/(c/a), and
    // the length of 1/3<11-23> is sqrt(a^2 + c^2).
    for (const SlipSystem& pyramidal : slip_systems(SlipFamily::hcp_pyramidal2_ca, c_over_a)) {
      EXPECT_NEAR(std::tan(std::acos(std::abs(pyramidal.m.z()))), c_over_a, 1e-12);
      EXPECT_NEAR(std::tan(std::acos(std::abs(pyramidal.s.z()))), 1.0 / c_over_a, 1e-12);
    }
    for (const SlipSystem& pyramidal : slip_systems(SlipFamily::hcp_pyramidal_ca, c_over_a)) {
      EXPECT_NEAR(std::tan(std::acos(std::abs(pyramidal.m.z()))), 2.0 * c_over_a / std::sqrt(3.0),
                  1e-12);
      EXPECT_NEAR(std::tan(std::acos(std::abs(pyramidal.s.z()))), 1.0 / c_over_a, 1e-12);
    }
    EXPECT_NEAR(miller_bravais_direction(-1, -1, 2, 3, c_over_a).norm() / 3.0,
                std::sqrt(1.0 + c_over_a * c_over_a), 1e-14);
  }
  // a1 along x and c along z, as documented.
  EXPECT_LT((miller_bravais_direction(2, -1, -1, 0, 1.6) / 3.0 - Eigen::Vector3d::UnitX()).norm(),
            1e-15);
  EXPECT_LT((miller_bravais_direction(0, 0, 0, 1, 1.6) - Eigen::Vector3d(0, 0, 1.6)).norm(), 1e-15);
  EXPECT_LT((miller_bravais_direction(-1, 2, -1, 0, 1.6) / 3.0 -
             Eigen::Vector3d(-0.5, std::sqrt(3.0) / 2.0, 0.0))
                .norm(),
            1e-15);
  EXPECT_THROW(miller_bravais_direction(1, 0, 0, 0, 1.6), std::invalid_argument);
  EXPECT_THROW(miller_bravais_plane_normal(1, 0, -1, 1, 0.0), std::invalid_argument);
}

TEST(SlipSystems, PlaneNormalIsPerpendicularToDirectionsInThePlane) {
  // (1 0 -1 1) contains [-1 2 -1 0] and [-2 1 1 3] for any c/a (zone law).
  for (double c_over_a : {1.0, kTitanium, 2.0}) {
    const Eigen::Vector3d n = miller_bravais_plane_normal(1, 0, -1, 1, c_over_a);
    EXPECT_NEAR(n.dot(miller_bravais_direction(-1, 2, -1, 0, c_over_a)), 0.0, 1e-14);
    EXPECT_NEAR(n.dot(miller_bravais_direction(-2, 1, 1, 3, c_over_a)), 0.0, 1e-14);
  }
}

TEST(SlipSystems, NamesParseAndUnknownNamesListTheValidOnes) {
  for (SlipFamily family : all_slip_families()) {
    EXPECT_EQ(parse_slip_family(to_string(family)), family);
  }
  EXPECT_EQ(parse_slip_family("hcp_pyramidal2_ca"), SlipFamily::hcp_pyramidal2_ca);
  try {
    parse_slip_family("fcc_111");
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("'fcc_111'"), std::string::npos) << message;
    for (SlipFamily family : all_slip_families()) {
      EXPECT_NE(message.find(std::string(to_string(family))), std::string::npos) << message;
    }
  }
}

TEST(SlipSystems, FamilyListsAreValidated) {
  const std::array<SlipFamily, 2> bcc{SlipFamily::bcc_110_111, SlipFamily::bcc_112_111};
  EXPECT_EQ(slip_systems(bcc).size(), 24u);
  const std::array<SlipFamily, 3> hcp{SlipFamily::hcp_basal_a, SlipFamily::hcp_prismatic_a,
                                      SlipFamily::hcp_pyramidal2_ca};
  const auto systems = slip_systems(hcp, kMagnesium);
  ASSERT_EQ(systems.size(), 12u);
  EXPECT_EQ(systems[3].family, SlipFamily::hcp_prismatic_a);
  EXPECT_EQ(systems[3].index, 0);

  const std::array<SlipFamily, 2> mixed{SlipFamily::fcc_111_110, SlipFamily::hcp_basal_a};
  EXPECT_THROW(slip_systems(mixed), std::invalid_argument);
  const std::array<SlipFamily, 2> twice{SlipFamily::hcp_basal_a, SlipFamily::hcp_basal_a};
  EXPECT_THROW(slip_systems(twice), std::invalid_argument);
  EXPECT_THROW(slip_systems(std::span<const SlipFamily>{}), std::invalid_argument);
  EXPECT_THROW(slip_systems(SlipFamily::hcp_basal_a, -1.0), std::invalid_argument);
}

TEST(SlipSystems, LabelsGiveTheIndices) {
  const auto fcc = slip_systems(SlipFamily::fcc_111_110);
  EXPECT_EQ(fcc[0].label, "(1 1 1)[1 0 -1]");
  EXPECT_LT((fcc[0].m - Eigen::Vector3d(1, 1, 1).normalized()).norm(), 1e-15);
  EXPECT_LT((fcc[0].s - Eigen::Vector3d(1, 0, -1).normalized()).norm(), 1e-15);
  const auto basal = slip_systems(SlipFamily::hcp_basal_a);
  EXPECT_EQ(basal[0].label, "(0 0 0 1)[2 -1 -1 0]");
  EXPECT_LT((basal[0].s - Eigen::Vector3d::UnitX()).norm(), 1e-15);
}

TEST(SlipSystems, SchmidTensors) {
  const auto fcc = slip_systems(SlipFamily::fcc_111_110);
  for (const SlipSystem& system : fcc) {
    const Eigen::Matrix3d P = schmid_tensor_symmetric(system);
    EXPECT_LT((P - P.transpose()).norm(), 1e-15);
    EXPECT_NEAR(P.trace(), 0.0, 1e-15);
    EXPECT_NEAR((P.array() * P.array()).sum(), 0.5, 1e-15);  // P : P = 1/2
    EXPECT_NEAR(schmid_mandel(system).squaredNorm(), 0.5, 1e-15);
    EXPECT_LT((P + schmid_tensor_skew(system) - schmid_tensor(system)).norm(), 1e-15);
  }
  // Uniaxial tension along [001]: the largest Schmid factor is 1/sqrt6, on 8 of the 12 systems.
  Eigen::Matrix3d tension = Eigen::Matrix3d::Zero();
  tension(2, 2) = 1.0;
  int active = 0;
  double largest = 0.0;
  for (const SlipSystem& system : fcc) {
    const double factor = std::abs((tension.array() * schmid_tensor(system).array()).sum());
    largest = std::max(largest, factor);
    active += std::abs(factor - 1.0 / std::sqrt(6.0)) < 1e-12 ? 1 : 0;
  }
  EXPECT_NEAR(largest, 1.0 / std::sqrt(6.0), 1e-12);
  EXPECT_EQ(active, 8);
}

TEST(SlipSystems, CoplanarPairs) {
  auto pairs_of = [](std::vector<SlipFamily> families) {
    return coplanar_pairs(std::span<const SlipFamily>(families), kMagnesium).size();
  };
  EXPECT_EQ(pairs_of({SlipFamily::fcc_111_110}), 12u);  // 4 planes x 3 pairs
  EXPECT_EQ(pairs_of({SlipFamily::bcc_110_111}), 6u);   // 6 planes x 1 pair
  EXPECT_EQ(pairs_of({SlipFamily::bcc_112_111}), 0u);
  EXPECT_EQ(pairs_of({SlipFamily::bcc_123_111}), 0u);
  EXPECT_EQ(pairs_of({SlipFamily::hcp_basal_a}), 3u);
  EXPECT_EQ(pairs_of({SlipFamily::hcp_pyramidal_ca}), 6u);
  // Pyramidal <a> and first-order <c+a> share the {10-11} planes: 6 planes x C(3,2) pairs.
  EXPECT_EQ(pairs_of({SlipFamily::hcp_pyramidal_a, SlipFamily::hcp_pyramidal_ca}), 18u);
  const auto systems = slip_systems(SlipFamily::fcc_111_110);
  for (const auto& [i, j] : coplanar_pairs(systems)) {
    EXPECT_LT(i, j);
    EXPECT_TRUE(coplanar(systems[i], systems[j]));
  }
}
