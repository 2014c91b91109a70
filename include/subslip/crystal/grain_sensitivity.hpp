// The derivatives of a grain's state with respect to the constants of its phase's law: what a
// path of implicit grain steps carries for forward sensitivities (point::GrainPoint's update with
// a GrainSensitivity; docs/calibration.md, "Sensitivities of a grain").
#pragma once

#include <Eigen/Core>
#include <vector>

#include "subslip/crystal/crystal_kernel.hpp"
#include "subslip/law/parameter_table.hpp"

namespace subslip::crystal {

// The columns: the law's constants in the order of law::kLawParameters, then tau0 (every
// system's reference stress, one value) and the initial friction coefficient (a phase's
// `initial_mu`; its column stays zero where the phase starts from mu_s).
inline constexpr int kTau0Column = law::kParameterCount;
inline constexpr int kInitialMuColumn = law::kParameterCount + 1;
inline constexpr int kGrainParameterCount = law::kParameterCount + 2;

template <int Rows>
using GrainGradients = Eigen::Matrix<double, Rows, kGrainParameterCount>;
// One row per slip system.
using SlipGradients = Eigen::Matrix<double, Eigen::Dynamic, kGrainParameterCount, 0,
                                    kMaxSlipSystems, kGrainParameterCount>;

struct GrainSensitivity {
  GrainGradients<6> stress = GrainGradients<6>::Zero();  // lattice frame, Mandel [stress/unit]
  // Of the sample-frame stress (GrainState::sample_stress) [stress/unit].
  GrainGradients<6> sample_stress = GrainGradients<6>::Zero();
  GrainGradients<9> orientation = GrainGradients<9>::Zero();  // g's entries, column by column
  SlipGradients mu, r_s, slip;                                // per system
};

// Mixed control of a step: the components u of the velocity gradient along `directions`
// (dL/du_k, sample frame) are what a driver solves for so that the sample-frame Cauchy stress
// components `held` (Mandel indices, one per direction) keep their prescribed values. The
// constants then move the step's L as well: du/dp = -(d sigma_held/du)^-1 d sigma_held/dp at
// fixed u, and the carried sensitivities include that change (the total derivative along the
// mixed-controlled path); `free_gradient` receives du/dp (a row per direction) [1/time/unit].
struct MixedControlSensitivity {
  std::vector<Mat3> directions;
  std::vector<int> held;
  Eigen::Matrix<double, Eigen::Dynamic, kGrainParameterCount> free_gradient;
};

}  // namespace subslip::crystal
