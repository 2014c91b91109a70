// The implicit grain step for 48 slip systems (one translation unit per slip count, see
// implicit_grain_step.hpp).
#include "implicit_grain_step.hpp"

namespace subslip::crystal {

template GrainStepReport implicit_grain_step<48>(const Phase<48>&, const GrainState<48>&,
                                                 const Mat3&, double, const GrainStepOptions&,
                                                 GrainState<48>&, Tangent*,
                                                 const SlipTypes<48>::VecN*, SlipTangent<48>*);

}  // namespace subslip::crystal
