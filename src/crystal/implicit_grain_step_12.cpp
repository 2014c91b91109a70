// The implicit grain step for 12 slip systems (one translation unit per slip count, see
// implicit_grain_step.hpp).
#include "implicit_grain_step.hpp"

namespace subslip::crystal {

template GrainStepReport implicit_grain_step<12>(const Phase<12>&, const GrainState<12>&,
                                                 const Mat3&, double, const GrainStepOptions&,
                                                 GrainState<12>&, Tangent*,
                                                 const SlipTypes<12>::VecN*, SlipTangent<12>*);

}  // namespace subslip::crystal
