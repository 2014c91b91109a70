#include "subslip/crystal/flow_point_batch.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <stdexcept>
#include <string>
#include <string_view>

#include "flow_point_batch_kernels.hpp"

namespace subslip::crystal::detail {
namespace {

using SubloadingStartsKernel = void (*)(double, int, SubloadingStartBatch&);
using FlowPointsKernel = void (*)(const law::LawParameters&, double, double, int,
                                  const FlowBatchInput&, FlowBatchOutput&);
struct IsaKernels {
  SubloadingStartsKernel subloading_starts;
  FlowPointsKernel flow_points;
  int width;  // doubles per batch
};

IsaKernels kernels_of(FlowBatchIsa isa) {
  switch (isa) {
#if SUBSLIP_FLOW_BATCH_X86
    case FlowBatchIsa::avx512:
      return {&subloading_starts_avx512, &flow_points_avx512, 8};
    case FlowBatchIsa::avx2:
      return {&subloading_starts_avx2, &flow_points_avx2, 4};
#endif
    default:
      return {&subloading_starts_for<xsimd::default_arch>, &flow_points_for<xsimd::default_arch>,
              static_cast<int>(xsimd::batch<double>::size)};
  }
}

// The widest instruction set this machine runs (the CPU has it and the operating system saves
// its registers: GCC's __builtin_cpu_supports checks both).
FlowBatchIsa widest_available() {
  for (FlowBatchIsa isa : {FlowBatchIsa::avx512, FlowBatchIsa::avx2})
    if (flow_batch_isa_available(isa)) return isa;
  return FlowBatchIsa::build;
}

// The widest level of batches the run allows (limit_flow_batches): 2 every set, 1 up to AVX2,
// 0 none.
std::atomic<int> allowed_level{2};

// The instruction set the solver takes: the widest this machine runs, within the allowed level.
FlowBatchIsa chosen_isa() {
  static const FlowBatchIsa widest = widest_available();
  if (widest == FlowBatchIsa::avx512 && allowed_level.load(std::memory_order_relaxed) < 2)
    return FlowBatchIsa::avx2;
  return widest;
}

const IsaKernels& chosen() {
  static const std::array<IsaKernels, 3> kernels{kernels_of(FlowBatchIsa::build),
                                                 kernels_of(FlowBatchIsa::avx2),
                                                 kernels_of(FlowBatchIsa::avx512)};
  return kernels[static_cast<size_t>(chosen_isa())];
}

}  // namespace

bool flow_batch_isa_available(FlowBatchIsa isa) {
  switch (isa) {
    case FlowBatchIsa::build:
      return true;
#if SUBSLIP_FLOW_BATCH_X86
    case FlowBatchIsa::avx2:
      __builtin_cpu_init();
      return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
    case FlowBatchIsa::avx512:
      __builtin_cpu_init();
      return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512cd") &&
             __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512bw");
#endif
    default:
      return false;
  }
}

int flow_batch_width() {
  return chosen().width;
}

bool flow_batches_pay() {
  return allowed_level.load(std::memory_order_relaxed) > 0 && chosen().width >= 4;
}

int flow_batch_level() {
  if (!flow_batches_pay()) return 0;
  return chosen().width >= 8 ? 2 : 1;
}

void limit_flow_batches(int level) {
  allowed_level.store(std::clamp(level, 0, 2), std::memory_order_relaxed);
}

const char* grain_step_isa_name() {
#if SUBSLIP_GRAIN_STEP_ISAS && !SUBSLIP_GRAIN_STEP_PORTABLE
  return SUBSLIP_GRAIN_STEP_AVX512 ? "avx512" : "avx2";
#elif SUBSLIP_GRAIN_STEP_ISAS
  switch (flow_batch_level()) {  // (the dispatch of implicit_grain_step.hpp)
    case 2:
      return "avx512";
    case 1:
      return "avx2";
    default:
      return "baseline";
  }
#else
  return std::string_view(SUBSLIP_BUILD) == "native" ? "native" : "baseline";
#endif
}

void require_grain_step_isa() {
#if SUBSLIP_GRAIN_STEP_ISAS && !SUBSLIP_GRAIN_STEP_PORTABLE
  const FlowBatchIsa isa = SUBSLIP_GRAIN_STEP_AVX512 ? FlowBatchIsa::avx512 : FlowBatchIsa::avx2;
  if (!flow_batch_isa_available(isa))
    throw std::runtime_error(
        std::string("this subslip was built for its building machine's ") + grain_step_isa_name() +
        ", which this machine does not run: build it here, or build a binary for any x86-64 "
        "machine with -DSUBSLIP_GRAIN_STEP_ISA=all");
#endif
}

const char* flow_batch_isa_name() {
  if (!flow_batches_pay()) return "none";
  switch (chosen_isa()) {
    case FlowBatchIsa::avx512:
      return "avx512";
    case FlowBatchIsa::avx2:
      return "avx2";
    default:
      return "native";  // a native build's own set, on a machine without AVX2
  }
}

bool has_batched_flow_points(const std::vector<law::SubloadingFrictionLaw>& laws, int count) {
  if (count < 1 || count > kMaxSlipSystems || laws.size() < static_cast<size_t>(count))
    return false;
  const law::LawParameters& p = laws.front().parameters();
  if (p.subloading.function != law::SubloadingFunction::cot ||
      p.overstress.form != law::OverstressForm::exponential)
    return false;
  for (int a = 1; a < count; ++a)
    if (!(laws[static_cast<size_t>(a)].parameters() == p)) return false;
  return true;
}

void clear_batch_padding(FlowBatchInput& in, int count) {
  // Only the lanes the chosen kernel's last batch reads (none where count fills whole batches,
  // as 12 systems do in AVX2's batches of 4).
  const int width = chosen().width;
  const int end = std::min((count + width - 1) / width * width, kFlowBatchCapacity);
  if (end == count) return;
  for (FlowBatchArray* v : {&in.mu0, &in.slip, &in.effective, &in.r0, &in.cos0, &in.one_minus_cos0,
                            &in.rate0, &in.shear, &in.normal})
    std::fill(v->begin() + count, v->begin() + end, 0.0);
}

void batched_subloading_starts(double u_tilde, int count, SubloadingStartBatch& s,
                               FlowBatchIsa isa) {
  kernels_of(isa).subloading_starts(u_tilde, count, s);
}
void batched_subloading_starts(double u_tilde, int count, SubloadingStartBatch& s) {
  chosen().subloading_starts(u_tilde, count, s);
}

void batched_flow_points(const law::LawParameters& p, double dt, double latent_self, int count,
                         const FlowBatchInput& in, FlowBatchOutput& out, FlowBatchIsa isa) {
  kernels_of(isa).flow_points(p, dt, latent_self, count, in, out);
}
void batched_flow_points(const law::LawParameters& p, double dt, double latent_self, int count,
                         const FlowBatchInput& in, FlowBatchOutput& out) {
  chosen().flow_points(p, dt, latent_self, count, in, out);
}

}  // namespace subslip::crystal::detail
