// The implicit grain step for a runtime slip count (one translation unit per slip count, see
// implicit_grain_step.hpp).
#include "implicit_grain_step.hpp"

namespace subslip::crystal {

template GrainStepReport implicit_grain_step<Eigen::Dynamic>(
    const Phase<Eigen::Dynamic>&, const GrainState<Eigen::Dynamic>&, const Mat3&, double,
    const GrainStepOptions&, GrainState<Eigen::Dynamic>&, Tangent*,
    const SlipTypes<Eigen::Dynamic>::VecN*, SlipTangent<Eigen::Dynamic>*);

}  // namespace subslip::crystal
