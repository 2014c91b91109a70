// Warnings for scenes that are legal but probably not what the user wants (large increments,
// forward Euler beyond its stability estimate, huge outputs, extreme law constants, a long run
// without checkpoints, magnitudes that look written in another unit than the scene's). Each
// warning is one line naming the scene file (and the line, for a value), the key and, in a
// sweep, the cases it concerns; the command line prints them to stderr as "warning: ...".
#pragma once

#include <string>
#include <vector>

#include "subslip/io/contact_scene.hpp"
#include "subslip/io/crystal_scene.hpp"

namespace subslip::io {

// Where the values of one kind lie in practice, in SI units (Pa, m/s, 1/s, s).
struct PlausibleRange {
  double lo;
  double hi;
};

struct WarningLimits {
  double strain_increment = 1e-2;       // largest prescribed |L_ij| dt of one increment
  double output_bytes = 2e9;            // estimated size of the per-grain series of a case
  double power_exponent = 64.0;         // n of the power overstress form
  double r_hat_margin = 0.02;           // r_hat - 1
  double stiffness_over_tau0 = 1e5;     // largest elastic constant / smallest tau0
  double grain_steps_checkpoint = 5e8;  // a case this long (grains x increments) wants checkpoints
  // Plausible magnitudes: a value outside was probably written in another unit than the
  // scene's (168 for copper's C11 in an MPa scene). Elastic constants: potassium's C11 is 3.7
  // GPa, diamond's 1079 GPa (the lower limit applies to the largest constant of a phase, since
  // C12 or C13 may be small). tau0: soft single crystals ~0.1-1 MPa, the ideal shear strength
  // of the stiffest metals a few GPa. Sliding speeds: from geological creep to impacts.
  PlausibleRange elastic_constant{1e9, 2e12};  // Pa
  PlausibleRange tau0{1e4, 5e9};               // Pa
  PlausibleRange normal_traction{10.0, 5e9};   // Pa
  PlausibleRange sliding_speed{1e-12, 100.0};  // m/s
  PlausibleRange strain_rate{1e-12, 1e6};      // 1/s (prescribed velocity-gradient components)
  PlausibleRange duration{1e-9, 1e9};          // s (a segment, 30 years at most)
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
