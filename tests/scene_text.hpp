// Test helper: the YAML text of the contact scenes several tests write (units, the law, the
// contact), so that each test spells out only its loading, sweep and output.
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

}  // namespace subslip::testing
