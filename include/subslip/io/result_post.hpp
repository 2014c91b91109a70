// `subslip post`: reading any subslip result file (contact or crystal, complete or not) without
// knowing its layout in advance, a text summary, and CSV export of chosen datasets.
//
// Errors: a path that is not a subslip result file, an unknown case or dataset, a dataset that
// holds text, or a grain out of range throw subslip::InputError (the command line exits with 2);
// an existing CSV without `force`, or a directory that cannot be created, throw
// h5::OutputPathError (also 2). Every request is checked before the first CSV is written.
#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

namespace subslip::io::post {

// Writes the summary of `file` to `out`: format, version, scene kind, title, completed flag,
// units, and for each case (only `case_name` when it is not empty) its attributes with their
// units and every dataset with shape, unit and description.
void print_summary(std::ostream& out, const std::filesystem::path& file,
                   const std::string& case_name = "");

struct CsvOptions {
  std::filesystem::path directory;  // created when missing
  std::string case_name;            // empty: every case
  // Paths relative to a case group ("macro/stress", "ratio", "grains") or absolute
  // ("/cases/base/macro/stress"); a group stands for every dataset below it. Empty: every
  // numeric dataset of the selected case(s).
  std::vector<std::string> datasets;
  // For per-grain series [n, G, k]: write only this grain, one row per step ("wide"); without
  // it, one row per (step, grain) ("long" format, with a `grain` column).
  std::optional<std::size_t> grain;
  bool force = false;  // overwrite existing CSV files
};

// Writes one CSV per (case, dataset) into options.directory and returns the paths written, in
// order. One header line names each column and its unit, `name [unit]`; time series start with
// `step` (row index) and the case's `time` column. Numbers are written in the shortest form
// that reads back to the same double.
std::vector<std::filesystem::path> export_csv(const std::filesystem::path& file,
                                              const CsvOptions& options);

}  // namespace subslip::io::post
