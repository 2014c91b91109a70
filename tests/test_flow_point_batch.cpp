// The grain solver's batched flow points (SIMD over slip systems) against the law evaluated
// system by system: the same G, slopes, mu and r_s to a few ulps, over the law's whole domain
// (virgin and saturated starts, no slip, series and closed-form hardening, cot updates to ratios
// near 1, points outside the flow rule), for every slip count up to the largest; and the batched
// subloading starts against the law's.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "copper_phase.hpp"
#include "crystal_law.hpp"
#include "subslip/crystal/flow_point_batch.hpp"
#include "subslip/law/closed_form.hpp"
#include "subslip/law/subloading_friction.hpp"

namespace subslip {
namespace {

using crystal::detail::FlowBatchInput;
using crystal::detail::FlowBatchIsa;
using crystal::detail::FlowBatchOutput;

struct Expected {
  double g, g_slip, g_r, r, mu_slope, mu, r_s;
};

// The scalar flow point of one system, composed from the law's own functions as the solver's
// system-by-system path composes it.
Expected scalar_flow_point(const law::SubloadingFrictionLaw& law, const FlowBatchInput& in, int a,
                           double q, double dt) {
  const auto i = static_cast<size_t>(a);
  const auto mu = law.friction_coefficient_after(in.mu0[i], in.effective[i], dt);
  const law::SubloadingFrictionLaw::SubloadingStart start{in.r0[i], in.cos0[i],
                                                          in.one_minus_cos0[i], 0.0, in.rate0[i]};
  const auto rs = law.subloading_ratio_after(start, in.slip[i]);
  const double r = in.shear[i] / (mu.value * in.normal[i]);
  const auto g = law.flow_residual(r, rs.value, in.slip[i], dt);
  if (!g.admissible || !(mu.value > 0.0))
    return {std::numeric_limits<double>::infinity(), 0, 0, r, 0, mu.value, rs.value};
  const double g_slip = g.d_r * (-r / mu.value * mu.d_slip * q) + g.d_rs * rs.d_slip + g.d_slip;
  return {g.value, g_slip, g.d_r, r, mu.d_slip, mu.value, rs.value};
}

// Random systems over the domain; a few lanes at each edge.
FlowBatchInput random_systems(const law::SubloadingFrictionLaw& law, int count, double q,
                              std::mt19937_64& rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  FlowBatchInput in{};
  for (int a = 0; a < count; ++a) {
    const auto i = static_cast<size_t>(a);
    const int kind = a % 8;
    const double r_s0 = kind == 0 ? 0.0 : kind == 1 ? 1.0 : unit(rng);
    const auto start = law.subloading_start(r_s0);
    in.r0[i] = start.r0, in.cos0[i] = start.cos0, in.one_minus_cos0[i] = start.one_minus_cos0;
    in.rate0[i] = start.rate0;
    // Slips from 1e-12 to 1 (|B| beyond the series' 1/16 and r1 past 2/3 at the large end),
    // none on some systems.
    in.slip[i] = kind == 2 ? 0.0 : std::pow(10.0, -12.0 + 12.0 * unit(rng));
    in.effective[i] = q * in.slip[i] + (kind == 3 ? 0.0 : 1e-3 * unit(rng));
    in.mu0[i] = 0.5 + 3.0 * unit(rng);
    in.normal[i] = 10.0;
    // Loading ratios up to 2.2: beyond r_hat = 1.8 on some systems (outside the flow rule).
    in.shear[i] = in.mu0[i] * in.normal[i] * 2.2 * unit(rng);
  }
  return in;
}

// Every instruction set this machine runs: each is checked, not only the one the solver takes.
std::vector<FlowBatchIsa> available_isas() {
  std::vector<FlowBatchIsa> isas;
  for (FlowBatchIsa isa : {FlowBatchIsa::build, FlowBatchIsa::avx2, FlowBatchIsa::avx512})
    if (crystal::detail::flow_batch_isa_available(isa)) isas.push_back(isa);
  return isas;
}

bool close(double batch, double scalar, double scale) {
  if (std::isinf(scalar)) return batch == scalar;
  return std::abs(batch - scalar) <= 1e-13 * scale;
}

TEST(FlowPointBatch, AgreesWithTheLawSystemBySystem) {
  const double dt = 0.1;
  // Hardening with time recovery (crystal-like) and softening (the paper's friction fit).
  const std::vector<law::LawParameters> laws = {
      testing::crystal_law(1.7, 12.24, 46.45, 0.0, 200.0, 1e-3, 16.0, 1.8),
      testing::crystal_law(1.0, 3.0, 10.0, 0.5, 20.0, 1.0, 8.0, 1.8),
      testing::crystal_law(0.097, 0.085, 0.2, 0.009, 80.0, 950.0, 16.0, 1.8)};
  std::mt19937_64 rng(7);
  int compared = 0, outside = 0, closed_form_hardening = 0, far_update = 0, newton_coefficients = 0;
  for (const auto& p : laws) {
    const law::SubloadingFrictionLaw law(p);
    for (const double q : {1.0, 0.4}) {
      for (int count = 1; count <= crystal::kMaxSlipSystems; ++count) {
        const FlowBatchInput in = random_systems(law, count, q, rng);
        for (const FlowBatchIsa isa : available_isas()) {
          FlowBatchOutput out;
          crystal::detail::batched_flow_points(p, dt, q, count, in, out, isa);
          for (int a = 0; a < count; ++a) {
            const auto i = static_cast<size_t>(a);
            const Expected e = scalar_flow_point(law, in, a, q, dt);
            const double scale = 1.0 + std::abs(e.r) + std::abs(e.r_s) + std::abs(e.g);
            SCOPED_TRACE(::testing::Message()
                         << "system " << a << " of " << count << ", slip " << in.slip[i]
                         << ", r_s0 " << in.r0[i] << ", isa " << static_cast<int>(isa));
            EXPECT_TRUE(close(out.g[i], e.g, scale)) << out.g[i] << " vs " << e.g;
            EXPECT_TRUE(close(out.mu[i], e.mu, std::abs(e.mu))) << out.mu[i] << " vs " << e.mu;
            EXPECT_TRUE(close(out.r_s[i], e.r_s, 1.0)) << out.r_s[i] << " vs " << e.r_s;
            EXPECT_TRUE(close(out.r[i], e.r, std::abs(e.r))) << out.r[i] << " vs " << e.r;
            if (std::isinf(e.g)) {
              ++outside;
              continue;
            }
            EXPECT_TRUE(close(out.g_slip[i], e.g_slip, std::abs(e.g_slip)))
                << out.g_slip[i] << " vs " << e.g_slip;
            EXPECT_TRUE(close(out.g_r[i], e.g_r, std::abs(e.g_r)));
            EXPECT_TRUE(close(out.mu_slope[i], e.mu_slope, std::abs(e.mu_slope) + 1.0));
            if (out.g_slip[i] < 0.0 && std::isfinite(out.g_slip[i])) {
              // The Newton coefficients (StressSolver::SlipPoint's w, d, l without the sign) are
              // the solver's formulas of this flow point (whose parts are checked above), to a
              // few ulps.
              const double inverse_slope = 1.0 / (-out.g_slip[i]);
              const double w = out.g[i] * inverse_slope;
              const double d = out.g_r[i] / (out.mu[i] * in.normal[i]) * inverse_slope;
              const double l =
                  out.g_r[i] * (-out.r[i] / out.mu[i]) * out.mu_slope[i] * inverse_slope;
              EXPECT_NEAR(out.newton_w[i], w, 1e-15 * std::abs(w));
              EXPECT_NEAR(out.newton_d[i], d, 1e-15 * std::abs(d));
              EXPECT_NEAR(out.newton_l[i], l, 1e-15 * std::abs(l));
              ++newton_coefficients;
            }
            const double b = p.friction.kappa * in.effective[i] / p.friction.mu_k +
                             p.friction.xi * dt / p.friction.mu_s;
            closed_form_hardening += std::abs(b) >= 0.0625;
            far_update += e.r_s > 2.0 / 3.0 && in.slip[i] > 0.0 && e.r_s > in.r0[i];
            ++compared;
          }
        }
      }
    }
  }
  // The draw reached every branch.
  EXPECT_GT(outside, 100);
  EXPECT_GT(closed_form_hardening, 100);
  EXPECT_GT(far_update, 100);
  EXPECT_GT(compared, 3000);
  EXPECT_GT(newton_coefficients, 1000);
}

// The batches' arcsine (a polynomial fit over [0, 2^-1/2], the half angles of the cot ratio)
// against libm's: each within about 0.7 ulp of the exact value there, so within 2 ulp of each
// other at every point of a fine grid, down to arguments where asin(h) = h.
TEST(FlowPointBatch, TheArcsineFitAgreesWithLibmToTheLastBits) {
  std::vector<double> points;
  const double end = std::sqrt(0.5);
  for (int i = 0; i <= 100000; ++i) points.push_back(end * i / 100000.0);
  for (double h = 1e-300; h < end; h *= 1.5) points.push_back(h);
  double worst_ulp = 0.0;
  for (const double h : points) {
    const double fit = law::closed_form::arcsine_to_quarter_pi(h);
    const double exact = std::asin(h);
    const double ulp =
        h == 0.0 ? std::numeric_limits<double>::denorm_min() : std::nextafter(exact, 2.0) - exact;
    worst_ulp = std::max(worst_ulp, std::abs(fit - exact) / ulp);
  }
  EXPECT_LE(worst_ulp, 2.0);
  EXPECT_EQ(law::closed_form::arcsine_to_quarter_pi(0.0), 0.0);
}

TEST(FlowPointBatch, SubloadingStartsAgreeWithTheLaw) {
  const law::SubloadingFrictionLaw law(testing::crystal_law(1.7, 12.24, 46.45, 0.0, 200.0, 1e-3));
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int compared = 0;
  for (int count = 1; count <= crystal::kMaxSlipSystems; ++count) {
    crystal::detail::SubloadingStartBatch b;
    // Both sides of r0 = 1/2 (the two sines), the ends 0 and 1, ratios next to 0 and 1.
    for (int a = 0; a < count; ++a) {
      const int kind = a % 6;
      b.r0[static_cast<size_t>(a)] = kind == 0   ? 0.0
                                     : kind == 1 ? 1.0
                                     : kind == 2 ? 1e-9 * unit(rng)
                                     : kind == 3 ? 1.0 - 1e-9 * unit(rng)
                                                 : unit(rng);
    }
    for (const FlowBatchIsa isa : available_isas()) {
      crystal::detail::batched_subloading_starts(law.parameters().subloading.u_tilde, count, b,
                                                 isa);
      for (int a = 0; a < count; ++a) {
        const auto i = static_cast<size_t>(a);
        const auto e = law.subloading_start(b.r0[i]);
        SCOPED_TRACE(::testing::Message() << "r0 " << b.r0[i]);
        EXPECT_TRUE(close(b.cos0[i], e.cos0, 1.0)) << b.cos0[i] << " vs " << e.cos0;
        // 1 - cos keeps its digits for small r0: relative.
        EXPECT_TRUE(close(b.one_minus_cos0[i], e.one_minus_cos0, e.one_minus_cos0));
        EXPECT_TRUE(close(b.rate0[i], e.rate0, std::abs(e.rate0)))
            << b.rate0[i] << " vs " << e.rate0;
        ++compared;
      }
    }
  }
  EXPECT_EQ(compared, static_cast<int>(available_isas().size()) * crystal::kMaxSlipSystems *
                          (crystal::kMaxSlipSystems + 1) / 2);
}

// A limit on the batches (what the MPI ranks of a run agree on: the least level among them)
// holds for every phase assembled afterwards, and results say which kernels ran. In child
// processes: a limit holds for the rest of the process.
TEST(FlowPointBatch, ALimitOnTheBatchesHoldsForEveryLaterPhase) {
  using crystal::detail::flow_batch_isa_name;
  using crystal::detail::flow_batch_level;
  using crystal::detail::flow_batch_width;
  using crystal::detail::flow_batches_pay;
  using crystal::detail::limit_flow_batches;
  const auto batched = [] {
    return crystal::build_phase<12>(testing::copper_phase(20.0)).phase.batched_flow_points;
  };
  EXPECT_EXIT(
      {
        limit_flow_batches(0);
        const bool none = !flow_batches_pay() && flow_batch_level() == 0 &&
                          std::string(flow_batch_isa_name()) == "none";
        std::exit(none && !batched() ? 0 : 1);
      },
      ::testing::ExitedWithCode(0), "");
  if (crystal::detail::flow_batch_isa_available(FlowBatchIsa::avx512)) {
    EXPECT_EXIT(
        {
          limit_flow_batches(1);
          const bool avx2 = flow_batch_level() == 1 && flow_batch_width() == 4 &&
                            std::string(flow_batch_isa_name()) == "avx2";
          std::exit(avx2 && batched() ? 0 : 1);
        },
        ::testing::ExitedWithCode(0), "");
  }
  // Unlimited (this process): the widest level the machine has, wherever batches pay.
  EXPECT_EQ(batched(), flow_batches_pay());
  EXPECT_EQ(flow_batch_level(), !flow_batches_pay() ? 0 : flow_batch_width() >= 8 ? 2 : 1);
}

// The solver's batches are the widest this machine runs.
TEST(FlowPointBatch, TheWidestAvailableInstructionSetIsChosen) {
  const int expected = crystal::detail::flow_batch_isa_available(FlowBatchIsa::avx512) ? 8
                       : crystal::detail::flow_batch_isa_available(FlowBatchIsa::avx2) ? 4
                                                                                       : 0;
  if (expected > 0) {
    EXPECT_EQ(crystal::detail::flow_batch_width(), expected);
  } else {
    EXPECT_LE(crystal::detail::flow_batch_width(), 8);
  }
  EXPECT_EQ(crystal::detail::flow_batches_pay(), crystal::detail::flow_batch_width() >= 4);
}

TEST(FlowPointBatch, OnlyOneClosedFormLawIsBatched) {
  const auto copper = testing::crystal_law(1.7, 12.24, 46.45, 0.0, 200.0, 1e-3);
  std::vector<law::SubloadingFrictionLaw> laws(12, law::SubloadingFrictionLaw(copper));
  EXPECT_TRUE(crystal::detail::has_batched_flow_points(laws, 12));
  auto other = copper;
  other.friction.kappa = 40.0;  // one family hardening differently
  laws[5] = law::SubloadingFrictionLaw(other);
  EXPECT_FALSE(crystal::detail::has_batched_flow_points(laws, 12));
  EXPECT_TRUE(crystal::detail::has_batched_flow_points(laws, 5));
  for (auto form : {law::OverstressForm::power, law::OverstressForm::rate_independent}) {
    auto p = copper;
    p.overstress.form = form;
    EXPECT_FALSE(crystal::detail::has_batched_flow_points({law::SubloadingFrictionLaw(p)}, 1));
  }
  for (auto function : {law::SubloadingFunction::neg_log, law::SubloadingFunction::reciprocal}) {
    auto p = copper;
    p.subloading.function = function;
    EXPECT_FALSE(crystal::detail::has_batched_flow_points({law::SubloadingFrictionLaw(p)}, 1));
  }
}

}  // namespace
}  // namespace subslip
