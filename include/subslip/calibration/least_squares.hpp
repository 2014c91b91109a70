// The bounded least squares every fit of the law shares (the friction fit, contact_fit.hpp; the
// single-crystal fit, crystal_fit.hpp): Ceres' trust region (Levenberg-Marquardt) on the free
// constants, positive ones in log scale, with the Jacobian the caller's model gives (forward
// sensitivities); then standard errors, 95 % intervals and correlations linearised at the
// estimate, and a warning for every constant the data do not determine.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "subslip/law/parameter_table.hpp"

namespace subslip::calibration {

// A constant the fit determines (the others keep their given values). `index` names it in the
// problem's own columns: law::kLawParameters for the friction fit, crystal::GrainGradients'
// columns for the crystal fit.
struct FreeParameter {
  int index = 0;
  double lower = 0.0, upper = 0.0;
  // Fitted as its logarithm (a positive constant: steps are relative, and it stays positive).
  bool log_scale = false;
};

struct FitResult {
  law::LawParameters law;          // the estimate (fixed constants as given)
  std::vector<std::string> names;  // of the free constants, in the problem's `free` order
  std::vector<double> estimate;
  std::vector<double> standard_error;  // linearised, from the residuals' scatter
  std::vector<double> lower, upper;    // 95 % interval (in the fitted scale, mapped back)
  Eigen::MatrixXd correlation;
  bool converged = false;
  std::string termination;  // how the optimiser stopped, and where when it did not converge
  int iterations = 0;
  double residual_sd = 0.0;  // root mean square weighted residual, per degree of freedom
  int points = 0;
  // A constant the data do not determine: which, why, and which data would determine it.
  std::vector<std::string> warnings;
  std::vector<std::vector<double>> fitted;  // the model's values at each curve's points
};

// One measured curve as the least squares see it: its values and a model of them.
struct CurveModel {
  std::vector<double> measured;
  double weight = 1.0;  // of each point's squared residual
  // The model's values at the free constants' `values` (natural scale) into `predicted`, and
  // their derivatives with respect to those values into `gradient` (a row per point, a column
  // per free constant). Throws where the model cannot be computed there.
  std::function<void(const std::vector<double>& values, std::vector<double>& predicted,
                     Eigen::MatrixXd& gradient)>
      predict;
};

struct LeastSquaresProblem {
  std::vector<std::string> names;   // of the free constants
  std::vector<double> start;        // their starts, within the bounds
  std::vector<FreeParameter> free;  // their bounds and scales (index unused here)
  std::vector<CurveModel> curves;
  int max_iterations = 100;
  // Which data would determine the constant `name` where the fit leaves it undetermined.
  std::function<std::string(std::string_view name)> advice;
};

// Fits the problem: every FitResult field but `law`. Throws std::invalid_argument for a problem
// that cannot be set up (no free constant, no more points than constants, a start outside its
// bounds).
FitResult least_squares_fit(const LeastSquaresProblem& problem);

}  // namespace subslip::calibration
