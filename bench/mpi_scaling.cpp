// subslip_mpi_scaling: a Taylor aggregate over MPI ranks (docs/scaling.md): the time
// per increment for strong scaling (a fixed aggregate) or weak scaling (fixed grains per rank),
// the cost of the collectives every increment needs (the exact-sum allreduce of the stress
// average, of stress and tangent under mixed control, the collective write of one output
// state into a result file by every rank (parallel HDF5; its block of grains), and the gather
// of one output state and of one checkpoint to the root (--gather-output)), and the memory per
// grain. A report, not a test.
//
// Usage (one line of a Markdown table on the root; --header prints the table's head):
//   mpirun -np R build/bench/subslip_mpi_scaling [--grains 20000] [--weak] [--increments 30]
//          [--lattice fcc] [--mixed] [--repeats 200] [--scratch DIR]
// --weak: --grains per rank. OMP_NUM_THREADS sets the threads per rank. Loading: D = 1e-3/s
// diag(1, -1/2, -1/2) at strain steps of 1e-4, L fully prescribed (--mixed: the lateral
// stresses free, as inputs/default.yaml).
#include <omp.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <vector>

#include "subslip/crystal/phase_builder.hpp"
#include "subslip/crystal/texture.hpp"
#include "subslip/io/h5_writer.hpp"
#include "subslip/parallel/team.hpp"
#include "subslip/study/bench_phase.hpp"

using namespace subslip;

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// The slowest rank's value (what the run waits for).
double slowest(const parallel::Team& team, double mine) {
  std::array<double, 1> v{mine};
  team.max(v);
  return v[0];
}

// The median over `repeats` of the slowest rank's time of `work` (after a synchronising
// reduction, so that every rank starts together).
template <class Work>
double median_time(const parallel::Team& team, int repeats, Work&& work) {
  std::vector<double> t;
  for (int k = 0; k < repeats; ++k) {
    slowest(team, 0.0);
    const auto start = Clock::now();
    work();
    t.push_back(slowest(team, seconds_since(start)));
  }
  std::nth_element(t.begin(), t.begin() + static_cast<long>(t.size() / 2), t.end());
  return t[t.size() / 2];
}

std::vector<crystal::LoadSegment> tension(int increments, bool mixed) {
  crystal::LoadSegment s;
  const double rate = 1e-3;
  s.velocity_gradient.diagonal() << -0.5 * rate, -0.5 * rate, rate;
  if (mixed) s.free(0, 0) = s.free(1, 1) = true;  // L_11, L_22 free: zero lateral stress
  s.duration = 0.1 * increments;                  // strain steps of 1e-4
  s.increments = increments;
  s.output_every = increments;
  return {s};
}

// The median time of writing one row of `width` values per grain into a per-grain series of
// a file in `dir`, every rank its block at once (collective writes, as `subslip run` under
// MPI with parallel HDF5); NaN when this HDF5 is serial.
double collective_row_write(const parallel::Team& team, const std::filesystem::path& dir,
                            std::size_t total, std::size_t width, int repeats) {
  namespace h5 = io::h5;
  if (!h5::parallel_hdf5() || team.mpi_communicator() == nullptr) return std::nan("");
  const std::filesystem::path path = dir / "subslip_mpi_scaling_write.h5";
  parallel::on_root(team, [&] {  // the layout, by one process (as a run's)
    h5::File f = h5::File::create(path, true);
    const auto rows = static_cast<std::size_t>(repeats);
    f.root().create_series(
        {"field", 0, h5::Type::float64, "1", "timing", rows, 1, rows, {total, width}});
    f.close();
  });
  const h5::MpiAccess mpi{team.mpi_communicator(), team.rank()};
  double t = 0.0;
  {
    h5::File f = h5::File::open_write(path, &mpi);
    {
      h5::Series series = f.root().open_series("field", h5::Type::float64, 0, 1);
      const parallel::Block mine = parallel::block_of(total, team.rank(), team.size());
      series.select_grains(mine.offset, mine.count);
      const std::vector<double> row(mine.count * width, 1.0);
      t = median_time(team, repeats, [&] { series.append(row); });  // (a block of 1: commits)
    }
    f.close();
  }
  parallel::on_root(team, [&] { std::filesystem::remove(path); });
  return t;
}

}  // namespace

int main(int argc, char** argv) {
  parallel::Session session(argc, argv);
  const parallel::Team& team = session.team();
  CLI::App app{"Taylor aggregate over MPI ranks: time per increment and collectives"};
  std::size_t grains = 20000;
  bool weak = false, mixed = false, header = false;
  int increments = 30, repeats = 200;
  std::string lattice = "fcc";
  std::string scratch = ".";
  app.add_option("--grains", grains, "Grains (per rank with --weak)");
  app.add_flag("--weak", weak, "Weak scaling: --grains per rank");
  app.add_option("--increments", increments, "Increments timed");
  app.add_option("--lattice", lattice, "fcc, bcc48 or hcp");
  app.add_flag("--mixed", mixed, "Mixed control: the lateral stresses free");
  app.add_option("--repeats", repeats, "Repeats of each collective (median)");
  app.add_flag("--header", header, "Print the table's head first");
  app.add_option("--scratch", scratch, "Directory of the collective write's file");
  CLI11_PARSE(app, argc, argv);

  const std::size_t total = weak ? grains * static_cast<std::size_t>(team.size()) : grains;
  const auto aggregate = crystal::build_taylor_aggregate(
      study::bench_phase(lattice), crystal::random_orientations(total, 1), team);
  crystal::AggregateOptions options;
  const auto start = Clock::now();
  const crystal::AggregateStats stats =
      aggregate->run(tension(increments, mixed), options,
                     [](const crystal::MacroState&, const crystal::GrainFields&) {});
  const double run = slowest(team, seconds_since(start));

  // The collectives of one increment, alone.
  std::array<parallel::ExactSum, 6> stress;
  std::array<parallel::ExactSum, 42> stress_and_tangent;
  for (auto& s : stress) s.add(1.0 + team.rank());
  for (auto& s : stress_and_tangent) s.add(1.0 + team.rank());
  const double allreduce6 = median_time(team, repeats, [&] {
    auto copy = stress;
    team.sum(copy);
  });
  const double allreduce42 = median_time(team, repeats, [&] {
    auto copy = stress_and_tangent;
    team.sum(copy);
  });
  const auto n = static_cast<std::size_t>(aggregate->slip_count());
  const auto mine = static_cast<std::size_t>(aggregate->grain_count());
  const auto gather = [&](std::size_t width) {
    std::vector<double> block(mine * width, 1.0), all(team.is_root() ? total * width : 0);
    return median_time(team, std::max(3, repeats / 20),
                       [&] { team.gather_rows(block, all, width); });
  };
  const std::size_t output_width = 6 + 9 + 5 * n;  // every per-grain output field
  const double output = gather(output_width);
  const double written =
      collective_row_write(team, scratch, total, output_width, std::max(3, repeats / 20));
  const double checkpoint =
      gather(static_cast<std::size_t>(crystal::checkpoint_values_per_grain(static_cast<int>(n))));

  if (!team.is_root()) return 0;
  if (header) {
    std::printf(
        "| ranks | threads/rank | grains | grains/rank | control | increments | s/increment "
        "| grain-steps/s | newton/solve | allreduce 6 [us] | allreduce 42 [us] | write "
        "output [ms] | gather output [ms] | gather checkpoint [ms] | bytes/grain (state) |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  }
  std::printf(
      "| %d | %d | %zu | %zu | %s | %ld | %.4g | %.3g | %.2f | %.1f | %.1f | %.2f | %.2f | %.2f "
      "| %zu |\n",
      team.size(), omp_get_max_threads(), total, mine, mixed ? "mixed" : "prescribed",
      stats.increments, run / static_cast<double>(stats.increments),
      static_cast<double>(stats.grain_steps) / run,
      static_cast<double>(stats.newton_iterations) /
          static_cast<double>(std::max(1L, stats.grain_solves)),
      1e6 * allreduce6, 1e6 * allreduce42, 1e3 * written, 1e3 * output, 1e3 * checkpoint,
      aggregate->memory_bytes_per_grain());
  return 0;
}
