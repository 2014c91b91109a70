// Linear elasticity of crystals in Mandel notation.
//
// MANDEL ORDER: a symmetric tensor T is the 6-vector
//
//     [T11, T22, T33, sqrt2 T23, sqrt2 T13, sqrt2 T12]      (11, 22, 33, 23, 13, 12)
//
// and a stiffness C (sigma = C : eps) the 6x6 matrix with C_M(i,j) = w_i w_j C_Voigt(i,j),
// w = (1, 1, 1, sqrt2, sqrt2, sqrt2). The basis is orthonormal, so double contractions are plain
// dot products (A : B = a . b), sigma = C_M eps, and rotations are orthogonal 6x6 matrices. Note
// C_M(4,4) = 2 C44 and, for a shear strain eps23, the vector entry is sqrt2 eps23 (not the
// engineering gamma23 = 2 eps23 of Voigt).
//
// Crystal stiffnesses are given in the LATTICE frame: cubic with the cube axes along x, y, z;
// hexagonal with the c axis along z (a1 along x, as in slip_systems.hpp). To express one in the
// sample frame use stiffness_in_sample_frame(C, g) with the orientation g of rotation.hpp.
//
// Constructors check positive definiteness and throw std::invalid_argument naming the constants
// and the conditions they violate (the scene reader adds file and line).
#pragma once

#include <Eigen/Core>

namespace subslip::crystal {

using MandelVector = Eigen::Matrix<double, 6, 1>;
using MandelMatrix = Eigen::Matrix<double, 6, 6>;

// The symmetric part of t, as a Mandel vector.
MandelVector mandel_from_symmetric(const Eigen::Matrix3d& t);
Eigen::Matrix3d symmetric_from_mandel(const MandelVector& v);

// Voigt stiffness (C44 = sigma23 / gamma23 convention of data tables) <-> Mandel stiffness.
MandelMatrix mandel_from_voigt_stiffness(const MandelMatrix& voigt);
MandelMatrix voigt_from_mandel_stiffness(const MandelMatrix& mandel);

// The orthogonal 6x6 Q with mandel(R T R^T) = Q mandel(T) for every symmetric T.
MandelMatrix mandel_rotation_operator(const Eigen::Matrix3d& R);
// Components of the stiffness after the change of components T -> R T R^T: Q C Q^T.
MandelMatrix rotate_stiffness(const MandelMatrix& C, const Eigen::Matrix3d& R);
// Lattice-frame stiffness -> sample frame for the orientation g (v_crystal = g v_sample):
// T_sample = g^T T_crystal g, so this is rotate_stiffness(C, g^T).
MandelMatrix stiffness_in_sample_frame(const MandelMatrix& C_lattice, const Eigen::Matrix3d& g);

// Isotropic stiffness C = lambda 1(x)1 + 2 G I in its various parametrisations.
MandelMatrix isotropic_from_E_nu(double E, double nu);
MandelMatrix isotropic_from_G_nu(double G, double nu);
MandelMatrix isotropic_from_lambda_G(double lambda, double G);
MandelMatrix isotropic_from_K_G(double K, double G);

// Cubic (cube axes along x, y, z); constants in Voigt convention as tabulated.
MandelMatrix cubic_stiffness(double C11, double C12, double C44);
// Transversely isotropic / hexagonal with the c axis along z; C66 = (C11 - C12) / 2.
MandelMatrix hexagonal_stiffness(double C11, double C12, double C13, double C33, double C44);

// Zener anisotropy ratio 2 C44 / (C11 - C12): 1 for an isotropic cubic crystal.
double zener_ratio(double C11, double C12, double C44);

// Smallest eigenvalue of the (symmetric part of the) Mandel matrix: > 0 iff positive definite.
double smallest_eigenvalue(const MandelMatrix& C);

}  // namespace subslip::crystal
