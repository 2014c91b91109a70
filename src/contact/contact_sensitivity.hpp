// The forward sensitivities of one implicit update (contact_point.cpp calls them once the step
// has converged): the step replayed in automatic-differentiation scalars of the law's constants,
// with the converged slip differentiated through the flow rule instead of iterated again.
#pragma once

#include <optional>

#include "subslip/contact/contact_point.hpp"

namespace subslip::contact::detail {

// The converged viscoplastic slip of a sliding step and dG/d(slip) of its flow rule there.
struct SlipRoot {
  double slip;
  double slope;
};

// The sensitivities after an open step (f_n <= 0) from those of s0.
ContactSensitivity open_step_sensitivity(const law::SubloadingFrictionLaw& law,
                                         const ContactState& s0, const ContactSensitivity& d0,
                                         double dt);

// The sensitivities after a step from a closed s0 that ends on the opening (f_n(end) = 0): the
// trial traction slid off, mu softened over that slip (contact_point.cpp, slide_into_opening).
ContactSensitivity opening_step_sensitivity(const law::SubloadingFrictionLaw& law,
                                            const ContactStiffness& c, const ContactState& s0,
                                            const ContactSensitivity& d0, const Vec2& du_t,
                                            double dt);

// The sensitivities after an implicit step from s0 (sensitivities d0) over dt with du_t and
// f_n(end) = fn1 > 0: elastic without a root, sliding by root.slip otherwise.
ContactSensitivity step_sensitivity(const law::SubloadingFrictionLaw& law,
                                    const ContactStiffness& c, const ContactState& s0,
                                    const ContactSensitivity& d0, const Vec2& du_t, double fn1,
                                    double dt, const std::optional<SlipRoot>& root);

}  // namespace subslip::contact::detail
