// Prints the widest instruction set of the grain step's wide builds that this machine runs
// (src/CMakeLists.txt, SUBSLIP_GRAIN_STEP_ISA=host): avx512, avx2 or none. The tests are those
// of the run-time choice (src/crystal/flow_point_batch.cpp, flow_batch_isa_available).
#include <cstdio>

int main() {
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512cd") &&
      __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512bw"))
    std::puts("avx512");
  else if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"))
    std::puts("avx2");
  else
    std::puts("none");
  return 0;
}
