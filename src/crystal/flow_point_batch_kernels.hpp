#pragma once
// The batched flow-point kernels as templates over an xsimd architecture. Each translation unit
// that includes this header instantiates them for one instruction set: flow_point_batch.cpp for
// the build's own (SSE2 in the portable build), flow_point_batch_avx2.cpp and
// flow_point_batch_avx512.cpp for the wider sets, compiled with their own flags and chosen at
// run time (flow_point_batch.cpp). The templates live in an unnamed namespace, so no function
// compiled for a wider set can stand in, through the linker's choice among identical inline
// definitions, for code that runs on a machine without it; the closed-form templates they call
// are instantiated with the architecture's batch type, a name of their own.
#include <xsimd/xsimd.hpp>

#include <limits>

#include "subslip/crystal/flow_point_batch.hpp"
#include "subslip/law/closed_form.hpp"

namespace subslip::crystal::detail {
namespace {

template <class Arch>
void subloading_starts_for(double u_tilde, int count, SubloadingStartBatch& s) {
  using Batch = xsimd::batch<double, Arch>;
  static_assert(kFlowBatchCapacity % Batch::size == 0, "the arrays hold whole batches");
  for (int a = 0; a < count; a += static_cast<int>(Batch::size)) {
    const auto start =
        law::closed_form::cot_subloading_start(u_tilde, Batch::load_aligned(s.r0.data() + a));
    start.cos0.store_aligned(s.cos0.data() + a);
    start.one_minus_cos0.store_aligned(s.one_minus_cos0.data() + a);
    start.rate0.store_aligned(s.rate0.data() + a);
  }
}

template <class Arch>
void flow_points_for(const law::LawParameters& p, double dt, double latent_self, int count,
                     const FlowBatchInput& in, FlowBatchOutput& out) {
  namespace cf = law::closed_form;
  using Batch = xsimd::batch<double, Arch>;
  static_assert(kFlowBatchCapacity % Batch::size == 0, "the arrays hold whole batches");
  const double inf = std::numeric_limits<double>::infinity();
  // Lanes past `count` compute on whatever the arrays hold there; their results are not read.
  for (int a = 0; a < count; a += static_cast<int>(Batch::size)) {
    auto load = [a](const FlowBatchArray& v) { return Batch::load_aligned(v.data() + a); };
    const Batch slip = load(in.slip);
    const auto mu =
        cf::friction_coefficient_after(p.friction, load(in.mu0), load(in.effective), dt);
    const auto r_s =
        cf::cot_subloading_ratio_after(p.subloading.u_tilde, load(in.r0), load(in.cos0),
                                       load(in.one_minus_cos0), load(in.rate0), slip);
    // r, dr/d|tau| and r/mu from one quotient (see StressSolver::flow_point).
    const Batch normal = load(in.normal);
    const Batch per_traction = 1.0 / (mu.value * normal);
    const Batch r = load(in.shear) * per_traction;
    const Batch r_per_mu = r * (per_traction * normal);
    const auto g = cf::exponential_flow_residual(p.overstress, r, r_s.value, slip, dt);
    // dG/d ds through r (hardening: dr/d ds = -r/mu dmu/d ds, q of it the system's own slip),
    // through r_s (dG/dr_s = -1) and the overstress term.
    const Batch g_slip = g.d_r * (-r_per_mu * mu.slope * latent_self) - r_s.slope + g.d_slip;
    // The Newton coefficients in the order of the solver's scalar path, so each rounds as there.
    const Batch inverse_slope = 1.0 / (-g_slip);
    (g.value * inverse_slope).store_aligned(out.newton_w.data() + a);
    (g.d_r * per_traction * inverse_slope).store_aligned(out.newton_d.data() + a);
    (g.d_r * (-r_per_mu) * mu.slope * inverse_slope).store_aligned(out.newton_l.data() + a);
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

}  // namespace

// The kernels of the wider instruction sets (defined only in an x86-64 build).
void subloading_starts_avx2(double u_tilde, int count, SubloadingStartBatch& s);
void flow_points_avx2(const law::LawParameters& p, double dt, double latent_self, int count,
                      const FlowBatchInput& in, FlowBatchOutput& out);
void subloading_starts_avx512(double u_tilde, int count, SubloadingStartBatch& s);
void flow_points_avx512(const law::LawParameters& p, double dt, double latent_self, int count,
                        const FlowBatchInput& in, FlowBatchOutput& out);

}  // namespace subslip::crystal::detail
