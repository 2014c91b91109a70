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

}  // namespace subslip::testing
