// Warnings for scenes that are legal but probably not what the user wants (large increments,
// forward Euler beyond its stability estimate, huge outputs, extreme law constants, a long run
// without checkpoints). Each warning is one line naming the scene file, the key and, in a
// sweep, the cases it concerns; the command line prints them to stderr as "warning: ...".
#pragma once

#include <string>
#include <vector>

#include "subslip/io/contact_scene.hpp"
#include "subslip/io/crystal_scene.hpp"

namespace subslip::io {

struct WarningLimits {
  double strain_increment = 1e-2;       // largest prescribed |L_ij| dt of one increment
  double output_bytes = 2e9;            // estimated size of the per-grain series of a case
  double power_exponent = 64.0;         // n of the power overstress form
  double r_hat_margin = 0.02;           // r_hat - 1
  double stiffness_over_tau0 = 1e5;     // largest elastic constant / smallest tau0
  double grain_steps_checkpoint = 5e8;  // a case this long (grains x increments) wants checkpoints
};

// `checkpoints`: whether the run will write checkpoints.
std::vector<std::string> crystal_scene_warnings(const CrystalScene& scene, bool checkpoints,
                                                const WarningLimits& limits = {});
std::vector<std::string> contact_scene_warnings(const ContactScene& scene,
                                                const WarningLimits& limits = {});

// The stability estimate of forward Euler at steady sliding with slip rate v, f_n and elastic
// modulus k (alpha_t, or P:C:P for a slip system): 2 / lambda, lambda = k / (f_n mu)
// dphi/dr at the steady state. Infinite when nothing limits the step (no sliding).
double forward_euler_step_limit(const law::LawParameters& law, double v, double stiffness,
                                double normal_traction);

}  // namespace subslip::io
