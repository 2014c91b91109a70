// A calibration problem from a FIT.yaml and its measured curves, CSV files beside it: what
// `subslip fit` and the Python module's fit read (docs/calibration.md). `fit: contact` fits the
// friction law to friction curves (calibration/contact_fit.hpp); `fit: crystal` fits the law of a
// crystal's slip systems to single-crystal stress-strain curves (calibration/crystal_fit.hpp).
// Every problem with the input is one InputError naming the file, the line and the key or column.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "subslip/calibration/contact_fit.hpp"
#include "subslip/calibration/crystal_fit.hpp"
#include "subslip/io/yaml_checked.hpp"
#include "subslip/model/units.hpp"

namespace subslip::io {

enum class FitKind { contact, crystal };

struct FitFile {
  std::string file;   // as given
  std::string title;  // "" when it has none
  FitKind kind = FitKind::contact;
  model::Units units;                      // a crystal fit's has no length
  calibration::FitProblem problem;         // fit: contact
  calibration::CrystalFitProblem crystal;  // fit: crystal
  // fit: crystal: each curve's orientation as written, Bunge Euler angles [phi1, Phi, phi2]
  // [deg] (the report repeats them).
  std::vector<Eigen::Vector3d> euler_degrees;
};

FitFile read_fit_file(const std::filesystem::path& path);

// One measured friction curve: a header naming the columns `slip [LENGTH]` and `ratio [-]`
// (f_t/f_n; other columns are ignored), then one row per point, comma-separated; `#` starts a
// comment line. Distances are converted from the header's length unit to `units`' and must be
// positive and increasing; every value finite.
calibration::Curve read_curve_csv(const std::filesystem::path& path, const model::Units& units);

// One measured single-crystal curve, laid out as read_curve_csv's: the columns `strain [-]` (the
// logarithmic axial strain ln F11) and `stress [STRESS]` (the axial Cauchy stress sigma11,
// converted from the header's stress unit to `units`'). Strains must be nonzero, of the sign of
// `strain_rate` [1/time] and increasing in magnitude; every value finite. The orientation,
// rate and weight are the fit file's to set.
calibration::CrystalCurve read_crystal_curve_csv(const std::filesystem::path& path,
                                                 const model::Units& units, double strain_rate);

}  // namespace subslip::io
