// The robustness grid of issue 14 (bench/robustness_grid.cpp, study::RobustnessGrid) counts a
// state as admissible when it is finite with 0 <= r_s <= r < r_hat on every slip system; this
// checks that the count could fail. The grid's own zero-failure test (20 grains per lattice, every
// cell) joins the suite with the grain solver that passes it: the kernel on main fails it from a
// strain step of 1e-2 up (issue 14; the program reports the counts).
#include <gtest/gtest.h>

#include <limits>

#include "subslip/crystal/phase_builder.hpp"
#include "subslip/study/robustness_grid.hpp"

namespace cr = subslip::crystal;
namespace st = subslip::study;

namespace {

// The grid's admissibility check must see each kind of violation, or the grid's zero counts would
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

}  // namespace
