// A calibration problem from a FIT.yaml (`fit: contact`) and its measured curves, CSV files
// beside it: what `subslip fit` and the Python module's fit read (docs/calibration.md). Every
// problem with the input is one InputError naming the file, the line and the key or column.
#pragma once

#include <filesystem>
#include <string>

#include "subslip/calibration/contact_fit.hpp"
#include "subslip/io/yaml_checked.hpp"
#include "subslip/model/units.hpp"

namespace subslip::io {

struct FitFile {
  std::string file;   // as given
  std::string title;  // "" when it has none
  model::Units units;
  calibration::FitProblem problem;
};

FitFile read_fit_file(const std::filesystem::path& path);

// One measured curve: a header naming the columns `slip [LENGTH]` and `ratio [-]` (f_t/f_n; other
// columns are ignored), then one row per point, comma-separated; `#` starts a comment line.
// Distances are converted from the header's length unit to `units`' and must be positive and
// increasing; every value finite.
calibration::Curve read_curve_csv(const std::filesystem::path& path, const model::Units& units);

}  // namespace subslip::io
