// Driving one contact point along a prescribed history (contact::Segment): fixed increments cut
// back where an update fails, or adaptive steps (backward Euler with its local error estimate, or
// backward Euler extrapolated), and the output states the segments ask for. Every step is one
// update of a point::ContactPoint (material_point.hpp); the contact layer below holds the
// updates themselves.
#pragma once

#include <functional>
#include <limits>
#include <stdexcept>
#include <vector>

#include "subslip/contact/contact_point.hpp"
#include "subslip/material_point.hpp"

namespace subslip::history {

struct IntegratorOptions {
  contact::Method method = contact::Method::implicit;
  int max_cutbacks = 40;              // halvings of one increment before giving up
  double residual_tolerance = 1e-12;  // implicit: |G| in traction-ratio units
  // With a tolerance, the steps are solved to tolerance / 100 where that is tighter than
  // residual_tolerance (integrators/inner_tolerance.hpp); false: to residual_tolerance as given
  // (a scene that names its residual_tolerance).
  bool residual_follows_tolerance = true;
  // Adaptive stepping (implicit only) when > 0: the local error of each step, estimated as
  // dt/2 |rate of f_t at the end - at the start| in units of the yield traction f_n mu, is kept
  // below `tolerance`; the step grows and shrinks with it. A segment's increments then only
  // set its first step, and every accepted step is an increment (output_every applies).
  double tolerance = 0.0;
  // With a tolerance: 1 is backward Euler with the estimate above (its error follows the square
  // root of the tolerance); 2 .. 4 is backward Euler extrapolated to that order
  // (integrators/extrapolation.hpp: every step taken with 1, 2, .., order substeps and
  // combined), whose estimate is the difference of its two best solutions in units of the yield
  // traction (traction, mu relative, r_s) and whose error follows the tolerance.
  int order = 1;
};

// The flow-rule tolerance the history's steps are solved to (residual_follows_tolerance).
double effective_residual_tolerance(const IntegratorOptions& opt);

// The contact point a history with these options steps: the model's law and stiffness, the
// options' update and flow-rule tolerance, no tangent (the history needs none).
point::ContactParameters point_parameters(const contact::ContactModel& model,
                                          const IntegratorOptions& opt);

// Work done by one increment, for reporting.
struct StepStats {
  int iterations = 0;  // Newton iterations (implicit) or 0
  int cutbacks = 0;    // halvings needed
  int substeps = 1;    // sub-increments actually taken
};

// Advances `point` over one increment of `seg` (of length dt, starting t_in_segment into it;
// the segment started at normal traction fn_start), halving it when an update fails
// (non-finite, out of the admissible set r_s <= r < r_hat, or no convergence). Throws
// StepFailure when opt.max_cutbacks halvings do not help.
struct StepFailure : std::runtime_error {
  explicit StepFailure(const std::string& what,
                       double smallest_tolerance = std::numeric_limits<double>::quiet_NaN())
      : std::runtime_error(what), smallest_tolerance(smallest_tolerance) {}
  // Where an adaptive run stopped at its error estimate's noise floor: the tolerance the message
  // names, from which on the floor no longer stops it; NaN for every other failure.
  double smallest_tolerance;
};
contact::ContactState advance(const point::ContactPoint& point, const IntegratorOptions& opt,
                              const contact::ContactState& s0, const contact::Segment& seg,
                              double fn_start, double t_in_segment, double dt, StepStats& stats);

struct RunStats {
  long increments = 0;
  long substeps = 0;
  long rejected = 0;  // adaptive steps refused by the error estimate (redone smaller)
  long iterations = 0;
  long cutbacks = 0;
  double wall_seconds = 0.0;
};

// Runs a whole history from contact::initial_state(model). `on_output(state, segment_index)` is
// called for the initial state (segment -1) and then at every output increment.
using OutputCallback = std::function<void(const contact::ContactState&, int segment)>;
RunStats run_history(const contact::ContactModel& model,
                     const std::vector<contact::Segment>& segments, const IntegratorOptions& opt,
                     const OutputCallback& on_output);

// run_history carrying the forward sensitivities of the state to the law's constants
// (contact::ContactSensitivity) along the steps it takes, from contact::initial_sensitivity:
// `on_output(state, sensitivities, segment)`. Fixed increments of the implicit update only
// (std::invalid_argument otherwise): adaptive steps depend on the constants through their error
// control, which derivatives along the steps taken do not see.
using SensitivityCallback = std::function<void(const contact::ContactState&,
                                               const contact::ContactSensitivity&, int segment)>;
RunStats run_history(const contact::ContactModel& model,
                     const std::vector<contact::Segment>& segments, const IntegratorOptions& opt,
                     bool initial_mu_is_mu_s, const SensitivityCallback& on_output);

}  // namespace subslip::history
