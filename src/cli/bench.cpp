#include "bench.hpp"
#include "validators.hpp"

#include <omp.h>

#include <algorithm>
#include <cstdio>
#include <string>

#include "subslip/crystal/phase_builder.hpp"
#include "subslip/crystal/texture.hpp"
#include "subslip/io/text_layout.hpp"
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

// Compact headers (explained by kLegend) so that the table fits 80 columns.
io::text::Table bench_table(const BenchArgs& a) {
  io::text::Table t({{"phase", 0, true},
                     {"slips", 5},
                     {"grains", 6},
                     {"threads", 7},
                     {"gsteps/s", 8},
                     {"newton", 6},
                     {"solves/step", 6},
                     {"cuts", 5},
                     {"B/grain", 7},
                     {"wall[s]", 7}});
  int longest = 0;
  for (const auto& l : a.lattices) longest = std::max(longest, io::text::display_width(l));
  t.fit_column(0, longest);
  return t;
}

constexpr const char* kLegend =
    "(gsteps/s: grain-steps per second; newton: Newton iterations per grain solve; solves/step: "
    "grain solves per grain-step; cuts: cutbacks; B/grain: state bytes per grain)";

}  // namespace

void add_bench_command(CLI::App& app, BenchArgs& a) {
  CLI::App* cmd = app.add_subcommand(
      "bench", "Grain-steps per second of the crystal kernel (uniaxial tension, strain step 1e-4)");
  cmd->add_option("--grains", a.grains, "random grains per aggregate")->check(cli::positive());
  cmd->add_option("--steps", a.steps, "increments of 1e-4 strain")->check(cli::positive());
  cmd->add_option("--threads", a.threads, "thread counts to run")->check(cli::positive());
  cmd->add_option("--lattice", a.lattices, "fcc, bcc48, hcp")
      ->check(CLI::IsMember(study::bench_lattices()));
  cmd->add_option("--predictor", a.predictor,
                  "mixed control's start: last or trend (as the integrator key `predictor`)")
      ->check(CLI::IsMember({"last", "trend"}));
  cmd->add_option("--stress-tolerance", a.stress_tolerance,
                  "mixed control's free-stress tolerance, relative to the stress scale (as the "
                  "integrator key `stress_tolerance`)")
      ->check(cli::positive());
}

int run_bench(const BenchArgs& a) {
  const io::text::Table t = bench_table(a);
  std::printf("mixed control: predictor %s, stress_tolerance %g (relative)\n", a.predictor.c_str(),
              a.stress_tolerance);
  std::printf("%s\n", t.header().c_str());
  const auto grains = random_orientations(static_cast<size_t>(a.grains), 20000);
  AggregateOptions options;
  options.predictor = a.predictor == "trend" ? MixedPredictor::trend : MixedPredictor::last;
  options.stress_tolerance = a.stress_tolerance;
  for (const auto& lattice : a.lattices) {
    for (int threads : a.threads) {
      omp_set_num_threads(threads);
      auto aggregate = build_taylor_aggregate(study::bench_phase(lattice), grains);
      const AggregateStats st =
          aggregate->run({tension(a.steps)}, options, [](const MacroState&, const GrainFields&) {});
      const auto count = [](auto n) { return std::to_string(n); };
      std::printf("%s\n",
                  t.row({lattice, count(aggregate->slip_count()), count(a.grains), count(threads),
                         t.number(4, st.grain_steps / st.wall_seconds, 4),
                         t.number(5, double(st.newton_iterations) / double(st.grain_solves), 3),
                         t.number(6, double(st.grain_solves) / double(st.grain_steps), 3),
                         count(st.cutbacks), count(aggregate->state_bytes_per_grain()),
                         t.number(9, st.wall_seconds, 3)})
                      .c_str());
      std::fflush(stdout);
    }
  }
  for (const auto& l : io::text::wrap_words(kLegend, io::text::kTextColumns, " "))
    std::printf("%s\n", l.c_str());
  return 0;
}

}  // namespace subslip::cli
