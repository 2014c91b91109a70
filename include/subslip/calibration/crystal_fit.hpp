// Calibrating the law of a crystal's slip systems on measured single-crystal curves: the axial
// stress against the axial strain of uniaxial tests, one curve per orientation. One grain
// (point::GrainPoint) is pulled along sample x at a constant axial rate L11, with the lateral
// stresses sigma22 = sigma33 = 0 (L22 and L33 solved for at every step) and no shear (the other
// components of L zero, as between rigid grips): the loading of the shipped single-crystal
// tension scenes. The law's free constants and the initial friction coefficient are fitted by
// the bounded trust-region least squares of the friction fit (calibration/least_squares.hpp),
// with the Jacobian from the grain's forward sensitivities carried through the mixed control
// (the lateral rates' own change with the constants included), not from finite differences.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "subslip/calibration/least_squares.hpp"
#include "subslip/crystal/grain_sensitivity.hpp"
#include "subslip/material_point.hpp"

namespace subslip::calibration {

// One measured curve of a single crystal: the axial Cauchy stress sigma11 against the
// logarithmic axial strain ln(F11) (= L11 t, L being diagonal), in the crystal's orientation.
struct CrystalCurve {
  std::string name;  // where it came from (a file), for messages and reports
  Eigen::Matrix3d orientation = Eigen::Matrix3d::Identity();  // g: v_crystal = g v_sample
  double strain_rate = 0.0;    // L11 [1/time], nonzero (negative: compression)
  std::vector<double> strain;  // ln(F11) [-]: nonzero, of the rate's sign, |strain| increasing
  std::vector<double> stress;  // sigma11 [stress]
  double weight = 1.0;         // of each point's squared residual
};

// How each curve's path is computed: equal implicit steps of at most |last strain| / increments
// from the virgin grain to the curve's last point, split to end on every measured strain.
struct CrystalPathSteps {
  int increments = 200;
};

// A constant of the grain the fit determines: a law constant (FreeParameter::index in
// law::kLawParameters) or the initial friction coefficient (index crystal::kInitialMuColumn;
// only where the phase gives `initial_mu`). tau0 is never free: scaling tau0 by c and mu_s,
// mu_k, kappa, xi and initial_mu by 1/c leaves every stress unchanged, so only the products
// (the CRSS) are determined.
struct CrystalFitProblem {
  // Its one law (every family's the same, as grain sensitivities need) holds the free constants'
  // starts and the fixed ones.
  point::GrainParameters phase;
  std::vector<FreeParameter> free;
  std::vector<CrystalCurve> curves;
  CrystalPathSteps steps;
  int max_iterations = 100;
};

// The model's sigma11 at a curve's strains and its derivatives with respect to the grain's
// constants (a row per point; columns crystal::GrainGradients' order: the law's constants, tau0,
// initial_mu). Throws std::runtime_error where a step cannot be computed.
struct CrystalPrediction {
  std::vector<double> stress;
  Eigen::Matrix<double, Eigen::Dynamic, crystal::kGrainParameterCount> gradient;
};
CrystalPrediction predict(const point::GrainParameters& phase, const CrystalCurve& curve,
                          const CrystalPathSteps& steps);

// Fits the problem; FitResult::law is the phase's law at the estimate, FitResult::fitted the
// model's sigma11 at each curve's strains. Throws std::invalid_argument for a problem that cannot
// be set up (a start outside its bounds, no points, no free constant, tau0 free, a phase whose
// families differ in law, tau0 or initial_mu).
FitResult fit(const CrystalFitProblem& problem);

}  // namespace subslip::calibration
