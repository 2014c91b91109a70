// The contact point and the Taylor point of the material-point API (the grain point:
// grain_point.cpp).
#include "subslip/material_point.hpp"

#include <array>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "subslip/parallel/exact_sum.hpp"

namespace subslip::point {

namespace {

// The message is a literal: checks on every update build no string unless they fail.
void require(bool ok, const char* what) {
  if (!ok) throw std::invalid_argument(what);
}

bool positive_finite(double x) {
  return std::isfinite(x) && x > 0.0;
}

void check_contact_parameters(const ContactParameters& p) {
  require(positive_finite(p.stiffness.alpha_n),
          "contact parameter alpha_n must be positive and finite [stress/length]");
  require(positive_finite(p.stiffness.alpha_t),
          "contact parameter alpha_t must be positive and finite [stress/length]");
  require(p.residual_tolerance > 0.0 && p.residual_tolerance < 1.0,
          "contact parameter residual_tolerance must lie in (0, 1)");
}

void check_contact_step(const ContactStep& s) {
  require(s.slip.allFinite(), "contact step: the slip increment must be finite");
  require(std::isfinite(s.normal_traction), "contact step: the normal traction must be finite");
  require(positive_finite(s.dt), "contact step: dt must be positive and finite");
}

}  // namespace

ContactPoint::ContactPoint(const ContactParameters& parameters)
    : parameters_(parameters), law_((check_contact_parameters(parameters), parameters.law)) {}

ContactState ContactPoint::initial_state(double normal_traction,
                                         const law::LawState& law_state) const {
  return contact::initial_state(
      contact::ContactModel{parameters_.law, law_state, parameters_.stiffness, normal_traction});
}

ContactUpdate ContactPoint::update(const ContactState& state, const ContactStep& step) const {
  check_contact_step(step);
  ContactUpdate out;
  contact::StepAttempt a =
      parameters_.method == contact::Method::implicit
          ? contact::implicit_step(law_, parameters_.stiffness, state, step.slip,
                                   step.normal_traction, step.dt, parameters_.residual_tolerance,
                                   parameters_.tangent ? &out.tangent : nullptr)
          : contact::forward_euler_step(law_, parameters_.stiffness, state, step.slip,
                                        step.normal_traction, step.dt);
  out.report = {a.ok, a.iterations, -1, -1, std::move(a.why)};
  out.state = a.ok ? a.state : state;
  if (!a.ok) out.tangent.setZero();
  return out;
}

ContactUpdate ContactPoint::update(const ContactState& state, const ContactStep& step,
                                   contact::ContactSensitivity& sensitivity) const {
  require(parameters_.method == contact::Method::implicit,
          "contact sensitivities: only the implicit update has them");
  check_contact_step(step);
  ContactUpdate out;
  contact::StepAttempt a = contact::implicit_step(
      law_, parameters_.stiffness, state, step.slip, step.normal_traction, step.dt,
      parameters_.residual_tolerance, parameters_.tangent ? &out.tangent : nullptr, sensitivity);
  out.report = {a.ok, a.iterations, -1, -1, std::move(a.why)};
  out.state = a.ok ? a.state : state;
  if (!a.ok) out.tangent.setZero();
  return out;
}

std::string ContactPoint::admissibility_violation(const ContactState& state) const {
  return contact::admissibility_violation(law_, state);
}

void ContactPoint::update(std::span<const ContactState> states, std::span<const ContactStep> steps,
                          std::span<ContactUpdate> out) const {
  require(states.size() == steps.size() && states.size() == out.size(),
          "contact batch: states, steps and results differ in size");
  for (const ContactStep& s : steps) check_contact_step(s);
  const long n = static_cast<long>(states.size());
#pragma omp parallel for schedule(static) if (n > 1)
  for (long k = 0; k < n; ++k) {
    const auto i = static_cast<std::size_t>(k);
    out[i] = update(states[i], steps[i]);
  }
}

TaylorPoint::TaylorPoint(const GrainParameters& parameters,
                         std::vector<Eigen::Matrix3d> orientations, std::vector<double> weights,
                         const GrainOptions& options)
    : grain_(parameters, options),
      orientations_(std::move(orientations)),
      weights_(std::move(weights)),
      tangent_(options.tangent) {
  require(!orientations_.empty(), "Taylor point: no grains");
  if (weights_.empty()) weights_.assign(orientations_.size(), 1.0);
  if (weights_.size() != orientations_.size())
    throw std::invalid_argument("Taylor point: " + std::to_string(weights_.size()) +
                                " weights for " + std::to_string(orientations_.size()) + " grains");
  // Normalised as the Taylor aggregate normalises them (an exact sum), so that the two average
  // the same numbers.
  parallel::ExactSum total;
  for (double w : weights_) {
    require(positive_finite(w), "Taylor point: weights must be positive and finite");
    total.add(w);
  }
  const double sum = total.value();
  for (double& w : weights_) w /= sum;
}

TaylorState TaylorPoint::initial_state() const {
  TaylorState s;
  s.grains.reserve(orientations_.size());
  for (const Eigen::Matrix3d& g : orientations_) s.grains.push_back(grain_.initial_state(g));
  return s;
}

TaylorUpdate TaylorPoint::update(const TaylorState& state, const Eigen::Matrix3d& velocity_gradient,
                                 double dt) const {
  if (state.grains.size() != orientations_.size())
    throw std::invalid_argument("Taylor point: a state of " + std::to_string(state.grains.size()) +
                                " grains for " + std::to_string(orientations_.size()));
  const std::vector<Eigen::Matrix3d> gradients(state.grains.size(), velocity_gradient);
  std::vector<GrainUpdate> grains(state.grains.size());
  grain_.update(state.grains, gradients, dt, grains);

  TaylorUpdate out;
  out.report.ok = true;
  std::array<parallel::ExactSum, 6> stress;
  std::array<parallel::ExactSum, 36> tangent;
  out.state.grains.reserve(grains.size());
  int iterations = 0;  // every grain's, the failing grain's report notwithstanding
  for (std::size_t g = 0; g < grains.size(); ++g) {
    const GrainUpdate& u = grains[g];
    iterations += u.report.iterations;
    if (!u.report.ok && out.report.ok) {
      out.report = u.report;
      out.report.grain = static_cast<int>(g);
    }
    const Mandel6 s = weights_[g] * u.stress;
    for (int i = 0; i < 6; ++i) stress[static_cast<std::size_t>(i)].add(s(i));
    if (tangent_)
      for (int i = 0; i < 36; ++i)
        tangent[static_cast<std::size_t>(i)].add(weights_[g] * u.tangent.data()[i]);
    out.state.grains.push_back(u.state);
  }
  out.report.iterations = iterations;
  if (!out.report.ok) {
    out.state = state;
    return out;
  }
  for (int i = 0; i < 6; ++i) out.stress(i) = stress[static_cast<std::size_t>(i)].value();
  for (int i = 0; i < 36; ++i) out.tangent.data()[i] = tangent[static_cast<std::size_t>(i)].value();
  return out;
}

}  // namespace subslip::point
