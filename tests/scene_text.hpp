// Test helper: the YAML text several tests' scenes share (contact: units, the law, the contact;
// crystal: units and the copper phase), so that each test spells out only what it varies.
#pragma once

#include <string>
#include <string_view>

namespace subslip::testing {

// `units:` and the `law:` block: rate-dependent subloading friction (mu_s 0.097, mu_k 0.085) with
// the exponential overstress.
inline constexpr char kContactUnitsAndLaw[] = R"(units: {stress: MPa, length: mm, time: min}
law:
  friction: {mu_s: 0.097, mu_k: 0.085, kappa: 0.2, xi: 0.009}
  subloading: {function: cot, u_tilde: 80}
  overstress: {form: exponential, eta_v: 950, n: 16, r_hat: 1.8}
)";

// A stiff contact (alpha 1e6 MPa/mm) under 5.56 MPa.
inline constexpr char kStiffContact[] =
    "contact: {alpha_n: 1.0e6, alpha_t: 1.0e6, normal_traction: 5.56}\n";

// A contact scene up to its `loading:`: `scene: contact`, then `header` (e.g. a title line),
// the units, the law and the stiff contact.
inline std::string contact_scene_start(std::string_view header = "") {
  return "scene: contact\n" + std::string(header) + kContactUnitsAndLaw + kStiffContact;
}

// The copper phase of inputs/default.yaml: the `phase:` block (its kinematics may follow).
inline constexpr char kCopperPhase[] = R"(phase:
  families: [fcc_111_110]
  elasticity: {type: cubic, C11: 168400, C12: 121400, C44: 75400}
  tau0: 10.0
  law:
    friction: {mu_s: 1.6, mu_k: 14.8, kappa: 20.0, xi: 0.0}
    subloading: {function: cot, u_tilde: 200}
    overstress: {form: exponential, eta_v: 1.0e-3, n: 16, r_hat: 1.6}
)";

// A crystal scene up to its orientations: `scene: crystal`, then `header` (e.g. a title line),
// the units (MPa, s) and the copper phase.
inline std::string copper_scene_start(std::string_view header = "") {
  return "scene: crystal\n" + std::string(header) + "units: {stress: MPa, time: s}\n" +
         kCopperPhase;
}

// A crystal scene up to its loading: the soft magnesium case of
// inputs/extreme/crystal_hcp_families.yaml, slip on `families` only (e.g. "hcp_basal_a"),
// tau0 = 0.163 MPa (G/tau0 = 1e5), finite rotation, eight random grains (seed 6).
inline std::string soft_magnesium_scene_start(std::string_view families) {
  return R"(scene: crystal
units: {stress: MPa, time: s}
phase:
  families: [)" +
         std::string(families) +
         R"(]
  c_over_a: 1.624
  elasticity: {type: hexagonal, C11: 59500, C12: 26100, C13: 21800, C33: 65600, C44: 16300}
  tau0: 0.163
  law:
    friction: {mu_s: 1.0, mu_k: 3.0, kappa: 10.0, xi: 0.0}
    subloading: {function: cot, u_tilde: 200}
    overstress: {form: exponential, eta_v: 1.0e-3, n: 16, r_hat: 1.6}
  kinematics: finite_rotation
orientations:
  random: {count: 8, seed: 6}
)";
}

}  // namespace subslip::testing
