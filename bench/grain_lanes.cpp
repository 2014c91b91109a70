// subslip_grain_lanes: what SIMD lanes across grains (one grain per lane, as a batched material
// point could hold them) would give the grain solver, against its lanes across slip systems.
//
// Two measurements (docs/benchmarks.md, "SIMD lanes across grains"):
// * Lockstep. Grains in lanes evaluate their flow rules together, so a batch of W grains takes as
//   many evaluations as its slowest grain. The ExaCMech anchor's work (random FCC grains, latent
//   ratio 1, D = 1e-3/s diag(1, -1/2, -1/2), steps of 0.1 s) through the material-point API:
//   each grain-step's Newton iterations, and the evaluations per grain in batches of W
//   consecutive grains against the grains' own.
// * The flow-point kernel with no padding. An FCC grain's 12 systems fill 2 batches of 8 lanes
//   (16); four grains' 48 systems fill 6. Times of four 12-system calls against one 48-system
//   call of the same kernel (the widest the machine runs), per system.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <vector>

#include "subslip/crystal/flow_point_batch.hpp"
#include "subslip/crystal/texture.hpp"
#include "subslip/material_point.hpp"

namespace {

namespace cr = subslip::crystal;
namespace pt = subslip::point;

// The anchor's phase (../shared/anchors/exacmech/: ExaCMech's FCC copper with Voce hardening as
// the friction law's mu from 1.7 toward 12.24, every system hardened by all).
pt::GrainParameters anchor_phase() {
  pt::GrainParameters d;
  cr::SlipGroupSettings g;
  g.tau0 = 10.0;  // [MPa]
  g.law.friction = {1.7, 12.24, 46.45, 0.0};
  g.law.subloading = {subslip::law::SubloadingFunction::cot, 200.0};
  g.law.overstress = {subslip::law::OverstressForm::exponential, 1.0e-3, 16.0, 1.6};
  d.families = {cr::SlipFamily::fcc_111_110};
  d.family_settings = {g};
  d.stiffness = cr::cubic_stiffness(168400, 121400, 75200);  // [MPa]
  d.latent.kind = cr::LatentHardening::Kind::ratio;
  d.latent.ratio = 1.0;
  return d;
}

struct Lockstep {
  double own = 0.0;                // evaluations per grain-step, each grain its own
  std::vector<double> in_batches;  // the same in lockstep batches of each width
};

// Evaluations of a grain-step: one at the start and one after each Newton iteration.
Lockstep lockstep_evaluations(int grains, int steps, const std::vector<int>& widths) {
  const pt::GrainParameters phase = anchor_phase();
  pt::GrainOptions options;
  options.tangent = false;
  const pt::GrainPoint point(phase, options);
  std::vector<pt::GrainState> states;
  for (const cr::Orientation& o : cr::random_orientations(static_cast<size_t>(grains), 1))
    states.push_back(point.initial_state(o.g));
  const std::vector<Eigen::Matrix3d> l(static_cast<size_t>(grains),
                                       Eigen::Vector3d(1e-3, -0.5e-3, -0.5e-3).asDiagonal());
  std::vector<pt::GrainUpdate> out(static_cast<size_t>(grains));
  const double dt = 0.1;  // [s]: strain steps of 1e-4
  Lockstep result;
  result.in_batches.assign(widths.size(), 0.0);
  std::vector<int> evaluations(static_cast<size_t>(grains));
  for (int step = 0; step < steps; ++step) {
    point.update(states, l, dt, out);
    for (int g = 0; g < grains; ++g) {
      const auto i = static_cast<size_t>(g);
      if (!out[i].report.ok) throw std::runtime_error("grain " + std::to_string(g) + " failed");
      evaluations[i] = out[i].report.iterations + 1;
      result.own += evaluations[i];
      states[i] = out[i].state;
    }
    for (size_t w = 0; w < widths.size(); ++w) {
      const auto width = static_cast<size_t>(widths[w]);
      for (size_t first = 0; first < evaluations.size(); first += width) {
        const size_t last = std::min(first + width, evaluations.size());
        const int slowest = *std::max_element(evaluations.begin() + static_cast<long>(first),
                                              evaluations.begin() + static_cast<long>(last));
        result.in_batches[w] += static_cast<double>(slowest) * static_cast<double>(last - first);
      }
    }
  }
  const double grain_steps = static_cast<double>(grains) * steps;
  result.own /= grain_steps;
  for (double& v : result.in_batches) v /= grain_steps;
  return result;
}

// A plausible trial point of `count` systems: loaded near r = 0.95, slipping a little.
void fill_trial_points(const subslip::law::LawParameters& law, int count,
                       cr::detail::FlowBatchInput& in) {
  cr::detail::SubloadingStartBatch starts;
  for (int a = 0; a < count; ++a) starts.r0[static_cast<size_t>(a)] = 0.9;
  cr::detail::batched_subloading_starts(law.subloading.u_tilde, count, starts);
  for (int a = 0; a < count; ++a) {
    const auto i = static_cast<size_t>(a);
    in.mu0[i] = 1.7 + 0.01 * a;
    in.slip[i] = 1e-6 * (1 + a % 5);
    in.effective[i] = 12 * in.slip[i];
    in.r0[i] = starts.r0[i], in.cos0[i] = starts.cos0[i];
    in.one_minus_cos0[i] = starts.one_minus_cos0[i], in.rate0[i] = starts.rate0[i];
    in.normal[i] = 10.0;
    in.shear[i] = 0.95 * in.mu0[i] * in.normal[i];
  }
  cr::detail::clear_batch_padding(in, count);
}

// Nanoseconds per system evaluation: `calls` calls of `count` systems, the median of 5 runs.
double nanoseconds_per_system(int count, int calls) {
  const subslip::law::LawParameters law = anchor_phase().family_settings[0].law;
  cr::detail::FlowBatchInput in;
  fill_trial_points(law, count, in);
  cr::detail::FlowBatchOutput out;
  std::vector<double> runs;
  double sink = 0.0;
  for (int run = 0; run < 5; ++run) {
    const auto start = std::chrono::steady_clock::now();
    for (int k = 0; k < calls; ++k) {
      in.slip[0] = 1e-6 * (1.0 + 1e-9 * k);  // one input changes: no call is hoisted
      cr::detail::batched_flow_points(law, 0.1, 1.0, count, in, out);
      sink += out.g[0];
    }
    const std::chrono::duration<double, std::nano> took = std::chrono::steady_clock::now() - start;
    runs.push_back(took.count() / (static_cast<double>(calls) * count));
  }
  if (!std::isfinite(sink)) std::printf("(a G was not finite)\n");
  std::sort(runs.begin(), runs.end());
  return runs[2];
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"What SIMD lanes across grains would give the grain solver"};
  int grains = 2000, steps = 200, calls = 200000;
  app.add_option("--grains", grains, "Grains of the lockstep count")->check(CLI::PositiveNumber);
  app.add_option("--steps", steps, "Steps of 0.1 s (strain 1e-4 each)")->check(CLI::PositiveNumber);
  app.add_option("--calls", calls, "Kernel calls per timing run")->check(CLI::PositiveNumber);
  CLI11_PARSE(app, argc, argv);

  const std::vector<int> widths = {4, 8};
  const Lockstep lockstep = lockstep_evaluations(grains, steps, widths);
  std::printf(
      "flow-rule evaluations per grain-step (%d grains x %d steps): %.3f each grain its own\n",
      grains, steps, lockstep.own);
  for (size_t w = 0; w < widths.size(); ++w)
    std::printf("  in lockstep batches of %d grains: %.3f (x%.3f)\n", widths[w],
                lockstep.in_batches[w], lockstep.in_batches[w] / lockstep.own);

  std::printf("flow-point kernel (%s batches of %d), ns per system evaluation:\n",
              cr::detail::flow_batch_isa_name(), cr::detail::flow_batch_width());
  const double one_grain = nanoseconds_per_system(12, calls);
  const double four_grains = nanoseconds_per_system(48, calls / 4);
  std::printf("  one grain's 12 systems per call: %.3f\n", one_grain);
  std::printf("  four grains' 48 systems per call: %.3f (x%.3f)\n", four_grains,
              four_grains / one_grain);
  return 0;
}
