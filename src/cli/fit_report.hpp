// The report of a fit (calibration/contact_fit.hpp, calibration/crystal_fit.hpp) as `subslip fit`
// prints it: a table, or JSON. Compiled once for the program and the Python module, which both
// fit and print it.
#pragma once

#include <iosfwd>

#include "subslip/calibration/contact_fit.hpp"
#include "subslip/io/fit_file.hpp"

namespace subslip::cli {

// Fits the file's problem, of either kind.
calibration::FitResult fit_of(const io::FitFile& file);

// A crystal fit's initial critical resolved shear stress at the estimate: initial_mu tau0, or
// mu_s tau0 where the phase starts from mu_s [the file's stress unit].
double initial_crss(const io::FitFile& file, const calibration::FitResult& result);

// The estimate, standard errors, 95 % intervals (with units), correlations and how the
// optimiser stopped, as a table; for a crystal fit also the initial CRSS.
void print_fit_table(std::ostream& out, const io::FitFile& file,
                     const calibration::FitResult& result);

// The same as JSON: kind ("contact" or "crystal"), estimate, standard_error, interval, unit and
// correlation (each by constant), the warnings, how the optimiser stopped, and every curve's data
// and fit (f_t/f_n against slip; sigma11 against ln F11 with the curve's orientation and strain
// rate, and the initial CRSS, for a crystal fit): what scripts/fit_report.py draws.
void write_fit_json(std::ostream& out, const io::FitFile& file,
                    const calibration::FitResult& result);

}  // namespace subslip::cli
