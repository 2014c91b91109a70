// The robustness grid on a small sample: the first 20 grains of the report's 500
// (bench/robustness_grid.cpp runs the full grid from the same definition, study::RobustnessGrid).
// Every lattice (with its bench phase and with the power overstress), both loadings, both starts,
// every strain step from 1e-4 to 3e-1: the implicit grain step must converge on every grain, and
// every state it commits (the prestrain's too) must be admissible: finite, 0 <= r_s <= r < r_hat
// on every slip system.
#include <gtest/gtest.h>

#include <limits>
#include <string>
#include <vector>

#include "subslip/crystal/phase_builder.hpp"
#include "subslip/study/robustness_grid.hpp"

namespace cr = subslip::crystal;
namespace st = subslip::study;

namespace {

// The grid's admissibility check must see each kind of violation, or its zero counts below would
// prove nothing. A virgin FCC grain (zero stress, r = r_s = 0) is admissible; each corruption is
// one of the states the check exists to catch.
TEST(RobustnessGridAdmissibility, NamesEachViolation) {
  const auto built = cr::build_phase<12>(st::bench_phase("fcc"));
  cr::GrainState<12> virgin;
  virgin.reset(12, cr::Mat3::Identity(), built.initial_mu);
  EXPECT_EQ(st::admissibility_violation(built.phase, virgin), "");

  auto broken = [&](auto corrupt) {
    cr::GrainState<12> s = virgin;
    corrupt(s);
    return st::admissibility_violation(built.phase, s);
  };
  EXPECT_EQ(broken([](auto& s) { s.stress(2) = std::numeric_limits<double>::quiet_NaN(); }),
            "non-finite state");
  EXPECT_EQ(broken([](auto& s) { s.r_s(4) = -1e-12; }).substr(0, 19), "system 4: r_s < 0 (");
  EXPECT_EQ(broken([](auto& s) { s.r_s(7) = 1e-12; }).substr(0, 19), "system 7: r_s > r (");
  // tau_0 = |P_0|^2 k = k/2 against a CRSS of mu tau0 = 10 MPa: r = 50 > r_hat = 1.6.
  EXPECT_EQ(broken([&](auto& s) { s.stress = 1000.0 * built.phase.schmid.col(0); }).substr(0, 22),
            "system 0: r >= r_hat (");
}

// The grid with each lattice's bench phase as given, and with its power overstress variant
// (study::grid_phase): both must converge everywhere.
struct GridCase {
  std::string lattice;
  subslip::law::OverstressForm overstress;
};

class RobustnessGrid : public ::testing::TestWithParam<GridCase> {};

TEST_P(RobustnessGrid, EveryStepConvergesToAnAdmissibleState) {
  st::RobustnessGrid grid;
  grid.grains = 20;
  grid.lattices = {GetParam().lattice};
  grid.overstress = GetParam().overstress;
  const st::GridResult result = st::run_robustness_grid(grid);

  ASSERT_EQ(result.prestrains.size(), grid.loadings.size());
  for (const st::PrestrainOutcome& p : result.prestrains) {
    EXPECT_EQ(p.failures, 0) << st::describe_problems(p);
    EXPECT_EQ(p.inadmissible, 0) << st::describe_problems(p);
  }
  ASSERT_EQ(result.cells.size(),
            grid.loadings.size() * grid.starts.size() * grid.strain_steps.size());
  for (const st::GridCell& c : result.cells) {
    EXPECT_EQ(c.solves, static_cast<int>(grid.grains))
        << st::describe_problems(c);  // none left out
    EXPECT_EQ(c.failures, 0) << st::describe_problems(c);
    EXPECT_EQ(c.inadmissible, 0) << st::describe_problems(c);
  }
}

// The variants change the bench phase in exactly the fields they name, on every family.
TEST(RobustnessGridPhase, VariantsChangeOnlyTheirFields) {
  st::RobustnessGrid grid;
  grid.pressure_sensitive = true;
  grid.overstress = subslip::law::OverstressForm::power;
  for (const std::string& lattice : st::bench_lattices()) {
    const cr::PhaseDescription bench = st::bench_phase(lattice);
    const cr::PhaseDescription variant = st::grid_phase(grid, lattice);
    EXPECT_FALSE(bench.pressure_sensitive);
    EXPECT_TRUE(variant.pressure_sensitive);
    ASSERT_EQ(variant.family_settings.size(), bench.family_settings.size());
    for (std::size_t f = 0; f < bench.family_settings.size(); ++f) {
      subslip::law::LawParameters expected = bench.family_settings[f].law;
      EXPECT_NE(expected.overstress.form, subslip::law::OverstressForm::power);
      expected.overstress.form = subslip::law::OverstressForm::power;
      EXPECT_EQ(variant.family_settings[f].law, expected) << lattice << ", family " << f;
      EXPECT_EQ(variant.family_settings[f].tau0, bench.family_settings[f].tau0);
    }
  }
}

std::vector<GridCase> grid_cases() {
  std::vector<GridCase> cases;
  for (const std::string& lattice : st::bench_lattices())
    for (subslip::law::OverstressForm form : st::grid_overstress_forms())
      cases.push_back({lattice, form});
  return cases;
}

INSTANTIATE_TEST_SUITE_P(Lattices, RobustnessGrid, ::testing::ValuesIn(grid_cases()),
                         [](const auto& info) {
                           return info.param.lattice + "_" +
                                  std::string(subslip::law::to_string(info.param.overstress));
                         });

}  // namespace
