// Scalar measures derived from the stored state of a crystal run: von Mises stress and strain,
// the accumulated equivalent plastic strain of a grain from its slips, and the slip activity of
// an aggregate. The one implementation of these formulas: the run summary, `subslip post` and
// the Python package (through subslip._core) all call these, so that they cannot disagree.
//
// Array arguments are flat, row-major, as a result file stores them: tensors [..., 3, 3] with
// [..., i, j] the component ij, per-grain series [row, grain, k].
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <span>
#include <vector>

namespace subslip::crystal {

// The first Piola-Kirchhoff stress P = J sigma F^-T (J = det F) of the Cauchy stress sigma
// at the deformation gradient F: force per reference area, the stress a dot_F/P load case
// prescribes.
Eigen::Matrix3d first_piola_stress(const Eigen::Matrix3d& cauchy, const Eigen::Matrix3d& f);

// sqrt(3/2 s:s), s the deviator of the symmetric part: equals |sigma| for uniaxial stress.
double von_mises_stress(const Eigen::Matrix3d& stress);
// sqrt(2/3 e:e), e the deviator of the symmetric part: equals |eps| for isochoric uniaxial
// strain (lateral -eps/2).
double von_mises_strain(const Eigen::Matrix3d& strain);

// The measures of every tensor of `tensors` (a multiple of 9 values), one value each.
std::vector<double> von_mises_stress(std::span<const double> tensors);
std::vector<double> von_mises_strain(std::span<const double> tensors);

// Accumulated von Mises equivalent plastic strain [rows * grains] of accumulated signed slips
// `slip` [rows, grains, N] with the slip systems `systems` [N, 6] (slip direction s, plane
// normal m, lattice frame): the sum over rows of sqrt(2/3 dE:dE), dE = sum_a dgamma_a
// sym(s_a (x) m_a), dgamma the change of slip since the previous row; row 0 (the initial state)
// is 0. The measure is invariant under rotation, so the lattice-frame systems serve every grain
// and row; it is exact while no system reverses between two rows.
std::vector<double> equivalent_plastic_strain(std::span<const double> slip, std::size_t rows,
                                              std::size_t grains, std::span<const double> systems);

// sum_g w_g |values[row, g, k]| / sum_g w_g: [rows, grains, k] -> [rows, k]; the slip activity
// of an aggregate from its grains' slip rates (or, with k = 1, any per-grain measure's weighted
// mean, without the absolute value mattering for a measure >= 0).
std::vector<double> weighted_mean_abs(std::span<const double> values, std::size_t rows,
                                      std::size_t grains, std::span<const double> weights);

}  // namespace subslip::crystal
