// subslip fit: the law's constants fitted to measured friction curves or single-crystal curves
// (io/fit_file.hpp reads the problem, calibration/contact_fit.hpp or crystal_fit.hpp solves it).
#pragma once

#include <CLI/CLI.hpp>
#include <string>

namespace subslip::cli {

struct FitArgs {
  std::string file;
  bool json = false;
  std::string output;  // also write the JSON report here (for scripts/fit_report.py)
};

void add_fit_command(CLI::App& app, FitArgs& args);
// Exit code 0 when the fit converged, 1 when it did not (the estimate where it stopped is still
// printed).
int run_fit(const FitArgs& args);

}  // namespace subslip::cli
