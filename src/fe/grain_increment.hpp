// One increment of the grains of a UMAT material (a single crystal or a Taylor aggregate) from
// their state in the UMAT's STATEV layout: what umat_ and the MGIS behaviour share.
#pragma once

#include <Eigen/Core>
#include <memory>

#include "umat_material.hpp"

namespace subslip::fe {

// The increment's kinematics: the grains take the constant velocity gradient `l` over dt,
// then turn rigidly by `rotation` (the identity for small strain).
struct Kinematics {
  Eigen::Matrix3d l = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  bool none = true;  // no deformation at all over the increment
};

// Small strain: D = strain increment / dt, no spin.
Kinematics small_strain_kinematics(const Eigen::Matrix3d& strain_increment, double dt);
// Finite strain from the deformation gradients at the increment's start and end.
Kinematics finite_strain_kinematics(const Eigen::Matrix3d& f0, const Eigen::Matrix3d& f1,
                                    double dt);

// The material of these PROPS (made once per distinct PROPS, shared by every thread).
std::shared_ptr<const UmatMaterial> umat_material(const double* props, int nprops);

struct GrainIncrement {
  point::Mandel6 stress;   // Cauchy, sample frame at the increment's end
  point::Matrix6 tangent;  // d stress / d (strain increment), Mandel, that frame
};

// One increment from the state in `statev` (the UMAT layout, m.statev_count entries; a marker 0
// starts from the virgin state). On success `statev` holds the new state; otherwise it throws
// naming the cause and `statev` is untouched. An increment of no time must have no deformation
// (the law is rate dependent) and gives the elastic stiffness.
GrainIncrement grain_increment(const UmatMaterial& m, double* statev, const Kinematics& k,
                               double dt);

}  // namespace subslip::fe
