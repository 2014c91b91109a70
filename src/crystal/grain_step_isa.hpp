// The grain step compiled for wider instruction sets than the build's own.
//
// The x86-64 build (SSE2) also compiles the grain step of the commonest slip counts (12: FCC,
// BCC {110}; 24: HCP; 48: BCC) for AVX2 with FMA and for AVX-512, from the same sources
// (implicit_grain_step_<N>.cpp compiled with SUBSLIP_GRAIN_STEP_ISA=isa_avx2 or isa_avx512).
// Which, src/CMakeLists.txt's SUBSLIP_GRAIN_STEP_ISA says:
// * host (the default of a source build): the widest set the building machine runs, alone
//   (SUBSLIP_GRAIN_STEP_PORTABLE = 0): implicit_grain_step<N> is that step, and the binary stops
//   with a message on a machine without the set (require_grain_step_isa);
// * all: both sets beside the portable step; implicit_grain_step<N> calls the widest the machine
//   runs and the run allows (the flow batches' level, flow_point_batch.hpp);
// * none, and native builds (-march=native): the build's own step alone.
//
// Two hazards of mixing instruction sets in one program, and what keeps them away:
// * One definition: an inline function of a header (Eigen's, the standard library's, ours)
//   compiled in a wide object is one of several identical definitions, and the linker may keep
//   the wide one for every caller. The wide objects are therefore linked into one relocatable
//   object each with every symbol but their own entry points made local (src/CMakeLists.txt:
//   `ld -r`, `objcopy --keep-global-symbol`); tests/check_isa_objects.sh checks what they export.
// * Layout: Eigen aligns its fixed-size objects to the widest vector it compiles for (64 bytes
//   with AVX-512), which would give Phase<N> and GrainState<N> another layout in the wide objects
//   than in the rest of the program, and frees memory with another allocator convention. The
//   wide objects are compiled with Eigen's alignment limited to the portable build's 16 bytes
//   (EIGEN_MAX_ALIGN_BYTES=16), and both sides assert it below.
#pragma once

#include <Eigen/Core>

#include "subslip/crystal/crystal_kernel.hpp"

namespace subslip::crystal {

#ifndef SUBSLIP_GRAIN_STEP_ISAS
#define SUBSLIP_GRAIN_STEP_ISAS 0
#endif
#ifndef SUBSLIP_GRAIN_STEP_AVX2
#define SUBSLIP_GRAIN_STEP_AVX2 SUBSLIP_GRAIN_STEP_ISAS
#endif
#ifndef SUBSLIP_GRAIN_STEP_AVX512
#define SUBSLIP_GRAIN_STEP_AVX512 SUBSLIP_GRAIN_STEP_ISAS
#endif
#ifndef SUBSLIP_GRAIN_STEP_PORTABLE
#define SUBSLIP_GRAIN_STEP_PORTABLE 1
#endif

// Whether the build has the grain step of N slip systems for AVX2 and AVX-512 too.
constexpr bool has_isa_grain_steps(int n) {
  return SUBSLIP_GRAIN_STEP_ISAS && (n == 12 || n == 24 || n == 48);
}

#if SUBSLIP_GRAIN_STEP_ISAS
static_assert(EIGEN_MAX_ALIGN_BYTES == 16 && EIGEN_MAX_STATIC_ALIGN_BYTES == 16,
              "the grain steps of several instruction sets share Eigen's 16-byte layout");

#define SUBSLIP_DECLARE_ISA_GRAIN_STEP(isa)                                                       \
  namespace isa {                                                                                 \
  template <int N>                                                                                \
  GrainStepReport implicit_grain_step(const Phase<N>& ph, const GrainState<N>& s0, const Mat3& L, \
                                      double dt, const GrainStepOptions& opt, GrainState<N>& s1,  \
                                      Tangent* tangent,                                           \
                                      const typename SlipTypes<N>::VecN* start_rate,              \
                                      SlipTangent<N>* slip_tangent);                              \
  }
SUBSLIP_DECLARE_ISA_GRAIN_STEP(isa_avx2)
SUBSLIP_DECLARE_ISA_GRAIN_STEP(isa_avx512)
#undef SUBSLIP_DECLARE_ISA_GRAIN_STEP
#endif

}  // namespace subslip::crystal
