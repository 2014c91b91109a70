#include "subslip/study/robustness_grid.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <stdexcept>

#include "subslip/crystal/texture.hpp"
#include "subslip/material_point.hpp"

namespace subslip::study {

namespace {

using point::GrainPoint;
using point::GrainState;
using Mat3 = Eigen::Matrix3d;

// What one grain's solve (or prestrain) left: the update's report and the first violation of
// admissibility among the states it committed (empty: all admissible).
struct GrainOutcome {
  point::SolveReport report;
  std::string violation;
};

// The grain update the grid tests: the default solver options, each step from its committed
// slip rates (one try), no tangent.
point::GrainOptions tested_options() {
  point::GrainOptions o;
  o.tangent = false;
  o.start = point::GrainStart::committed;
  return o;
}

// One implicit step; s1 gets the new state when the solve converges.
GrainOutcome tested_step(const GrainPoint& grain, const GrainState& s0, const Mat3& L, double dt,
                         GrainState& s1) {
  GrainOutcome out;
  point::GrainUpdate u = grain.update(s0, L, dt);
  out.report = std::move(u.report);
  if (out.report.ok) {
    s1 = std::move(u.state);
    out.violation = grain.admissibility_violation(s1);
  }
  return out;
}

int prestrain_steps(const RobustnessGrid& grid) {
  const long steps = std::lround(grid.prestrain / grid.prestrain_step);
  if (!(grid.prestrain_step > 0.0) || steps < 1)
    throw std::invalid_argument("robustness grid: the prestrain needs at least one step");
  return static_cast<int>(steps);
}

// Drives s by `steps` steps of dt; stops at the first failed step, s then being the last
// committed state and `done` the number of committed steps. The report is the failed or the
// last step's.
GrainOutcome prestrain_grain(const GrainPoint& grain, const Mat3& L, int steps, double dt,
                             GrainState& s, int& done) {
  std::string first_violation;
  GrainOutcome out;
  for (done = 0; done < steps; ++done) {
    GrainState next = s;
    out = tested_step(grain, s, L, dt, next);
    if (!out.report.ok) break;
    s = next;
    if (first_violation.empty()) first_violation = out.violation;
  }
  out.violation = first_violation;
  return out;
}

// f(g) for every grain with active[g], in parallel. Grain costs differ by orders of magnitude
// (a failing solve runs to the iteration cap), hence dynamic scheduling; each outcome is the
// grain's own, so the result does not depend on the thread count or the schedule.
template <class F>
std::vector<GrainOutcome> for_each_grain(const std::vector<bool>& active, F&& f) {
  const long n = static_cast<long>(active.size());
  std::vector<GrainOutcome> out(active.size());
#pragma omp parallel for schedule(dynamic)
  for (long g = 0; g < n; ++g) {
    const auto gi = static_cast<std::size_t>(g);
    if (active[gi]) out[gi] = f(gi);
  }
  return out;
}

// Counts a cell's outcomes; the first failure and violation are the lowest-numbered grain's.
void summarise(const std::vector<GrainOutcome>& out, const std::vector<bool>& tested,
               GridCell& cell) {
  long iterations = 0;
  for (std::size_t g = 0; g < out.size(); ++g) {
    if (!tested[g]) continue;
    const GrainOutcome& o = out[g];
    ++cell.solves;
    iterations += o.report.iterations;
    cell.max_iterations = std::max(cell.max_iterations, o.report.iterations);
    if (!o.report.ok && cell.failures++ == 0) {
      cell.first_failure = static_cast<int>(g);
      cell.failure_system = o.report.system;
      cell.failure_why = o.report.why;
    }
    if (!o.violation.empty() && cell.inadmissible++ == 0)
      cell.first_violation = "grain " + std::to_string(g) + ", " + o.violation;
  }
  if (cell.solves > 0) cell.mean_iterations = double(iterations) / cell.solves;
}

void summarise(const std::vector<GrainOutcome>& out, const std::vector<int>& done,
               const RobustnessGrid& grid, PrestrainOutcome& p) {
  for (std::size_t g = 0; g < out.size(); ++g) {
    const GrainOutcome& o = out[g];
    ++p.grains;
    if (!o.report.ok && p.failures++ == 0) {
      p.first_failure = static_cast<int>(g);
      p.failed_at = done[g] * grid.prestrain_step;
      p.failure_system = o.report.system;
      p.failure_why = o.report.why;
    }
    if (!o.violation.empty() && p.inadmissible++ == 0)
      p.first_violation = "grain " + std::to_string(g) + ", " + o.violation;
  }
}

bool prestrains(const RobustnessGrid& grid) {
  return std::find(grid.starts.begin(), grid.starts.end(), GridStart::prestrained) !=
         grid.starts.end();
}

// One lattice: its virgin grains, and per loading (run) the prestrain when a start needs it,
// then every start and step.
class LatticeRun {
 public:
  LatticeRun(const crystal::PhaseDescription& phase, const std::string& lattice,
             const RobustnessGrid& grid)
      : grain_(phase, tested_options()), lattice_(lattice), grid_(grid) {
    const auto grains = crystal::random_orientations(grid.grains, grid.seed);
    virgin_.reserve(grid.grains);
    for (std::size_t g = 0; g < grid.grains; ++g) virgin_.push_back(grain_.initial_state(grains[g].g));
  }

  void run(GridLoading loading, GridResult& result) {
    const Mat3 L = grid_velocity_gradient(loading, grid_.rate);
    std::vector<bool> everyone(grid_.grains, true), reached = everyone;
    std::vector<GrainState> prestrained = virgin_;
    if (prestrains(grid_)) result.prestrains.push_back(prestrain(loading, L, prestrained, reached));
    for (GridStart start : grid_.starts) {
      const bool virgin = start == GridStart::virgin;
      for (double e : grid_.strain_steps)
        result.cells.push_back(cell(loading, start, e, L, virgin ? virgin_ : prestrained,
                                    virgin ? everyone : reached));
    }
  }

 private:
  PrestrainOutcome prestrain(GridLoading loading, const Mat3& L, std::vector<GrainState>& s,
                             std::vector<bool>& reached) const {
    const int steps = prestrain_steps(grid_);
    const double dt = grid_.prestrain_step / grid_.rate;
    std::vector<int> done(s.size(), 0);
    const auto out = for_each_grain(
        reached, [&](std::size_t g) { return prestrain_grain(grain_, L, steps, dt, s[g], done[g]); });
    PrestrainOutcome p;
    p.lattice = lattice_;
    p.loading = loading;
    summarise(out, done, grid_, p);
    for (std::size_t g = 0; g < out.size(); ++g) reached[g] = out[g].report.ok;
    return p;
  }

  GridCell cell(GridLoading loading, GridStart start, double strain_step, const Mat3& L,
                const std::vector<GrainState>& from, const std::vector<bool>& tested) const {
    GridCell c;
    c.lattice = lattice_;
    c.loading = loading;
    c.start = start;
    c.strain_step = strain_step;
    c.dt = strain_step / grid_.rate;
    const auto out = for_each_grain(tested, [&](std::size_t g) {
      GrainState s1 = from[g];
      return tested_step(grain_, from[g], L, c.dt, s1);
    });
    summarise(out, tested, c);
    return c;
  }

  GrainPoint grain_;
  const std::string& lattice_;
  const RobustnessGrid& grid_;
  std::vector<GrainState> virgin_;
};

std::string failure_text(int grain, int system, const std::string& why) {
  std::ostringstream text;
  text << "first grain " << grain << " (system " << system << ": " << why << ")";
  return text.str();
}

// "F of N failed, first grain ...; K inadmissible, grain ...", each part only when not 0.
std::string problems(int failures, int solves, const std::string& first_failure, int inadmissible,
                     const std::string& first_violation) {
  std::ostringstream text;
  if (failures > 0) text << failures << " of " << solves << " failed, " << first_failure;
  if (failures > 0 && inadmissible > 0) text << "; ";
  if (inadmissible > 0) text << inadmissible << " inadmissible, " << first_violation;
  return text.str();
}

}  // namespace

std::string_view to_string(GridLoading loading) {
  return loading == GridLoading::tension ? "tension" : "shear";
}

std::string_view to_string(GridStart start) {
  return start == GridStart::virgin ? "virgin" : "prestrained";
}

Eigen::Matrix3d grid_velocity_gradient(GridLoading loading, double rate) {
  Eigen::Matrix3d L = Eigen::Matrix3d::Zero();
  if (loading == GridLoading::tension) {
    L.diagonal() << rate, -0.5 * rate, -0.5 * rate;  // isochoric
  } else {
    L(0, 1) = rate;
  }
  return L;
}

int GridResult::failures() const {
  int n = 0;
  for (const auto& c : cells) n += c.failures;
  for (const auto& p : prestrains) n += p.failures;
  return n;
}

int GridResult::inadmissible() const {
  int n = 0;
  for (const auto& c : cells) n += c.inadmissible;
  for (const auto& p : prestrains) n += p.inadmissible;
  return n;
}

crystal::PhaseDescription grid_phase(const RobustnessGrid& grid, const std::string& lattice) {
  crystal::PhaseDescription d = bench_phase(lattice);
  d.pressure_sensitive = grid.pressure_sensitive;
  for (crystal::SlipGroupSettings& g : d.family_settings) g.law.overstress.form = grid.overstress;
  return d;
}

const std::vector<law::OverstressForm>& grid_overstress_forms() {
  static const std::vector<law::OverstressForm> forms{law::OverstressForm::exponential,
                                                      law::OverstressForm::power};
  return forms;
}

GridResult run_robustness_grid(const RobustnessGrid& grid) {
  if (prestrains(grid)) prestrain_steps(grid);  // checked before any work
  GridResult result;
  for (const std::string& lattice : grid.lattices) {
    LatticeRun run(grid_phase(grid, lattice), lattice, grid);
    for (GridLoading loading : grid.loadings) run.run(loading, result);
  }
  return result;
}

std::string describe_problems(const GridCell& c) {
  if (c.failures == 0 && c.inadmissible == 0) return {};
  char step[32];
  std::snprintf(step, sizeof step, "%.0e", c.strain_step);
  std::ostringstream head;
  head << c.lattice << " " << to_string(c.loading) << " " << to_string(c.start) << " step " << step;
  const std::string failure = failure_text(c.first_failure, c.failure_system, c.failure_why);
  return head.str() + ": " +
         problems(c.failures, c.solves, failure, c.inadmissible, c.first_violation);
}

std::string describe_problems(const PrestrainOutcome& p) {
  if (p.failures == 0 && p.inadmissible == 0) return {};
  std::ostringstream failure;
  failure << failure_text(p.first_failure, p.failure_system, p.failure_why) << " at strain "
          << p.failed_at;
  return p.lattice + " " + std::string(to_string(p.loading)) + " prestrain: " +
         problems(p.failures, p.grains, failure.str(), p.inadmissible, p.first_violation);
}

}  // namespace subslip::study
