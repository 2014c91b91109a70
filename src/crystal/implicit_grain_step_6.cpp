// The implicit grain step for 6 slip systems (one translation unit per slip count, see
// implicit_grain_step.hpp).
#include "implicit_grain_step.hpp"

namespace subslip::crystal {

template GrainStepReport implicit_grain_step<6>(const Phase<6>&, const GrainState<6>&, const Mat3&,
                                                double, const GrainStepOptions&, GrainState<6>&,
                                                Tangent*, const SlipTypes<6>::VecN*,
                                                SlipTangent<6>*);

}  // namespace subslip::crystal
