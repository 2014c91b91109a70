// One increment of the grains of a UMAT material (a single crystal or a Taylor aggregate) from
// their state in the UMAT's STATEV layout: what umat_ and the MGIS behaviour share.
#pragma once

#include <Eigen/Core>
#include <memory>

#include "umat_material.hpp"

namespace subslip::fe {

// The increment's kinematics: the grains take the constant velocity gradient `l` over dt,
// then turn rigidly by `rotation` (the identity for small strain). At finite strain `l` is
// log(U) / dt of the relative deformation F1 F0^-1 = R U, U = V diag(stretch) V^T.
struct Kinematics {
  Eigen::Matrix3d l = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d stretch = Eigen::Vector3d::Ones();           // principal stretches of U
  Eigen::Matrix3d stretch_axes = Eigen::Matrix3d::Identity();  // V: their directions
  bool finite = false;  // from deformation gradients (the tangent is then d sigma1 / d eps)
  bool none = true;     // no deformation at all over the increment
};

// Small strain: D = strain increment / dt, no spin.
Kinematics small_strain_kinematics(const Eigen::Matrix3d& strain_increment, double dt);
// Finite strain from the deformation gradients at the increment's start and end.
Kinematics finite_strain_kinematics(const Eigen::Matrix3d& f0, const Eigen::Matrix3d& f1,
                                    double dt);

// The material of these PROPS (made once per distinct PROPS, shared by every thread).
std::shared_ptr<const UmatMaterial> umat_material(const double* props, int nprops);

// Energies per unit volume (the grains' weighted sum) [stress]: `elastic` at the increment's end
// (1/2 sigma : C^-1 : sigma of the lattice stress), `plastic` and `viscous` the increment's
// dissipation, split on each slip system into the static resistance (r_s mu tau0) and the
// overstress above it; plastic + viscous = sum_a (tau_a(0) + tau_a(1)) / 2 dgamma_a.
struct IncrementEnergies {
  double elastic = 0.0;
  double plastic = 0.0;
  double viscous = 0.0;
};

struct GrainIncrement {
  point::Mandel6 stress;  // Cauchy, sample frame at the increment's end
  // Mandel, that frame. Small strain: d stress / d (strain increment). Finite strain: the
  // derivative under F1 -> (I + d eps) F1 with d eps symmetric (a variation of F1 whose spin
  // part only turns the stress with it), the exact derivative of the finite increment.
  point::Matrix6 tangent;
  IncrementEnergies energies;
};

// One increment from the state in `statev` (the UMAT layout, m.statev_count entries; a marker 0
// starts from the virgin state). On success `statev` holds the new state; otherwise it throws
// naming the cause and `statev` is untouched. An increment of no time must have no deformation
// (the law is rate dependent) and gives the elastic stiffness.
GrainIncrement grain_increment(const UmatMaterial& m, double* statev, const Kinematics& k,
                               double dt);

}  // namespace subslip::fe
