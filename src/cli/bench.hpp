// subslip bench: grain-steps per second of the crystal kernel (a benchmark, not a test).
#pragma once

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "subslip/crystal/aggregate.hpp"
#include "subslip/study/bench_phase.hpp"

namespace subslip::cli {

struct BenchArgs {
  int grains = 20000;
  int steps = 50;
  std::vector<int> threads{1, 2};
  std::vector<std::string> lattices = study::bench_lattices();
  std::string predictor = "last";  // mixed control's start (integrator key `predictor`)
  // Mixed control's tolerance on the free stresses, relative (integrator key `stress_tolerance`).
  double stress_tolerance = crystal::AggregateOptions{}.stress_tolerance;
};

void add_bench_command(CLI::App& app, BenchArgs& args);
int run_bench(const BenchArgs& args);

}  // namespace subslip::cli
