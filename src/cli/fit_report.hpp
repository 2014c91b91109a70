// The report of a fit (calibration/contact_fit.hpp) as `subslip fit` prints it: a table, or
// JSON. Compiled once for the program and the Python module, which both print it.
#pragma once

#include <iosfwd>

#include "subslip/calibration/contact_fit.hpp"
#include "subslip/io/fit_file.hpp"

namespace subslip::cli {

// The estimate, standard errors, 95 % intervals (with units), correlations and how the
// optimiser stopped, as a table.
void print_fit_table(std::ostream& out, const io::FitFile& file,
                     const calibration::FitResult& result);

// The same as JSON: estimate, standard_error, interval, unit and correlation (each by constant),
// the warnings, how the optimiser stopped, and every curve's data and fitted f_t/f_n (what
// scripts/fit_report.py draws).
void write_fit_json(std::ostream& out, const io::FitFile& file,
                    const calibration::FitResult& result);

}  // namespace subslip::cli
