#include "subslip/crystal/slip_systems.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <numbers>
#include <set>
#include <stdexcept>

namespace subslip::crystal {

namespace {

// Miller indices (h k l, fourth entry 0) or Miller-Bravais indices (h k i l).
using Indices = std::array<int, 4>;

struct IndexedSystem {
  Indices normal;
  Indices direction;
  auto operator<=>(const IndexedSystem&) const = default;
};

struct FamilyData {
  SlipFamily family;
  std::string_view name;
  std::string_view notation;
  LatticeKind lattice;
  int count;
  IndexedSystem representative;
};

// One representative (plane, direction) per family; the rest follow by symmetry.
constexpr std::array<FamilyData, 9> kFamilies{{
    {SlipFamily::fcc_111_110,
     "fcc_111_110",
     "{111}<110>",
     LatticeKind::fcc,
     12,
     {{1, 1, 1, 0}, {0, 1, -1, 0}}},
    {SlipFamily::bcc_110_111,
     "bcc_110_111",
     "{110}<111>",
     LatticeKind::bcc,
     12,
     {{0, 1, 1, 0}, {1, -1, 1, 0}}},
    {SlipFamily::bcc_112_111,
     "bcc_112_111",
     "{112}<111>",
     LatticeKind::bcc,
     12,
     {{2, 1, 1, 0}, {-1, 1, 1, 0}}},
    {SlipFamily::bcc_123_111,
     "bcc_123_111",
     "{123}<111>",
     LatticeKind::bcc,
     24,
     {{1, 2, 3, 0}, {1, 1, -1, 0}}},
    {SlipFamily::hcp_basal_a,
     "hcp_basal_a",
     "(0001)<11-20>",
     LatticeKind::hcp,
     3,
     {{0, 0, 0, 1}, {2, -1, -1, 0}}},
    {SlipFamily::hcp_prismatic_a,
     "hcp_prismatic_a",
     "{10-10}<11-20>",
     LatticeKind::hcp,
     3,
     {{0, 1, -1, 0}, {2, -1, -1, 0}}},
    {SlipFamily::hcp_pyramidal_a,
     "hcp_pyramidal_a",
     "{10-11}<11-20>",
     LatticeKind::hcp,
     6,
     {{1, 0, -1, 1}, {-1, 2, -1, 0}}},
    {SlipFamily::hcp_pyramidal2_ca,
     "hcp_pyramidal2_ca",
     "{11-22}<11-23>",
     LatticeKind::hcp,
     6,
     {{1, 1, -2, 2}, {-1, -1, 2, 3}}},
    {SlipFamily::hcp_pyramidal_ca,
     "hcp_pyramidal_ca",
     "{10-11}<11-23>",
     LatticeKind::hcp,
     12,
     {{1, 0, -1, 1}, {-2, 1, 1, 3}}},
}};

constexpr std::array<SlipFamily, kFamilies.size()> kAllFamilies = [] {
  std::array<SlipFamily, kFamilies.size()> families{};
  for (std::size_t i = 0; i < kFamilies.size(); ++i) families[i] = kFamilies[i].family;
  return families;
}();

const FamilyData& data_of(SlipFamily family) {
  for (const FamilyData& data : kFamilies) {
    if (data.family == family) return data;
  }
  throw std::invalid_argument("slip family out of range");
}

// The 24 proper rotations of 432 are the signed permutations with determinant +1:
// v'_i = sign_i v_{perm_i}. Calls visit(perm, sign) for each, in a fixed order.
template <typename Visit>
void for_each_cubic_rotation(Visit visit) {
  std::array<int, 3> perm{0, 1, 2};
  do {
    int inversions = 0;
    for (int i = 0; i < 3; ++i) {
      for (int j = i + 1; j < 3; ++j) inversions += perm[i] > perm[j] ? 1 : 0;
    }
    const int parity = inversions % 2 == 0 ? 1 : -1;
    for (int bits = 0; bits < 8; ++bits) {
      const std::array<int, 3> sign{bits & 1 ? -1 : 1, bits & 2 ? -1 : 1, bits & 4 ? -1 : 1};
      if (parity * sign[0] * sign[1] * sign[2] == 1) visit(perm, sign);
    }
  } while (std::next_permutation(perm.begin(), perm.end()));
}

std::vector<IndexedSystem> cubic_images(const IndexedSystem& system) {
  std::vector<IndexedSystem> images;
  auto apply = [](const Indices& v, const std::array<int, 3>& perm,
                  const std::array<int, 3>& sign) {
    return Indices{sign[0] * v[perm[0]], sign[1] * v[perm[1]], sign[2] * v[perm[2]], 0};
  };
  for_each_cubic_rotation([&](const std::array<int, 3>& perm, const std::array<int, 3>& sign) {
    images.push_back({apply(system.normal, perm, sign), apply(system.direction, perm, sign)});
  });
  return images;
}

// 622 acting on Miller-Bravais indices. The rotation by +60 deg about c takes a1 -> -a3,
// a2 -> -a1, a3 -> -a2, so [u v t w] -> [-v -t -u w]; the 2-fold rotation about a1 swaps a2 and
// a3 and reverses c: [u v t w] -> [u t v -w]. Plane indices (h k i l) transform alike, since the
// in-plane part of a plane normal is proportional to h a1 + k a2 + i a3.
Indices rotate_60(const Indices& v) {
  return {-v[1], -v[2], -v[0], v[3]};
}
Indices two_fold_about_a1(const Indices& v) {
  return {v[0], v[2], v[1], -v[3]};
}

std::vector<IndexedSystem> hexagonal_images(const IndexedSystem& system) {
  std::vector<IndexedSystem> images;
  IndexedSystem turned = system;
  for (int k = 0; k < 6; ++k) {
    images.push_back(turned);
    images.push_back({two_fold_about_a1(turned.normal), two_fold_about_a1(turned.direction)});
    turned = {rotate_60(turned.normal), rotate_60(turned.direction)};
  }
  return images;
}

// The sign-independent form: first non-zero index positive.
Indices with_positive_lead(Indices v) {
  for (int value : v) {
    if (value == 0) continue;
    if (value < 0) {
      for (int& entry : v) entry = -entry;
    }
    break;
  }
  return v;
}

std::string format_indices(const Indices& v, int count, char open, char close) {
  std::string text(1, open);
  for (int i = 0; i < count; ++i) {
    if (i > 0) text += ' ';
    text += std::to_string(v[i]);
  }
  return text + close;
}

void require_valid_c_over_a(double c_over_a) {
  if (!(c_over_a > 0.0) || !std::isfinite(c_over_a)) {
    throw std::invalid_argument("c/a must be a positive number, got " + std::to_string(c_over_a));
  }
}

void require_four_index_sum(int first, int second, int third, const char* what) {
  if (third != -(first + second)) {
    throw std::invalid_argument(std::string("Miller-Bravais ") + what +
                                ": the third index must be -(first + second)");
  }
}

}  // namespace

std::string_view to_string(SlipFamily family) {
  return data_of(family).name;
}

SlipFamily parse_slip_family(std::string_view name) {
  std::string valid;
  for (const FamilyData& data : kFamilies) {
    if (data.name == name) return data.family;
    valid += (valid.empty() ? "" : ", ") + std::string(data.name);
  }
  throw std::invalid_argument("unknown slip family '" + std::string(name) +
                              "'; valid names: " + valid);
}

std::span<const SlipFamily> all_slip_families() {
  return kAllFamilies;
}

LatticeKind lattice_of(SlipFamily family) {
  return data_of(family).lattice;
}

int slip_system_count(SlipFamily family) {
  return data_of(family).count;
}

std::string_view miller_notation(SlipFamily family) {
  return data_of(family).notation;
}

Eigen::Vector3d miller_bravais_direction(int u, int v, int t, int w, double c_over_a) {
  require_four_index_sum(u, v, t, "direction [u v t w]");
  require_valid_c_over_a(c_over_a);
  // u a1 + v a2 + t a3 + w c with t = -(u + v).
  return {1.5 * u, std::sqrt(0.75) * (u + 2.0 * v), w * c_over_a};
}

Eigen::Vector3d miller_bravais_plane_normal(int h, int k, int i, int l, double c_over_a) {
  require_four_index_sum(h, k, i, "plane (h k i l)");
  require_valid_c_over_a(c_over_a);
  // h a1* + k a2* + l c* with a1* = [1, 1/sqrt3, 0], a2* = [0, 2/sqrt3, 0], c* = [0, 0, 1/(c/a)].
  return {double(h), (h + 2.0 * k) / std::sqrt(3.0), l / c_over_a};
}

std::vector<SlipSystem> slip_systems(SlipFamily family, double c_over_a) {
  const FamilyData& data = data_of(family);
  const bool hexagonal = data.lattice == LatticeKind::hcp;
  if (hexagonal) require_valid_c_over_a(c_over_a);

  const std::vector<IndexedSystem> images =
      hexagonal ? hexagonal_images(data.representative) : cubic_images(data.representative);
  std::set<IndexedSystem, std::greater<>> distinct;
  for (const IndexedSystem& image : images) {
    distinct.insert({with_positive_lead(image.normal), with_positive_lead(image.direction)});
  }

  std::vector<SlipSystem> systems;
  for (const IndexedSystem& indexed : distinct) {
    const Indices& n = indexed.normal;
    const Indices& d = indexed.direction;
    SlipSystem system{
        .s = {}, .m = {}, .family = family, .index = int(systems.size()), .label = {}};
    if (hexagonal) {
      system.s = miller_bravais_direction(d[0], d[1], d[2], d[3], c_over_a).normalized();
      system.m = miller_bravais_plane_normal(n[0], n[1], n[2], n[3], c_over_a).normalized();
      system.label = format_indices(n, 4, '(', ')') + format_indices(d, 4, '[', ']');
    } else {
      system.s = Eigen::Vector3d(d[0], d[1], d[2]).normalized();
      system.m = Eigen::Vector3d(n[0], n[1], n[2]).normalized();
      system.label = format_indices(n, 3, '(', ')') + format_indices(d, 3, '[', ']');
    }
    systems.push_back(std::move(system));
  }
  // The counts are a property of crystallography, not of this code: a mismatch is a bug here.
  if (int(systems.size()) != data.count) {
    throw std::logic_error("slip family " + std::string(data.name) + " generated " +
                           std::to_string(systems.size()) + " systems instead of " +
                           std::to_string(data.count));
  }
  return systems;
}

std::vector<SlipSystem> slip_systems(std::span<const SlipFamily> families, double c_over_a) {
  if (families.empty()) throw std::invalid_argument("no slip families given");
  std::vector<SlipSystem> systems;
  for (std::size_t i = 0; i < families.size(); ++i) {
    if (std::find(families.begin(), families.begin() + i, families[i]) != families.begin() + i) {
      throw std::invalid_argument("slip family " + std::string(to_string(families[i])) +
                                  " is listed twice");
    }
    if (lattice_of(families[i]) != lattice_of(families[0])) {
      throw std::invalid_argument("slip families " + std::string(to_string(families[0])) + " and " +
                                  std::string(to_string(families[i])) +
                                  " belong to different lattices");
    }
    std::vector<SlipSystem> family_systems = slip_systems(families[i], c_over_a);
    systems.insert(systems.end(), std::make_move_iterator(family_systems.begin()),
                   std::make_move_iterator(family_systems.end()));
  }
  return systems;
}

std::vector<Eigen::Matrix3d> cubic_rotations() {
  std::vector<Eigen::Matrix3d> rotations;
  for_each_cubic_rotation([&](const std::array<int, 3>& perm, const std::array<int, 3>& sign) {
    Eigen::Matrix3d R = Eigen::Matrix3d::Zero();
    for (int i = 0; i < 3; ++i) R(i, perm[i]) = sign[i];
    rotations.push_back(R);
  });
  return rotations;
}

std::vector<Eigen::Matrix3d> hexagonal_rotations() {
  const Eigen::Matrix3d two_fold_about_x = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
  std::vector<Eigen::Matrix3d> rotations;
  for (int k = 0; k < 6; ++k) {
    const Eigen::Matrix3d about_c =
        Eigen::AngleAxisd(k * std::numbers::pi / 3.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    rotations.push_back(about_c);
    rotations.push_back(about_c * two_fold_about_x);
  }
  return rotations;
}

Eigen::Matrix3d schmid_tensor(const SlipSystem& system) {
  return system.s * system.m.transpose();
}

Eigen::Matrix3d schmid_tensor_symmetric(const SlipSystem& system) {
  const Eigen::Matrix3d P = schmid_tensor(system);
  return 0.5 * (P + P.transpose());
}

MandelVector schmid_mandel(const SlipSystem& system) {
  return mandel_from_symmetric(schmid_tensor_symmetric(system));
}

Eigen::Matrix3d schmid_tensor_skew(const SlipSystem& system) {
  const Eigen::Matrix3d P = schmid_tensor(system);
  return 0.5 * (P - P.transpose());
}

bool coplanar(const SlipSystem& a, const SlipSystem& b, double tolerance) {
  // |m_a x m_b| is the sine of the angle between the normals: linear in a small angle, unlike
  // 1 - |m_a . m_b|.
  return a.m.cross(b.m).norm() <= tolerance;
}

bool same_slip_system(const SlipSystem& a, const SlipSystem& b, double tolerance) {
  return coplanar(a, b, tolerance) && a.s.cross(b.s).norm() <= tolerance;
}

std::vector<std::pair<int, int>> coplanar_pairs(const std::vector<SlipSystem>& systems) {
  std::vector<std::pair<int, int>> pairs;
  for (int i = 0; i < int(systems.size()); ++i) {
    for (int j = i + 1; j < int(systems.size()); ++j) {
      if (coplanar(systems[i], systems[j])) pairs.emplace_back(i, j);
    }
  }
  return pairs;
}

std::vector<std::pair<int, int>> coplanar_pairs(std::span<const SlipFamily> families,
                                                double c_over_a) {
  return coplanar_pairs(slip_systems(families, c_over_a));
}

}  // namespace subslip::crystal
