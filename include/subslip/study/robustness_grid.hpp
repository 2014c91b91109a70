// The robustness grid of the implicit grain step: random grains of each bench lattice,
// two loadings with the velocity gradient L fully prescribed, one implicit step of each of a
// ladder of strain steps, from a virgin and from a prestrained state. What is counted per cell:
// failed solves, Newton iterations per solve, and committed states outside the admissible set.
//
// One definition serves the report program (bench/robustness_grid.cpp, 500 grains) and the test
// of its smaller version (tests/test_robustness_grid.cpp), so the two cannot drift apart.
//
// Every grain is independent (no aggregate, no cutback: a failure is the kernel's own verdict on
// that step), so the results do not depend on the number of OpenMP threads.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <iomanip>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "subslip/crystal/admissibility.hpp"
#include "subslip/crystal/crystal_kernel.hpp"
#include "subslip/study/bench_phase.hpp"

namespace subslip::study {

enum class GridLoading {
  tension,       // D = rate diag(1, -1/2, -1/2), no spin
  simple_shear,  // L_12 = rate, every other component 0
};
enum class GridStart {
  virgin,       // GrainState::reset with the phase's initial mu
  prestrained,  // driven to `prestrain` in the same loading by steps of `prestrain_step`
};
std::string_view to_string(GridLoading loading);
std::string_view to_string(GridStart start);

// The velocity gradient of a loading at a strain rate [1/s] (sample frame).
Eigen::Matrix3d grid_velocity_gradient(GridLoading loading, double rate);

struct RobustnessGrid {
  std::vector<std::string> lattices = bench_lattices();
  std::vector<GridLoading> loadings{GridLoading::tension, GridLoading::simple_shear};
  std::vector<GridStart> starts{GridStart::virgin, GridStart::prestrained};
  std::vector<double> strain_steps{1e-4, 1e-3, 1e-2, 3e-2, 1e-1, 3e-1};  // rate dt [-]
  double rate = 1e-3;            // [1/s]: the time step of a strain step e is e / rate
  double prestrain = 0.02;       // [-]
  double prestrain_step = 1e-3;  // [-]
  std::size_t grains = 500;      // random orientations per lattice, the first of the seed's
  std::uint64_t seed = 20000;    // random_orientations seed (the one `subslip bench` uses)
  // Variants of the bench phase (bench_phase): the pressure-sensitive reading of the law (the
  // normal traction on each slip plane plays f_n, so planes under tension open) and the
  // overstress form; the defaults are `subslip bench`'s phase.
  bool pressure_sensitive = false;
  law::OverstressForm overstress = law::OverstressForm::exponential;
};

// The phase of one lattice of the grid: bench_phase with the grid's variants.
crystal::PhaseDescription grid_phase(const RobustnessGrid& grid, const std::string& lattice);

// The overstress forms the grid's phase takes (RobustnessGrid::overstress): the viscous ones,
// exponential (bench_phase's) first.
const std::vector<law::OverstressForm>& grid_overstress_forms();

// One tested step: lattice x loading x start x strain step, over the grains that reached its start.
struct GridCell {
  std::string lattice;
  GridLoading loading = GridLoading::tension;
  GridStart start = GridStart::virgin;
  double strain_step = 0.0;      // [-]
  double dt = 0.0;               // [s]
  int solves = 0;                // grains tested (those whose prestrain, if any, succeeded)
  int failures = 0;              // solves that did not converge (GrainStepReport::ok false)
  int inadmissible = 0;          // converged solves whose state is not admissible (see below)
  double mean_iterations = 0.0;  // Newton iterations per solve, failed solves included
  int max_iterations = 0;
  // The lowest-numbered failing grain, its slip system (-1: not named) and the kernel's reason.
  int first_failure = -1;
  int failure_system = -1;
  std::string failure_why;
  // The lowest-numbered inadmissible grain's first violation, e.g. "grain 3, system 7: r_s > r".
  std::string first_violation;
};

// The prestrain of one lattice x loading: grains whose prestrain failed start no prestrained cell.
struct PrestrainOutcome {
  std::string lattice;
  GridLoading loading = GridLoading::tension;
  int grains = 0;
  int failures = 0;
  int inadmissible = 0;  // grains with a committed prestrain step that is not admissible
  int first_failure = -1;
  double failed_at = 0.0;  // [-]: the strain reached before the failing step of first_failure
  int failure_system = -1;
  std::string failure_why;
  std::string first_violation;
};

struct GridResult {
  std::vector<GridCell> cells;               // lattice, loading, start, strain step: grid order
  std::vector<PrestrainOutcome> prestrains;  // lattice, loading (only when a start prestrains)
  int failures() const;                      // failed solves: tested steps and prestrains
  int inadmissible() const;                  // inadmissible committed states, all of them
};

// The check of every committed state (crystal/admissibility.hpp).
using crystal::admissibility_violation;

// Runs the grid, OpenMP-parallel over grains (omp_get_max_threads threads); every committed
// state (the prestrain's too) is checked with admissibility_violation.
GridResult run_robustness_grid(const RobustnessGrid& grid);

// One line about a cell's failures and violations, e.g. "fcc tension virgin step 1e-02:
// 11 of 500 failed, first grain 7 (system 3: line search stalled)"; empty when it has none.
std::string describe_problems(const GridCell& cell);
std::string describe_problems(const PrestrainOutcome& prestrain);

}  // namespace subslip::study
