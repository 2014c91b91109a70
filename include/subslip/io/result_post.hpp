// `subslip post`: reading any subslip result file (contact or crystal, complete or not) without
// knowing its layout in advance, a text summary, CSV export of chosen datasets, and one CSV
// table per case of chosen stored and derived quantities.
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
#include <utility>
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

struct TableOptions {
  std::filesystem::path directory;  // created when missing
  std::string case_name;            // empty: every case
  // Time series relative to the case ("macro/stress", "ratio") and derived quantities
  // (derived_quantities()), in column order.
  std::vector<std::string> quantities;
  // Per-grain quantities of this grain only, one line per row; without it, one line per row
  // and grain (with a `grain` column).
  std::optional<std::size_t> grain;
  bool force = false;  // overwrite existing CSV files
};

// Writes one CSV per case, `<case>.csv`, into options.directory and returns the paths written:
// `step` (the output row), the case's `time`, then the columns of every quantity in order, one
// header field `name [unit]` each (a tensor gives nine, `stress_11 ... stress_33`; a quantity
// per slip system one per system). Macro and per-grain quantities share a table at the
// per-grain rows (output.grains_at may write fewer). Numbers as export_csv writes them. Every
// case, quantity and grain is checked before the first file is written.
std::vector<std::filesystem::path> export_table(const std::filesystem::path& file,
                                                const TableOptions& options);

// The derived quantities export_table computes (crystal/measures.hpp): path and description.
std::vector<std::pair<std::string, std::string>> derived_quantities();

}  // namespace subslip::io::post
