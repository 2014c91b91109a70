#include "subslip/crystal/flow_point_batch.hpp"

#include <xsimd/xsimd.hpp>

#include <algorithm>
#include <limits>

#include "subslip/law/closed_form.hpp"

namespace subslip::crystal::detail {

namespace {
using Batch = xsimd::batch<double>;
constexpr int kWidth = static_cast<int>(Batch::size);
static_assert(kFlowBatchCapacity % kWidth == 0, "the arrays hold whole batches");
}  // namespace

bool flow_batches_pay() {
  return kWidth >= 4;
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
  const int end = std::min((count + 7) / 8 * 8, kFlowBatchCapacity);
  for (FlowBatchArray* v : {&in.mu0, &in.slip, &in.effective, &in.r0, &in.cos0, &in.one_minus_cos0,
                            &in.rate0, &in.shear, &in.normal})
    std::fill(v->begin() + count, v->begin() + end, 0.0);
}

void batched_flow_points(const law::LawParameters& p, double dt, double latent_self, int count,
                         const FlowBatchInput& in, FlowBatchOutput& out) {
  namespace cf = law::closed_form;
  const double inf = std::numeric_limits<double>::infinity();
  // Lanes past `count` compute on whatever the arrays hold there; their results are not read.
  for (int a = 0; a < count; a += kWidth) {
    auto load = [a](const FlowBatchArray& v) { return Batch::load_aligned(v.data() + a); };
    const Batch slip = load(in.slip);
    const auto mu =
        cf::friction_coefficient_after(p.friction, load(in.mu0), load(in.effective), dt);
    const auto r_s =
        cf::cot_subloading_ratio_after(p.subloading.u_tilde, load(in.r0), load(in.cos0),
                                       load(in.one_minus_cos0), load(in.rate0), slip);
    const Batch r = load(in.shear) / (mu.value * load(in.normal));
    const auto g = cf::exponential_flow_residual(p.overstress, r, r_s.value, slip, dt);
    // dG/d ds through r (hardening: dr/d ds = -r/mu dmu/d ds, q of it the system's own slip),
    // through r_s (dG/dr_s = -1) and the overstress term.
    const Batch g_slip = g.d_r * (-r / mu.value * mu.slope * latent_self) - r_s.slope + g.d_slip;
    const auto outside = !(r < p.overstress.r_hat) || !(mu.value > 0.0);
    xsimd::select(outside, Batch(inf), g.value).store_aligned(out.g.data() + a);
    g_slip.store_aligned(out.g_slip.data() + a);
    g.d_r.store_aligned(out.g_r.data() + a);
    r.store_aligned(out.r.data() + a);
    mu.slope.store_aligned(out.mu_slope.data() + a);
    mu.value.store_aligned(out.mu.data() + a);
    r_s.value.store_aligned(out.r_s.data() + a);
  }
}

}  // namespace subslip::crystal::detail
