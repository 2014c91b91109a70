// subslip_robustness_grid: the robustness grid of the implicit grain step, a report.
//
// For each lattice of `subslip bench` (the same phases), random grains under tension and simple
// shear with L fully prescribed, one implicit step of each strain step from a virgin and from a
// prestrained state (the grid itself is study::RobustnessGrid, shared with the test of its small
// version, tests/test_robustness_grid.cpp). Per lattice x loading x start x step: failed solves,
// inadmissible converged states, Newton iterations per solve and the first failing grain.
//
// Usage: subslip_robustness_grid [--grains 500] [--lattice fcc ...] [--threads N] [--csv FILE]
//                                [--pressure-sensitive] [--overstress exponential|power]
// Exit status 0 whatever it finds (it is a report); the last line is `failures: N`, N counting
// the failed solves of the tested steps and of the prestrains.
#include <omp.h>
#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "subslip/study/robustness_grid.hpp"

using namespace subslip::study;

namespace {

void print_header(const RobustnessGrid& grid, int threads) {
  std::printf(
      "# Robustness grid of the implicit grain step: %zu random grains per lattice (seed %llu), "
      "%d threads\n"
      "# phase: bench phase, overstress form %s%s\n"
      "# L fully prescribed at a rate of %g /s (tension: D = rate diag(1, -1/2, -1/2); shear: "
      "L_12 = rate); one point::GrainPoint update from the committed slip rates, default options\n"
      "# prestrained: %g strain in steps of %g of the same loading first\n"
      "# step: strain step [-], dt [s]; solves: grains tested; fail: not converged; inadm: "
      "converged to an inadmissible state; newton: iterations per solve, failed ones included\n",
      grid.grains, static_cast<unsigned long long>(grid.seed), threads,
      subslip::law::to_string(grid.overstress).data(),
      grid.pressure_sensitive ? ", pressure-sensitive (normal traction plays f_n)" : "", grid.rate,
      grid.prestrain, grid.prestrain_step);
  std::printf("%-6s %-8s %-12s %8s %7s %6s %5s %5s %11s %10s  %s\n", "phase", "loading", "start",
              "step[-]", "dt[s]", "solves", "fail", "inadm", "newton_mean", "newton_max",
              "first failure");
}

std::string first_failure(int grain, int system, const std::string& why) {
  if (grain < 0) return "-";
  return "grain " + std::to_string(grain) + ", system " + std::to_string(system) + ": " + why;
}

void print_cells(const std::vector<GridCell>& cells) {
  for (const GridCell& c : cells)
    std::printf("%-6s %-8s %-12s %8.0e %7g %6d %5d %5d %11.2f %10d  %s\n", c.lattice.c_str(),
                to_string(c.loading).data(), to_string(c.start).data(), c.strain_step, c.dt,
                c.solves, c.failures, c.inadmissible, c.mean_iterations, c.max_iterations,
                first_failure(c.first_failure, c.failure_system, c.failure_why).c_str());
}

void print_prestrains(const std::vector<PrestrainOutcome>& prestrains, double prestrain) {
  for (const PrestrainOutcome& p : prestrains) {
    const std::string problems = describe_problems(p);
    if (problems.empty())
      std::printf("# prestrain %s %s to %g: all %d grains, no failure, all admissible\n",
                  p.lattice.c_str(), to_string(p.loading).data(), prestrain, p.grains);
    else
      std::printf("# %s\n", problems.c_str());
  }
}

void print_violations(const std::vector<GridCell>& cells) {
  for (const GridCell& c : cells)
    if (c.inadmissible > 0) std::printf("# inadmissible %s\n", describe_problems(c).c_str());
}

// The why strings are the kernel's own sentences: quoted, with quotes doubled (RFC 4180).
std::string csv_quoted(const std::string& text) {
  std::string out = "\"";
  for (char ch : text) out += ch == '"' ? std::string("\"\"") : std::string(1, ch);
  return out + "\"";
}

void write_csv(const std::string& path, const GridResult& r, const RobustnessGrid& grid) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error("cannot write " + path);
  out << "phase,loading,start,strain_step,dt_s,solves,failures,inadmissible,newton_mean,"
         "newton_max,first_failure_grain,first_failure_system,first_failure_why,failed_at_strain,"
         "first_violation\n";
  for (const GridCell& c : r.cells)
    out << c.lattice << "," << to_string(c.loading) << "," << to_string(c.start) << ","
        << c.strain_step << "," << c.dt << "," << c.solves << "," << c.failures << ","
        << c.inadmissible << "," << c.mean_iterations << "," << c.max_iterations << ","
        << c.first_failure << "," << c.failure_system << "," << csv_quoted(c.failure_why) << ",,"
        << csv_quoted(c.first_violation) << "\n";
  // The prestrain rows: their step is the prestrain's, their Newton columns are empty.
  for (const PrestrainOutcome& p : r.prestrains)
    out << p.lattice << "," << to_string(p.loading) << ",prestrain," << grid.prestrain_step << ","
        << grid.prestrain_step / grid.rate << "," << p.grains << "," << p.failures << ","
        << p.inadmissible << ",,," << p.first_failure << "," << p.failure_system << ","
        << csv_quoted(p.failure_why) << "," << p.failed_at << "," << csv_quoted(p.first_violation)
        << "\n";
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Robustness grid of the implicit grain step"};
  RobustnessGrid grid;
  int threads = omp_get_max_threads();
  std::string csv;
  app.add_option("--grains", grid.grains, "random grains per lattice")->check(CLI::PositiveNumber);
  app.add_option("--lattice", grid.lattices, "lattices to run")
      ->check(CLI::IsMember(bench_lattices()));
  app.add_option("--threads", threads, "OpenMP threads (results do not depend on it)")
      ->check(CLI::PositiveNumber);
  app.add_option("--csv", csv, "also write the table to this CSV file");
  app.add_flag("--pressure-sensitive", grid.pressure_sensitive,
               "the pressure-sensitive reading of the law (planes under tension open)");
  std::map<std::string, subslip::law::OverstressForm> forms;
  for (subslip::law::OverstressForm form : grid_overstress_forms())
    forms.emplace(subslip::law::to_string(form), form);
  std::string overstress(subslip::law::to_string(grid.overstress));
  app.add_option("--overstress", overstress, "overstress form of the bench phase")
      ->check(CLI::IsMember(forms));
  CLI11_PARSE(app, argc, argv);
  grid.overstress = forms.at(overstress);
  omp_set_num_threads(threads);

  print_header(grid, threads);
  GridResult all;
  // One lattice at a time, so that the rows of a finished lattice are seen while the next runs.
  for (const std::string& lattice : grid.lattices) {
    RobustnessGrid one = grid;
    one.lattices = {lattice};
    const auto start = std::chrono::steady_clock::now();
    GridResult r = run_robustness_grid(one);
    const std::chrono::duration<double> wall = std::chrono::steady_clock::now() - start;
    print_cells(r.cells);
    std::printf("# %s: %.1f s wall\n", lattice.c_str(), wall.count());
    std::fflush(stdout);
    all.cells.insert(all.cells.end(), r.cells.begin(), r.cells.end());
    all.prestrains.insert(all.prestrains.end(), r.prestrains.begin(), r.prestrains.end());
  }
  print_prestrains(all.prestrains, grid.prestrain);
  print_violations(all.cells);
  if (!csv.empty()) write_csv(csv, all, grid);
  int prestrain_failures = 0;
  for (const PrestrainOutcome& p : all.prestrains) prestrain_failures += p.failures;
  std::printf("# failed solves: %d in the tested steps, %d in the prestrains; inadmissible: %d\n",
              all.failures() - prestrain_failures, prestrain_failures, all.inadmissible());
  std::printf("failures: %d\n", all.failures());
  return 0;
}
