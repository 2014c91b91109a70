// Abaqus' component order of symmetric tensors (11, 22, 33, 12, 13, 23, shear strains as
// engineering shears gamma = 2 eps) against the Mandel vectors of the material-point API
// (11, 22, 33, sqrt2 23, sqrt2 13, sqrt2 12). With NSHR = 1 (plane strain, axisymmetry) only the
// first four components are used.
#pragma once

#include <Eigen/Core>
#include <array>
#include <numbers>

#include "subslip/crystal/elasticity.hpp"
#include "subslip/material_point.hpp"

namespace subslip::fe {

// Abaqus component a is Mandel component kMandelOf[a]; its tensor indices are kIndices[a].
inline constexpr std::array<int, 6> kMandelOf = {0, 1, 2, 5, 4, 3};
inline constexpr std::array<std::array<int, 2>, 6> kIndices = {
    {{0, 0}, {1, 1}, {2, 2}, {0, 1}, {0, 2}, {1, 2}}};

// The Mandel entry of a component over its Abaqus stress (and of an engineering strain over
// the Mandel entry): 1 for normal components, sqrt2 for shears.
inline double shear_scale(int a) {
  return a < 3 ? 1.0 : std::numbers::sqrt2;
}

// STRESS(1..ntens) of a symmetric tensor given as a Mandel vector.
inline void to_abaqus_stress(const point::Mandel6& m, int ntens, double* stress) {
  const Eigen::Matrix3d t = crystal::symmetric_from_mandel(m);
  for (int a = 0; a < ntens; ++a) stress[a] = t(kIndices[a][0], kIndices[a][1]);
}

// The strain increment tensor of DSTRAN(1..ntens) (engineering shears; the others zero).
inline Eigen::Matrix3d strain_from_abaqus(const double* dstran, int ntens) {
  Eigen::Matrix3d e = Eigen::Matrix3d::Zero();
  for (int a = 0; a < ntens; ++a) {
    const auto [i, j] = kIndices[a];
    const double v = a < 3 ? dstran[a] : 0.5 * dstran[a];
    e(i, j) = v;
    e(j, i) = v;
  }
  return e;
}

// DDSDDE (column major, ntens x ntens): d STRESS(i) / d DSTRAN(j) of a Mandel tangent
// d sigma / d eps.
inline void to_abaqus_tangent(const point::Matrix6& t, int ntens, double* ddsdde) {
  for (int j = 0; j < ntens; ++j)
    for (int i = 0; i < ntens; ++i)
      ddsdde[i + ntens * j] = t(kMandelOf[i], kMandelOf[j]) / (shear_scale(i) * shear_scale(j));
}

}  // namespace subslip::fe
