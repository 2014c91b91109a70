// The cost of streaming results (docs/internals.md, "Streaming, kills and restarts"): CPU time of
// the main job (inputs/default.yaml) and of one 2000-step contact case
// (inputs/contact_default.yaml) without output, with every output step written, as run
// (WritePacer), and with rows written at the end only. The variants are interleaved and the minimum
// over the repetitions is kept (the machine may be shared); CPU time, not wall time.
//
//   OMP_NUM_THREADS=1 build/bench/subslip_stream_bench [REPETITIONS] [crystal|contact|both]
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "subslip/driver/contact_run.hpp"
#include "subslip/driver/crystal_run.hpp"
#include "subslip/history/contact_history.hpp"
#include "subslip/io/contact_output.hpp"
#include "subslip/io/contact_scene.hpp"
#include "subslip/io/crystal_output.hpp"
#include "subslip/io/crystal_scene.hpp"

using namespace subslip;

namespace {

double cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

// The minimum CPU time of each variant over `reps` interleaved rounds.
std::vector<double> interleaved(int reps, const std::vector<std::function<void()>>& variants) {
  std::vector<double> best(variants.size(), 1e300);
  for (int r = 0; r < reps; ++r) {
    for (std::size_t k = 0; k < variants.size(); ++k) {
      const std::size_t i = (k + static_cast<std::size_t>(r)) % variants.size();
      const double start = cpu_seconds();
      variants[i]();
      best[i] = std::min(best[i], cpu_seconds() - start);
    }
  }
  return best;
}

constexpr double kEveryStep = 0.0;
constexpr double kEndOnly = 1e12;

void bench_crystal(int reps, const std::string& path) {
  const auto scene = io::load_crystal_scene(SUBSLIP_SOURCE_DIR "/inputs/default.yaml");
  const auto& c = scene.cases.at(0);
  auto none = [&] {
    const auto a = crystal::build_taylor_aggregate(c.phase, c.orientations);
    a->run(c.segments, c.options, [](const crystal::MacroState&, const crystal::GrainFields&) {});
  };
  auto written = [&](double ratio) {
    return [&, ratio] {
      io::h5::File f = io::h5::File::create(path, true);
      io::CrystalSinkOptions o;  // no restart file: no checkpoints
      o.write_cost_ratio = ratio;
      io::CrystalResultSink sink(scene, f, o);
      driver::run_crystal_scene(scene, sink);
    };
  };
  const auto t = interleaved(reps, {none, written(kEveryStep),
                                    written(io::h5::WritePacer::kCostRatio), written(kEndOnly)});
  std::printf(
      "inputs/default.yaml, CPU s: no output %.3f | every step %.3f | as run %.3f | end only "
      "%.3f\n",
      t[0], t[1], t[2], t[3]);
}

void bench_contact(int reps, const std::string& path) {
  auto scene = io::load_contact_scene(SUBSLIP_SOURCE_DIR "/inputs/contact_default.yaml");
  scene.cases.resize(1);  // speed 1 mm/min: 2000 increments, 11 fields
  const auto& c = scene.cases.at(0);
  constexpr int inner = 20;
  auto none = [&] {
    for (int i = 0; i < inner; ++i)
      history::run_history(c.model, c.segments, c.integrator,
                           [](const contact::ContactState&, int) {});
  };
  auto written = [&](double ratio) {
    return [&, ratio] {
      for (int i = 0; i < inner; ++i) {
        io::h5::File f = io::h5::File::create(path, true);
        io::ContactSinkOptions o;
        o.write_cost_ratio = ratio;
        io::ContactResultSink sink(scene, f, o);
        driver::ContactRunOptions run;
        run.threads = 1;
        driver::run_contact_scene(scene, sink, run);
      }
    };
  };
  auto t = interleaved(reps, {none, written(kEveryStep), written(io::h5::WritePacer::kCostRatio),
                              written(kEndOnly)});
  for (double& x : t) x /= inner;
  std::printf(
      "contact case of 2000 increments, CPU s: no output %.4f | every step %.4f | as run %.4f "
      "| end only %.4f\n",
      t[0], t[1], t[2], t[3]);
}

}  // namespace

int main(int argc, char** argv) {
  const int reps = argc > 1 ? std::max(1, std::atoi(argv[1])) : 3;
  const std::string which = argc > 2 ? argv[2] : "both";
  const std::string path = (std::filesystem::temp_directory_path() /
                            ("subslip_stream_bench_" + std::to_string(::getpid()) + ".h5"))
                               .string();
  if (which != "contact") bench_crystal(reps, path);
  if (which != "crystal") bench_contact(reps, path);
  std::filesystem::remove(path);
  return 0;
}
