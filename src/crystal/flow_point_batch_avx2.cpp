// The batched flow-point kernels for AVX2 with FMA (4 doubles), compiled with that instruction
// set's flags (src/CMakeLists.txt) and called only where the machine has it (flow_point_batch.cpp).
#include "flow_point_batch_kernels.hpp"

namespace subslip::crystal::detail {

void subloading_starts_avx2(double u_tilde, int count, SubloadingStartBatch& s) {
  subloading_starts_for<xsimd::fma3<xsimd::avx2>>(u_tilde, count, s);
}

void flow_points_avx2(const law::LawParameters& p, double dt, double latent_self, int count,
                      const FlowBatchInput& in, FlowBatchOutput& out) {
  flow_points_for<xsimd::fma3<xsimd::avx2>>(p, dt, latent_self, count, in, out);
}

}  // namespace subslip::crystal::detail
