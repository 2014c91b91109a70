// subslip accuracy: the work-precision study of a scene (error against run time for every
// integrator; see include/subslip/study/work_precision.hpp and docs/accuracy.md).
#pragma once

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

namespace subslip::cli {

struct AccuracyArgs {
  std::string scene;
  std::string output;  // directory; empty: results/accuracy_<scene stem>
  bool force = false;
  bool quiet = false;
  std::vector<std::string> cases;  // empty: every case
  std::vector<std::string> integrators{"forward_euler",  "implicit",       "implicit_adaptive",
                                       "extrapolated_2", "extrapolated_3", "extrapolated_4",
                                       "cvode"};
  // Increment factors relative to the scene's increments (fixed-step ladders).
  std::vector<double> forward_euler;  // empty: 1, 4, 16, ... until the run-time budget
  bool fe_uniform = false;            // forward Euler with uniform increments
  std::vector<double> implicit{0.25, 0.5, 1.0, 2.0, 4.0, 8.0};
  std::vector<double> adaptive{1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7};
  std::vector<double> extrapolated{1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9};
  std::vector<double> cvode{1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9};
  double reference_factor = 0.0;        // 0: 16 x the largest implicit factor
  double reference_tolerance = 0.0;     // > 0: an adaptive reference instead
  int reference_order = 1;              // of the adaptive reference (2 .. 4: extrapolated)
  bool reference_at_run_times = false;  // crystal: the reference recomputed at each run's times
  std::string measure = "state";        // crystal: "state" (r, ln CRSS, r_s) or "stress"
  double cvode_atol = 1e-10;            // atol_scale of the CVODE ladder (at most the rtol)
  double cvode_check_rtol = 1e-12;
  double cvode_check_seconds = 120.0;
  int repeat = 5;
  double repeat_budget = 5.0;     // seconds of repeated runs per point
  double max_run_seconds = 30.0;  // ladder points predicted slower are skipped
  int threads = 1;
  bool no_plot = false;
};

void add_accuracy_command(CLI::App& app, AccuracyArgs& args);
int run_accuracy(const AccuracyArgs& args);

}  // namespace subslip::cli
