#include "fit.hpp"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <stdexcept>

#include "fit_report.hpp"
#include "subslip/calibration/contact_fit.hpp"
#include "subslip/io/fit_file.hpp"

namespace subslip::cli {

namespace {

// Written beside the target and renamed onto it: a failed write leaves no half file.
void write_atomically(const std::string& path, const std::string& text) {
  const std::string partial = path + ".partial";
  {
    std::ofstream out(partial, std::ios::binary);
    out << text;
    out.close();
    if (!out) {
      std::filesystem::remove(partial);
      throw std::runtime_error("cannot write " + path);
    }
  }
  std::filesystem::rename(partial, path);
}

}  // namespace

void add_fit_command(CLI::App& app, FitArgs& a) {
  CLI::App* cmd = app.add_subcommand(
      "fit",
      "Fit the law's constants to measured friction curves or single-crystal stress-strain "
      "curves (FIT.yaml and its CSV files)");
  cmd->add_option("file", a.file, "Fit file (fit: contact or fit: crystal)")->required();
  cmd->add_flag("--json", a.json,
                "Print the report as JSON (estimate, standard_error, interval, correlation, ...)");
  cmd->add_option("-o,--output", a.output,
                  "Also write the JSON report to this file (scripts/fit_report.py draws it)");
}

int run_fit(const FitArgs& a) {
  const io::FitFile f = io::read_fit_file(a.file);
  const auto start = std::chrono::steady_clock::now();
  const calibration::FitResult r = fit_of(f);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::ostringstream json;
  write_fit_json(json, f, r);
  if (!a.output.empty()) write_atomically(a.output, json.str());
  if (a.json) {
    std::cout << json.str();
  } else {
    print_fit_table(std::cout, f, r);
    std::cout << "\n(fitted in " << std::setprecision(3) << seconds << " s)\n";
  }
  for (const auto& w : r.warnings) std::fprintf(stderr, "subslip: warning: %s\n", w.c_str());
  if (!r.converged) {
    std::fprintf(stderr, "subslip: the fit %s\n", r.termination.c_str());
    return 1;
  }
  return 0;
}

}  // namespace subslip::cli
