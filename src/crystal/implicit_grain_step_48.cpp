// The implicit grain step for 48 slip systems (one translation unit per slip count, see
// implicit_grain_step.hpp).
// Compiled for AVX2 and AVX-512 too, each under a name of its own (grain_step_isa.hpp).
#include "implicit_grain_step.hpp"

namespace subslip::crystal {

#ifdef SUBSLIP_GRAIN_STEP_ISA
namespace SUBSLIP_GRAIN_STEP_ISA {
#endif
template GrainStepReport implicit_grain_step<48>(const Phase<48>&, const GrainState<48>&,
                                                 const Mat3&, double, const GrainStepOptions&,
                                                 GrainState<48>&, Tangent*,
                                                 const SlipTypes<48>::VecN*, SlipTangent<48>*);
#ifdef SUBSLIP_GRAIN_STEP_ISA
}  // namespace SUBSLIP_GRAIN_STEP_ISA
#endif

}  // namespace subslip::crystal
