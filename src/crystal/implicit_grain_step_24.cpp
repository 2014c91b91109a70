// The implicit grain step for 24 slip systems (one translation unit per slip count, see
// implicit_grain_step.hpp).
#include "implicit_grain_step.hpp"

namespace subslip::crystal {

template GrainStepReport implicit_grain_step<24>(const Phase<24>&, const GrainState<24>&,
                                                 const Mat3&, double, const GrainStepOptions&,
                                                 GrainState<24>&, Tangent*,
                                                 const SlipTypes<24>::VecN*, SlipTangent<24>*);

}  // namespace subslip::crystal
