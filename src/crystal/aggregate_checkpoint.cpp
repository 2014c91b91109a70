// The grains' part of the Taylor aggregate's checkpoint (AggregateCheckpoint::grains): per grain
// the committed state and its slip-rate history, packed and restored.
#include "grain_sweep.hpp"

#include <algorithm>

namespace subslip::crystal::aggregate_parts {

template <int N>
void GrainSweep<N>::pack(double* out) const {
  const int n = phase_.slip_count;
  for (size_t k = 0; k < committed_.size(); ++k) {
    const auto& g = committed_[k];
    out = std::copy(g.stress.data(), g.stress.data() + 6, out);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) *out++ = g.orientation(i, j);
    for (const auto* v :
         {&g.mu, &g.r_s, &g.slip, &g.rate, &history_[k].trend, &history_[k].trend_change})
      out = std::copy(v->data(), v->data() + n, out);
  }
}

template <int N>
void GrainSweep<N>::unpack(const double* in) {
  const int n = phase_.slip_count;
  for (size_t k = 0; k < committed_.size(); ++k) {
    auto& g = committed_[k];
    std::copy(in, in + 6, g.stress.data());
    in += 6;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) g.orientation(i, j) = *in++;
    for (auto* v :
         {&g.mu, &g.r_s, &g.slip, &g.rate, &history_[k].trend, &history_[k].trend_change}) {
      std::copy(in, in + n, v->data());
      in += n;
    }
  }
}

#define SUBSLIP_INSTANTIATE_GRAIN_CHECKPOINT(N)     \
  template void GrainSweep<N>::pack(double*) const; \
  template void GrainSweep<N>::unpack(const double*);

SUBSLIP_FOR_EACH_SLIP_COUNT(SUBSLIP_INSTANTIATE_GRAIN_CHECKPOINT)

}  // namespace subslip::crystal::aggregate_parts
