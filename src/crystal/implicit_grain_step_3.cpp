// The implicit grain step for 3 slip systems (one translation unit per slip count, see
// implicit_grain_step.hpp).
#include "implicit_grain_step.hpp"

namespace subslip::crystal {

template GrainStepReport implicit_grain_step<3>(const Phase<3>&, const GrainState<3>&, const Mat3&,
                                                double, const GrainStepOptions&, GrainState<3>&,
                                                Tangent*, const SlipTypes<3>::VecN*,
                                                SlipTangent<3>*);

}  // namespace subslip::crystal
