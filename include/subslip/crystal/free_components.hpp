// The stress-controlled (free) components of the macroscopic velocity gradient in mixed control.
// Shared by the Taylor aggregate and the CVODE peer, so that both read a load segment's `free`
// mask the same way.
#pragma once

#include <vector>

#include "subslip/crystal/aggregate.hpp"

namespace subslip::crystal {

// One free component of the prescribed rate (L_ij or dot_F_ij). Under a Cauchy stress target,
// L_ij and L_ji both free are one unknown, D_ij (no spin): the symmetric stress gives one
// condition for the two. Under P each is its own unknown.
struct FreeComponent {
  int i, j;
  bool symmetric_pair;
  // dL/du: the velocity gradient this unknown adds per unit.
  Mat3 direction() const {
    Mat3 e = Mat3::Zero();
    e(i, j) = 1.0;
    if (symmetric_pair) e(j, i) = 1.0;
    return e;
  }
};

// The unknowns of a mask, in a fixed order (row by row, upper triangle first for pairs);
// `pair`: whether a free ij and ji are one symmetric unknown (a Cauchy stress target).
inline std::vector<FreeComponent> free_components(const Mask3& free, bool pair = true) {
  std::vector<FreeComponent> out;
  for (int i = 0; i < 3; ++i) {
    if (free(i, i)) out.push_back({i, i, false});
    for (int j = i + 1; j < 3; ++j) {
      if (pair && free(i, j) && free(j, i)) {
        out.push_back({i, j, true});
      } else {
        if (free(i, j)) out.push_back({i, j, false});
        if (free(j, i)) out.push_back({j, i, false});
      }
    }
  }
  return out;
}

// The unknowns of a segment's mask: paired only under a Cauchy stress target.
inline std::vector<FreeComponent> free_components(const LoadSegment& seg) {
  return free_components(seg.free, seg.stress_measure == StressMeasure::cauchy);
}

}  // namespace subslip::crystal
