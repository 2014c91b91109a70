#include "bench.hpp"
#include "validators.hpp"

#include <omp.h>

#include <cstdio>

#include "subslip/crystal/phase_builder.hpp"
#include "subslip/crystal/texture.hpp"
#include "subslip/study/bench_phase.hpp"

namespace subslip::cli {

namespace {

using namespace subslip::crystal;

// Uniaxial tension along z at 1e-3 /s, lateral stresses free (mixed control), strain step 1e-4.
LoadSegment tension(int steps) {
  LoadSegment seg;
  seg.velocity_gradient(2, 2) = 1.0e-3;
  seg.free(0, 0) = seg.free(1, 1) = true;
  seg.duration = 0.1 * steps;
  seg.increments = steps;
  seg.output_every = steps;
  return seg;
}

}  // namespace

void add_bench_command(CLI::App& app, BenchArgs& a) {
  CLI::App* cmd = app.add_subcommand(
      "bench", "Grain-steps per second of the crystal kernel (uniaxial tension, strain step 1e-4)");
  cmd->add_option("--grains", a.grains, "random grains per aggregate")->check(cli::positive());
  cmd->add_option("--steps", a.steps, "increments of 1e-4 strain")->check(cli::positive());
  cmd->add_option("--threads", a.threads, "thread counts to run")->check(cli::positive());
  cmd->add_option("--lattice", a.lattices, "fcc, bcc48, hcp")
      ->check(CLI::IsMember(study::bench_lattices()));
}

int run_bench(const BenchArgs& a) {
  std::printf("%-6s %5s %7s %7s %14s %13s %12s %9s %10s %8s\n", "phase", "slips", "grains",
              "threads", "grain-steps/s", "newton/solve", "solves/step", "cutbacks", "B/grain",
              "wall[s]");
  const auto grains = random_orientations(static_cast<size_t>(a.grains), 20000);
  for (const auto& lattice : a.lattices) {
    for (int threads : a.threads) {
      omp_set_num_threads(threads);
      auto aggregate = build_taylor_aggregate(study::bench_phase(lattice), grains);
      const AggregateStats st = aggregate->run({tension(a.steps)}, AggregateOptions{},
                                               [](const MacroState&, const GrainFields&) {});
      std::printf("%-6s %5d %7d %7d %14.4g %13.3f %12.3f %9ld %10zu %8.2f\n", lattice.c_str(),
                  aggregate->slip_count(), a.grains, threads, st.grain_steps / st.wall_seconds,
                  double(st.newton_iterations) / double(st.grain_solves),
                  double(st.grain_solves) / double(st.grain_steps), st.cutbacks,
                  aggregate->state_bytes_per_grain(), st.wall_seconds);
      std::fflush(stdout);
    }
  }
  return 0;
}

}  // namespace subslip::cli
