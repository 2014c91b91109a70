// The implicit grain step for 1 slip system (one translation unit per slip count, see
// implicit_grain_step.hpp).
#include "implicit_grain_step.hpp"

namespace subslip::crystal {

template GrainStepReport implicit_grain_step<1>(const Phase<1>&, const GrainState<1>&, const Mat3&,
                                                double, const GrainStepOptions&, GrainState<1>&,
                                                Tangent*, const SlipTypes<1>::VecN*,
                                                SlipTangent<1>*);

}  // namespace subslip::crystal
