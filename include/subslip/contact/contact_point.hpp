// One frictional contact point (paper section 2): traction, contact stiffness, the description
// of a prescribed sliding history, and the step updates of the two integrators. Driving a point
// along a history (cutbacks, adaptive steps, output) is history/contact_history.hpp, which takes
// every step through point::ContactPoint (material_point.hpp).
//
// Frame: the contact normal n is fixed (e3); the tangential plane is spanned by e1, e2. Normal
// traction f_n is positive in compression (paper 2.13), normal sliding velocity v_n positive
// when the bodies approach (2.3).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "subslip/integrators/step_control.hpp"
#include "subslip/law/parameter_table.hpp"
#include "subslip/law/subloading_friction.hpp"

namespace subslip::contact {

using Vec2 = Eigen::Vector2d;

// Contact elastic modulus tensor C^e = alpha_n n(x)n + alpha_t (I - n(x)n) (2.18).
struct ContactStiffness {
  double alpha_n = 1.0e6;  // [stress/length]
  double alpha_t = 1.0e6;  // [stress/length]
};

enum class NormalControl { traction, velocity };

// One segment of a prescribed history. Within a segment the tangential sliding velocity is
// constant (zero for a hold); the normal side either ramps the normal traction linearly to
// `normal_traction` at the segment end or approaches at `normal_velocity`.
struct Segment {
  Vec2 velocity = Vec2::Zero();  // tangential sliding velocity [length/time]
  double duration = 0.0;         // [time]
  NormalControl normal_control = NormalControl::traction;
  double normal_traction = 0.0;  // end value when normal_control == traction [stress]
  double normal_velocity = 0.0;  // when normal_control == velocity [length/time]
  int increments = 1;            // number of increments in the segment
  double growth = 1.0;           // ratio of successive increment lengths (1: uniform)
  int output_every = 1;          // write every k-th increment (and always the last)
  // Output at chosen times instead (output_at_times): only at these times into the segment
  // (increasing, in (0, duration]), which the steps end on exactly: a fixed increment is split,
  // an adaptive step shortened. None: no output in this segment.
  bool output_at_times = false;
  std::vector<double> output_times;
};

// The increment lengths of a segment: `increments` lengths in geometric progression with ratio
// `growth`, summing to `duration` exactly.
std::vector<double> increment_lengths(const Segment& s);

struct ContactState {
  double time = 0.0;
  Vec2 slip = Vec2::Zero();  // total tangential sliding displacement
  double slip_path = 0.0;    // accumulated |du_t|
  double vp_slip = 0.0;      // accumulated viscoplastic sliding |du_vp|
  double vp_rate = 0.0;      // viscoplastic sliding rate of the last increment
  Vec2 traction_t = Vec2::Zero();
  double traction_n = 0.0;  // f_n, compression positive
  law::LawState law;
  double r = 0.0;  // dynamic loading ratio f_t / (f_n mu)

  double traction_ratio() const { return traction_n > 0.0 ? traction_t.norm() / traction_n : 0.0; }
};

// The two updates of a contact point: forward Euler (paper section 2f, method 2) and the implicit
// update (backward Euler of the flow rule with radial return).
enum class Method { forward_euler, implicit };

// The outcome of one attempted update, without cut-back.
struct StepAttempt {
  ContactState state;
  int iterations = 0;
  bool ok = false;
  std::string why;  // when !ok
};

// One forward-Euler update (paper section 2f, method 2) over dt with tangential sliding du_t
// and end-of-step normal traction fn1. Not cut back. Refused (ok = false) when dt exceeds the
// stability limit 2/lambda of the sliding traction (lambda = alpha_t phi_r / (f_n mu)), which
// the history driver then cuts back: forward Euler never runs unstable.
StepAttempt forward_euler_step(const law::SubloadingFrictionLaw& law, const ContactStiffness& c,
                               const ContactState& s0, const Vec2& du_t, double fn1, double dt,
                               integrators::ExplicitStability stability =
                                   integrators::ExplicitStability::refuse_unstable_steps);

// The consistent tangent of an implicit update: d f_t(n+1) / d (du_t, f_n(n+1)), columns du_1,
// du_2 [stress/length] and f_n [-].
using ContactTangent = Eigen::Matrix<double, 2, 3>;

// One implicit update: exact mu and r_s updates, radial return of the tangential traction, and
// the flow rule solved as a bracketed scalar equation in the viscoplastic slip increment. With
// `tangent`, its consistent tangent at the step's start point of sliding (a step whose
// traction passes through a lower ratio first, as a reversal does, takes that point as fixed).
StepAttempt implicit_step(const law::SubloadingFrictionLaw& law, const ContactStiffness& c,
                          const ContactState& s0, const Vec2& du_t, double fn1, double dt,
                          double residual_tolerance, ContactTangent* tangent = nullptr);

// The derivatives of a state's variables with respect to the law's constants, each a row in the
// order of law::kLawParameters: what a path of implicit updates carries for forward
// sensitivities. Time, slip and f_n are prescribed: they depend on no constant.
struct ContactSensitivity {
  Eigen::Matrix<double, 2, law::kParameterCount> traction_t =
      Eigen::Matrix<double, 2, law::kParameterCount>::Zero();
  law::ParameterGradient mu = law::ParameterGradient::Zero();
  law::ParameterGradient r_s = law::ParameterGradient::Zero();
  law::ParameterGradient r = law::ParameterGradient::Zero();
  law::ParameterGradient vp_slip = law::ParameterGradient::Zero();
  law::ParameterGradient vp_rate = law::ParameterGradient::Zero();

  // d(f_t/f_n)/d(constants) of `s` (zero where f_t or f_n vanishes).
  law::ParameterGradient traction_ratio(const ContactState& s) const;
};

// The sensitivities of a state before any step: all zero, but for mu = mu_s when the initial
// friction coefficient is the static one (a scene's default).
ContactSensitivity initial_sensitivity(bool initial_mu_is_mu_s);

// One implicit update that also carries the forward sensitivities from s0's to the end state's
// (unchanged when the update fails). At the converged slip ds the flow rule G(ds; p, s0) = 0
// holds, so dds/dp = -(dG/dp + dG/ds0 ds0/dp) / (dG/dds), where dG/dds is the step's own
// Newton slope and the partials come from automatic differentiation of the law's closed forms
// (law/parameter_jet.hpp); the end state then follows from ds as in the update.
StepAttempt implicit_step(const law::SubloadingFrictionLaw& law, const ContactStiffness& c,
                          const ContactState& s0, const Vec2& du_t, double fn1, double dt,
                          double residual_tolerance, ContactTangent* tangent,
                          ContactSensitivity& sensitivity);

// The plastic slip of a forward-Euler step of the rate-independent law from s0 (the multiplier
// (2.44) times dt, with the normal traction rate of the prescribed f_n(n+1) = fn1 > 0); 0 where
// the step does not load. forward_euler_step takes it; the adaptive history driver's error
// estimate takes it as the sliding velocity a step starts with.
double rate_independent_slip(const law::SubloadingFrictionLaw& law, const ContactStiffness& c,
                             const ContactState& s0, const Vec2& du_t, double fn1, double dt);

// The first way `s` leaves the admissible set every update must stay in ("non-finite state",
// "mu <= 0", "r_s < 0", "r_s > r", "r >= r_hat" for the rate-dependent forms, "r_s >= 2 (cot
// branch)"); empty where it is admissible.
std::string admissibility_violation(const law::SubloadingFrictionLaw& law, const ContactState& s);

// The normal traction at time t into a segment that started with fn_start.
double normal_traction_at(const Segment& seg, const ContactStiffness& c, double fn_start, double t);

// A segment's prescribed normal traction, rate (t - zero) at time t into it (`constant` where
// the rate is zero); `zero` is where it crosses zero (which may lie outside the segment). A ramp
// to a traction ends on it exactly (`target` at `end`, the segment's duration).
struct NormalRamp {
  double rate = 0.0;
  double zero = 0.0;
  double constant = 0.0;
  double end = -1.0;  // < 0: no target (a normal velocity)
  double target = 0.0;
  double at(double t) const {
    if (t == end) return target;
    return rate == 0.0 ? constant : rate * (t - zero);
  }
};
NormalRamp normal_ramp(const Segment& seg, const ContactStiffness& c, double fn_start);

struct ContactModel {
  law::LawParameters law;
  law::LawState initial_law_state;
  ContactStiffness stiffness;
  double initial_normal_traction = 0.0;
};

// The state before the first segment: no tangential traction, r = r_s = 0 unless given.
ContactState initial_state(const ContactModel& model);

}  // namespace subslip::contact
