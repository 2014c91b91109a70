// The material-point API: one update of one material point over one step, for a single contact
// point, a crystal grain, and a Taylor aggregate of grains taken as one point.
//
// Each point type has
// * parameters, named and validated once, when the point is made (std::invalid_argument names
//   the offending parameter);
// * a plain state: a value type that can be copied, stored and restored, and that the caller
//   owns (a point holds no state between calls, so one point serves any number of states);
// * one update over a step: the step's kinematics and length in, a new state, the stress or
//   traction, the consistent tangent and a report of the solve out;
// * the same update over a batch of states (OpenMP over the batch; each result is bitwise the
//   one the single update gives, at any thread count).
//
// An update does not cut its step back: a report that is not ok leaves the decision (a shorter
// step, a smaller load) to the caller, as a finite-element code decides its own increments. The
// drivers of subslip (scenes, the accuracy study, the robustness grid) advance the same states
// with the same updates; docs/material_point.md has the details and an example.
//
// Units are those of the parameters: stresses in the unit of the elastic constants and tau0
// (MPa in every shipped scene), lengths in the unit of the contact stiffness, time in seconds.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "subslip/contact/contact_point.hpp"
#include "subslip/crystal/grain_sensitivity.hpp"
#include "subslip/crystal/phase_builder.hpp"
#include "subslip/law/subloading_friction.hpp"

namespace subslip::point {

// How an update's solve went.
struct SolveReport {
  bool ok = false;
  int iterations = 0;  // Newton iterations of the step (all tries)
  int grain = -1;      // the grain that failed, in an aggregate
  int system = -1;     // the slip system that failed, when known
  std::string why;     // empty when ok
};

// ---- A single frictional contact point (paper section 2) -------------------------------------

struct ContactParameters {
  law::LawParameters law;
  contact::ContactStiffness stiffness;  // alpha_n, alpha_t [stress/length]
  double residual_tolerance = 1e-12;    // on the flow rule, traction-ratio units
  // The update: implicit (backward Euler of the flow rule with radial return) or forward Euler
  // (paper section 2f, method 2), which refuses a step above its stability limit 2/lambda and
  // has no consistent tangent (its tangent is zero).
  contact::Method method = contact::Method::implicit;
  bool tangent = true;  // compute the consistent tangent (implicit); without it, zero
};

using ContactState = contact::ContactState;

// One step of a contact point: the tangential sliding displacement increment and the normal
// traction at the step's end (compression positive).
struct ContactStep {
  Eigen::Vector2d slip = Eigen::Vector2d::Zero();  // du_t [length]
  double normal_traction = 0.0;                    // f_n at the end of the step [stress]
  double dt = 0.0;                                 // [time]
};

struct ContactUpdate {
  ContactState state;  // traction_t, traction_n [stress] and the law's state after the step
  // The consistent tangent d f_t(n+1) / d (du_t, f_n(n+1)): columns du_1, du_2 [stress/length]
  // and f_n [-].
  Eigen::Matrix<double, 2, 3> tangent = Eigen::Matrix<double, 2, 3>::Zero();
  SolveReport report;
};

class ContactPoint {
 public:
  explicit ContactPoint(const ContactParameters& parameters);

  const ContactParameters& parameters() const { return parameters_; }
  // At rest under the normal traction f_n: no tangential traction, the law at `law_state`.
  ContactState initial_state(double normal_traction, const law::LawState& law_state) const;
  // One update by ContactParameters::method.
  ContactUpdate update(const ContactState& state, const ContactStep& step) const;
  // One implicit update that also carries `sensitivity`, the derivatives of the state's
  // variables with respect to the law's constants (contact::ContactSensitivity), from `state`'s
  // to the result's; left as it is where the update fails. Start a path from
  // contact::initial_sensitivity. Only the implicit method has them (std::invalid_argument).
  ContactUpdate update(const ContactState& state, const ContactStep& step,
                       contact::ContactSensitivity& sensitivity) const;
  // Point k: states[k] over steps[k] into out[k] (the spans have one size).
  void update(std::span<const ContactState> states, std::span<const ContactStep> steps,
              std::span<ContactUpdate> out) const;
  // The first way `state` leaves the law's admissible set, e.g. "r_s > r"; empty where it is
  // admissible: finite, mu > 0, 0 <= r_s <= r < r_hat (r < r_hat for the rate-dependent forms).
  std::string admissibility_violation(const ContactState& state) const;
  const law::SubloadingFrictionLaw& law() const { return law_; }

 private:
  ContactParameters parameters_;
  law::SubloadingFrictionLaw law_;
};

// ---- A crystal grain ---------------------------------------------------------------------------

// Per slip system, up to crystal::kMaxSlipSystems entries (no heap allocation).
using SlipVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, crystal::kMaxSlipSystems, 1>;
using Mandel6 = Eigen::Matrix<double, 6, 1>;
using Matrix6 = Eigen::Matrix<double, 6, 6>;

// The state of one grain: the law's state and where its next step's Newton iteration starts
// (the slip rates' history). Tensors in Mandel notation (11, 22, 33, sqrt2 23, sqrt2 13,
// sqrt2 12).
struct GrainState {
  Mandel6 stress = Mandel6::Zero();  // Cauchy stress, lattice frame [stress]
  Eigen::Matrix3d orientation = Eigen::Matrix3d::Identity();  // g: v_crystal = g v_sample
  SlipVector mu;                 // friction coefficient (CRSS = mu tau0) [-]
  SlipVector r_s;                // subloading ratio [-]
  SlipVector slip;               // accumulated signed slip [-]
  SlipVector rate;               // signed slip rate of the last step [1/s]
  SlipVector rate_trend;         // the rates' change per unit time over the last step [1/s^2]
  SlipVector rate_trend_change;  // the trend's change per unit time since the step before [1/s^3]
  double trend_step = 0.0;       // the last step's length, 0 before the first [s]

  // The Cauchy stress in the sample frame (Mandel) [stress].
  Mandel6 sample_stress() const;
};

// Where a grain step's Newton iteration starts.
enum class GrainStart {
  // The committed slip rates continued along their history (GrainState::rate_trend), then, if
  // that fails, the committed rates: what the drivers take.
  continued,
  // The committed slip rates alone, one try: a step as the robustness grid tests it.
  committed,
};

struct GrainOptions {
  double tolerance = 1e-12;  // on each flow rule, traction-ratio units
  int max_iterations = 60;
  bool tangent = true;  // compute the consistent tangent
  GrainStart start = GrainStart::continued;
};

struct GrainUpdate {
  GrainState state;
  Mandel6 stress = Mandel6::Zero();  // Cauchy stress after the step, sample frame [stress]
  // d sigma(n+1) / d (D dt), sample frame, Mandel [stress] (when GrainOptions::tangent).
  Matrix6 tangent = Matrix6::Zero();
  SolveReport report;
};

// The derivatives of a grain's state and stress with respect to its law's constants, tau0 and
// initial_mu (crystal/grain_sensitivity.hpp).
using GrainSensitivity = crystal::GrainSensitivity;
using MixedControlSensitivity = crystal::MixedControlSensitivity;

// The phase of a grain: slip families (or custom systems) with their laws and tau0, elasticity,
// latent hardening, kinematics (crystal/phase_builder.hpp).
using GrainParameters = crystal::PhaseDescription;

class GrainPoint {
 public:
  explicit GrainPoint(const GrainParameters& parameters, const GrainOptions& options = {});
  ~GrainPoint();
  GrainPoint(GrainPoint&&) noexcept;
  GrainPoint& operator=(GrainPoint&&) noexcept;

  int slip_count() const;
  // The virgin state of a grain of orientation g (v_crystal = g v_sample).
  GrainState initial_state(const Eigen::Matrix3d& orientation) const;
  // One implicit step under the velocity gradient L (sample frame, constant over dt) [1/s].
  GrainUpdate update(const GrainState& state, const Eigen::Matrix3d& velocity_gradient,
                     double dt) const;
  // One implicit step that also carries `sensitivity`, the derivatives of the state's variables
  // and of the returned sample-frame stress with respect to the law's constants, tau0 and
  // initial_mu (GrainSensitivity), from `state`'s to the result's; left as it is where the
  // update fails. Start a path from initial_sensitivity(). Only a phase whose systems share one
  // law, one tau0 and one initial_mu, without plane pressure, has them (std::invalid_argument
  // otherwise); std::runtime_error where the step's flow rules are singular in its slips.
  GrainUpdate update(const GrainState& state, const Eigen::Matrix3d& velocity_gradient, double dt,
                     GrainSensitivity& sensitivity) const;
  // The same under mixed control: L's components along `mixed.directions` were solved for so
  // that the sample-frame stresses `mixed.held` keep their values, and the sensitivities carried
  // include those components' change with the constants (written to `mixed.free_gradient`).
  GrainUpdate update(const GrainState& state, const Eigen::Matrix3d& velocity_gradient, double dt,
                     GrainSensitivity& sensitivity, MixedControlSensitivity& mixed) const;
  // The sensitivities of initial_state(): zero, but d mu / d initial_mu = 1 (d mu / d mu_s
  // where the phase starts from mu_s). std::invalid_argument as for the update above.
  GrainSensitivity initial_sensitivity() const;
  // Grain k: states[k] under velocity_gradients[k] over dt into out[k].
  void update(std::span<const GrainState> states,
              std::span<const Eigen::Matrix3d> velocity_gradients, double dt,
              std::span<GrainUpdate> out) const;
  // The first way `state` leaves the law's admissible set, e.g. "system 7: r_s > r (r = ...,
  // r_s = ...)"; empty where it is admissible: finite, and 0 <= r_s <= r < r_hat on every slip
  // system (r < r_hat only for the rate-dependent forms).
  std::string admissibility_violation(const GrainState& state) const;

  struct Model;  // the phase of its slip count (src/point/grain_point.cpp)

 private:
  GrainUpdate sensitivity_update(const GrainState& state, const Eigen::Matrix3d& velocity_gradient,
                                 double dt, GrainSensitivity& sensitivity,
                                 MixedControlSensitivity* mixed) const;

  std::unique_ptr<const Model> model_;
};

// ---- A Taylor aggregate as one material point --------------------------------------------------

// Every grain takes the point's velocity gradient; the stress and the tangent are the
// volume averages (exact sums: independent of the order of the grains' updates).
struct TaylorState {
  std::vector<GrainState> grains;
};

struct TaylorUpdate {
  TaylorState state;
  Mandel6 stress = Mandel6::Zero();   // volume-averaged Cauchy stress, sample frame [stress]
  Matrix6 tangent = Matrix6::Zero();  // its d sigma / d (D dt), sample frame [stress]
  SolveReport report;                 // the first failing grain's, if any
};

class TaylorPoint {
 public:
  // Weights are relative (empty: equal); they are normalised.
  TaylorPoint(const GrainParameters& parameters, std::vector<Eigen::Matrix3d> orientations,
              std::vector<double> weights = {}, const GrainOptions& options = {});

  int grain_count() const { return static_cast<int>(orientations_.size()); }
  const GrainPoint& grain() const { return grain_; }
  TaylorState initial_state() const;
  TaylorUpdate update(const TaylorState& state, const Eigen::Matrix3d& velocity_gradient,
                      double dt) const;

 private:
  GrainPoint grain_;
  std::vector<Eigen::Matrix3d> orientations_;
  std::vector<double> weights_;  // normalised
  bool tangent_;
};

}  // namespace subslip::point
