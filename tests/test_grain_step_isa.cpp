// Every instruction set's grain step takes the same steps (src/crystal/grain_step_isa.hpp).
//
// A portable build runs the grain step of 12, 24 and 48 slip systems in the widest instruction set
// the machine has, so on an AVX-512 machine the rest of the suite never reaches the SSE2 step of
// those counts, nor the AVX2 one. Here each level the machine has (0: SSE2 step, system-by-system
// flow points, as on a machine without AVX2; 1: AVX2; 2: AVX-512; the level a run would agree on,
// limit_flow_batches) drives the same grains: FCC, BCC 48 and HCP (study::bench_phase), tension
// and simple shear, a prestrain of 20 steps of 1e-3, then one step of 1e-4 ... 1e-1 from there.
// Every level must converge on every step with the same Newton iterations, and agree with level 0
// to round-off: the levels differ only in rounding (vector widths, FMA contraction).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "subslip/crystal/crystal_kernel.hpp"
#include "subslip/crystal/flow_point_batch.hpp"
#include "subslip/crystal/phase_builder.hpp"
#include "subslip/crystal/texture.hpp"
#include "subslip/study/bench_phase.hpp"
#include "subslip/study/robustness_grid.hpp"

namespace cr = subslip::crystal;
namespace st = subslip::study;

namespace {

constexpr int kGrains = 8;
constexpr int kPrestrainSteps = 20;
constexpr double kPrestrainStep = 1e-3;  // [-]
constexpr double kRate = 1e-3;           // [1/s]
const std::vector<double> kStrainSteps{1e-4, 1e-3, 1e-2, 1e-1};

// What one step gave, for comparison across levels.
struct StepRecord {
  bool ok = false;
  int iterations = 0;
  cr::Vec6 stress = cr::Vec6::Zero();  // [MPa]
  Eigen::VectorXd slip;                // [-]
  std::string where;                   // lattice, grain, loading, step
};

// Restores the widest level when a test ends (the limit is process-wide).
struct LevelGuard {
  ~LevelGuard() { cr::detail::limit_flow_batches(2); }
};

std::vector<int> machine_levels() {
  std::vector<int> levels{0};
  if (cr::detail::flow_batch_isa_available(cr::detail::FlowBatchIsa::avx2)) levels.push_back(1);
  if (cr::detail::flow_batch_isa_available(cr::detail::FlowBatchIsa::avx512)) levels.push_back(2);
  return levels;
}

template <int N>
std::vector<StepRecord> steps_at_level(const std::string& lattice, int level) {
  cr::detail::limit_flow_batches(level);
  const auto built = cr::build_phase<N>(st::bench_phase(lattice));
  const auto grains = cr::random_orientations(kGrains, 20000);
  std::vector<StepRecord> out;
  for (const auto loading : {st::GridLoading::tension, st::GridLoading::simple_shear}) {
    const cr::Mat3 L = st::grid_velocity_gradient(loading, kRate);
    for (int g = 0; g < kGrains; ++g) {
      cr::GrainState<N> s;
      s.reset(built.phase.slip_count, grains[static_cast<size_t>(g)].g, built.initial_mu);
      const auto record = [&](const cr::GrainStepReport& rep, const cr::GrainState<N>& next,
                              const std::string& step) {
        out.push_back({rep.ok, rep.iterations, next.stress, next.slip,
                       lattice + " grain " + std::to_string(g) + " " +
                           std::string(st::to_string(loading)) + " " + step});
      };
      for (int k = 0; k < kPrestrainSteps; ++k) {
        cr::GrainState<N> next = s;
        const auto rep = cr::implicit_grain_step(built.phase, s, L, kPrestrainStep / kRate,
                                                 cr::GrainStepOptions{}, next, nullptr);
        record(rep, next, "prestrain step " + std::to_string(k));
        if (!rep.ok) break;
        s = next;
      }
      for (const double e : kStrainSteps) {
        cr::GrainState<N> next = s;
        const auto rep = cr::implicit_grain_step(built.phase, s, L, e / kRate,
                                                 cr::GrainStepOptions{}, next, nullptr);
        record(rep, next, "step " + std::to_string(e));
      }
    }
  }
  return out;
}

template <int N>
void compare_levels(const std::string& lattice) {
  const LevelGuard guard;
  const std::vector<int> levels = machine_levels();
  const std::vector<StepRecord> base = steps_at_level<N>(lattice, 0);
  for (const StepRecord& r : base) EXPECT_TRUE(r.ok) << r.where << " (level 0)";
  for (size_t l = 1; l < levels.size(); ++l) {
    const std::vector<StepRecord> other = steps_at_level<N>(lattice, levels[l]);
    ASSERT_EQ(other.size(), base.size());
    double worst_stress = 0.0, worst_slip = 0.0;
    for (size_t i = 0; i < base.size(); ++i) {
      const StepRecord& a = base[i];
      const StepRecord& b = other[i];
      SCOPED_TRACE(b.where + " at level " + std::to_string(levels[l]));
      EXPECT_TRUE(b.ok);
      EXPECT_EQ(b.iterations, a.iterations);
      const double stress_scale = std::max(1.0, a.stress.cwiseAbs().maxCoeff());
      const double slip_scale = std::max(1e-12, a.slip.cwiseAbs().maxCoeff());
      worst_stress =
          std::max(worst_stress, (b.stress - a.stress).cwiseAbs().maxCoeff() / stress_scale);
      worst_slip = std::max(worst_slip, (b.slip - a.slip).cwiseAbs().maxCoeff() / slip_scale);
    }
    std::printf("%s level %d against 0: stress %.3g, slip %.3g (relative, largest)\n",
                lattice.c_str(), levels[l], worst_stress, worst_slip);
    EXPECT_LE(worst_stress, 1e-9);
    EXPECT_LE(worst_slip, 1e-9);
  }
}

TEST(GrainStepIsa, FccStepsAgreeOnEveryInstructionSet) {
  compare_levels<12>("fcc");
}
TEST(GrainStepIsa, Bcc48StepsAgreeOnEveryInstructionSet) {
  compare_levels<48>("bcc48");
}
TEST(GrainStepIsa, HcpStepsAgreeOnEveryInstructionSet) {
  compare_levels<24>("hcp");
}

}  // namespace
