// Writing a work-precision study (subslip accuracy) into a directory:
//
//   accuracy.csv            one row per run: case, integrator, setting, increments, steps,
//                           rejected, newton_iterations, cutbacks, max_error, end_error,
//                           median_time_s, repeats, status, failure
//   accuracy_reference.csv  one row per case: the quantity, error scale and reference checks
//   accuracy.md             the same tables in Markdown, and the time each integrator needs to
//                           reach a given error
//   accuracy.h5             the tables as datasets with `unit` attributes, and the reference
//                           paths (layout in docs/scenes.md, "Accuracy study files")
//
// The plot (accuracy_<case>.png) is drawn by scripts/plot_accuracy.py from the two CSV files.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "subslip/io/scene_common.hpp"
#include "subslip/study/work_precision.hpp"

namespace subslip::io {

struct AccuracyCase {
  std::string name;           // the scene case
  std::string quantity_unit;  // "1" (f_t/f_n) or the stress unit
  study::StudyResult result;
};

struct AccuracyReport {
  std::string scene_file;  // as given
  std::string scene_text;  // verbatim
  std::string scene_kind;  // contact | crystal
  std::string title;
  std::vector<std::pair<std::string, std::string>> units;  // the scene's units
  double cvode_check_rtol = 0.0;
  double cvode_atol = 0.0;  // the CVODE ladder's atol_scale (at most its rtol)
  int threads = 1;
  std::vector<AccuracyCase> cases;
};

// The files of a study in `dir`, in the order above.
std::vector<std::filesystem::path> accuracy_files(const std::filesystem::path& dir);

// Call before any computation: refuses existing study files in `dir` unless `overwrite`
// (h5::OutputPathError), creates `dir`, and proves it writable.
void check_accuracy_output(const std::filesystem::path& dir, bool overwrite);

// Writes accuracy.csv, accuracy_reference.csv, accuracy.md and accuracy.h5 into `dir`.
void write_accuracy_report(const std::filesystem::path& dir, const AccuracyReport& report);

// The error levels of the "time to reach an error" table: the decades from the largest maximum
// error measured (at most 1e-1) down to the smallest.
std::vector<double> error_levels(const study::StudyResult& study);

}  // namespace subslip::io
