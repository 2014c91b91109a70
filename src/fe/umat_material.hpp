// The point of a UMAT material, made from its PROPS (subslip/fe/umat_layout.h), and a grain's
// state as STATEV holds it.
#pragma once

#include <memory>
#include <vector>

#include "subslip/material_point.hpp"

namespace subslip::fe {

struct UmatMaterial {
  bool taylor = false;
  bool finite_strain = false;                     // the step from DFGRD0, DFGRD1 (else from DSTRAN)
  std::unique_ptr<point::GrainPoint> grain;       // single crystal
  std::unique_ptr<point::TaylorPoint> aggregate;  // Taylor
  std::vector<Eigen::Matrix3d> orientations;      // every grain's initial g
  std::vector<double> weights;                    // normalised
  point::Matrix6 lattice_stiffness;               // Mandel, lattice frame
  point::Matrix6 lattice_compliance;              // its inverse
  // Per slip system (the grain's order): the Schmid tensor sym(s m) (Mandel, lattice frame),
  // tau0 [stress], and whether its law has an overstress (every form but rate_independent).
  std::vector<point::Mandel6> schmid;
  std::vector<double> tau0;
  std::vector<bool> viscous;
  int slip_count = 0;
  int statev_count = 0;

  const point::GrainPoint& grain_point() const { return taylor ? aggregate->grain() : *grain; }
};

// Throws std::invalid_argument naming the PROPS entry at fault.
UmatMaterial make_umat_material(const double* props, int nprops);

int grain_block(int slip_count);
// Grain `block` of STATEV (0-based pointer to its first entry) <-> a grain state.
point::GrainState unpack_grain(const double* block, int slip_count);
void pack_grain(const point::GrainState& s, double* block);

}  // namespace subslip::fe
