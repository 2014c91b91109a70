// The implicit grain step for 24 slip systems (one translation unit per slip count, see
// implicit_grain_step.hpp).
// Compiled for AVX2 and AVX-512 too, each under a name of its own (grain_step_isa.hpp).
#include "implicit_grain_step.hpp"

namespace subslip::crystal {

#ifdef SUBSLIP_GRAIN_STEP_ISA
namespace SUBSLIP_GRAIN_STEP_ISA {
#endif
template GrainStepReport implicit_grain_step<24>(const Phase<24>&, const GrainState<24>&,
                                                 const Mat3&, double, const GrainStepOptions&,
                                                 GrainState<24>&, Tangent*,
                                                 const SlipTypes<24>::VecN*, SlipTangent<24>*);
#ifdef SUBSLIP_GRAIN_STEP_ISA
}  // namespace SUBSLIP_GRAIN_STEP_ISA
#endif

}  // namespace subslip::crystal
