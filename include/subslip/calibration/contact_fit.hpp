// Calibrating the law of a frictional contact on measured friction curves: f_t/f_n against the
// sliding distance from rest, one curve per sliding speed. The law's free constants are fitted
// by bounded trust-region least squares (Ceres), with the Jacobian from the forward
// sensitivities of the contact path (history::run_history with sensitivities), not from finite
// differences; the estimate comes with standard errors, 95 % intervals and correlations, and
// with a warning for every constant the data do not determine. io/fit_file.hpp reads a problem
// from a FIT.yaml and its CSV curves; docs/calibration.md is the tutorial.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "subslip/calibration/least_squares.hpp"
#include "subslip/contact/contact_point.hpp"
#include "subslip/law/parameter_table.hpp"

namespace subslip::calibration {

// One measured curve: f_t/f_n at sliding distances from rest at one sliding speed.
struct Curve {
  std::string name;           // where it came from (a file), for messages and reports
  double speed = 0.0;         // [length/time], > 0
  std::vector<double> slip;   // [length], > 0 and increasing
  std::vector<double> ratio;  // f_t/f_n [-]
  double weight = 1.0;        // of each point's squared residual
};

// How each curve's contact path is computed: from rest, `increments` implicit steps of growing
// length (ratio `growth`) to its last point, split to end on every measured distance.
struct PathSteps {
  int increments = 300;
  double growth = 1.02;
  double residual_tolerance = 1e-12;
};

struct FitProblem {
  contact::ContactModel model;     // the law holds the free constants' starts and the fixed ones
  bool initial_mu_is_mu_s = true;  // the contact starts at mu = mu_s (else model's initial mu)
  std::vector<FreeParameter> free;
  std::vector<Curve> curves;
  PathSteps steps;
  int max_iterations = 100;
};

// The model's f_t/f_n at a curve's distances and its derivatives with respect to the law's
// constants (a row per point, columns in the order of law::kLawParameters).
struct Prediction {
  std::vector<double> ratio;
  Eigen::Matrix<double, Eigen::Dynamic, law::kParameterCount> gradient;
};
Prediction predict(const contact::ContactModel& model, bool initial_mu_is_mu_s, const Curve& curve,
                   const PathSteps& steps);

// Fits the problem. Throws std::invalid_argument for a problem that cannot be set up (a start
// outside its bounds, no points, no free constant).
FitResult fit(const FitProblem& problem);

}  // namespace subslip::calibration
