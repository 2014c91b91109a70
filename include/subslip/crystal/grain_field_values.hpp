// A per-grain output field (grain_fields_table.hpp) taken from the aggregate's GrainFields:
// the one switch from a field to the call that gives it, for the writer and the gathering.
#pragma once

#include "subslip/crystal/aggregate.hpp"
#include "subslip/crystal/grain_fields_table.hpp"

namespace subslip::crystal {

// Writes [grains x given_width(f)] values of `f` (row-major) into `out`.
inline void give(const GrainFields& g, GrainField f, double* out) {
  switch (f) {
    case GrainField::stress:
      return g.stress(out);
    case GrainField::orientation:
      return g.orientation(out);
    case GrainField::slip:
      return g.slip(out);
    case GrainField::slip_rate:
      return g.slip_rate(out);
    case GrainField::crss:
      return g.crss(out);
    case GrainField::r:
      return g.ratio(out);
    case GrainField::r_s:
      return g.subloading_ratio(out);
  }
}

}  // namespace subslip::crystal
