// The grain of the material-point API: the phase of its slip count behind one virtual call per
// update or batch (never per slip system), the update being the one the Taylor aggregate's
// grain sweep takes (crystal/grain_update.hpp).
#include <algorithm>
#include <stdexcept>

#include "../crystal/grain_sensitivity.hpp"
#include "../crystal/grain_update.hpp"
#include "subslip/crystal/admissibility.hpp"
#include "subslip/material_point.hpp"

namespace subslip::point {

namespace cr = subslip::crystal;

Mandel6 GrainState::sample_stress() const {
  return cr::mandel_from_symmetric(orientation.transpose() * cr::symmetric_from_mandel(stress) *
                                   orientation);
}

struct GrainPoint::Model {
  virtual ~Model() = default;
  virtual int slip_count() const = 0;
  // Throws std::invalid_argument where the state is not one of this phase's slip count.
  virtual void check(const GrainState& state) const = 0;
  virtual GrainState initial_state(const Eigen::Matrix3d& orientation) const = 0;
  virtual void update(const GrainState& state, const Eigen::Matrix3d& velocity_gradient, double dt,
                      GrainUpdate& out) const = 0;
  virtual std::string admissibility_violation(const GrainState& state) const = 0;
  // The update, then the step's sensitivities (crystal/grain_sensitivity.hpp) where it is ok.
  virtual void update(const GrainState& state, const Eigen::Matrix3d& velocity_gradient, double dt,
                      GrainUpdate& out, GrainSensitivity& sensitivity,
                      MixedControlSensitivity* mixed) const = 0;

  // Why the phase has no sensitivities (empty where it has them), and whether its mu starts
  // from mu_s.
  std::string sensitivity_refusal;
  bool initial_mu_is_mu_s = false;
};

namespace {

template <int N>
class PhaseModel final : public GrainPoint::Model {
 public:
  using VecN = typename cr::SlipTypes<N>::VecN;

  PhaseModel(cr::BuiltPhase<N> built, const GrainOptions& options)
      : phase_(std::move(built.phase)),
        initial_mu_(built.initial_mu),
        with_tangent_(options.tangent),
        continued_(options.start == GrainStart::continued) {
    options_.tolerance = options.tolerance;
    options_.max_iterations = options.max_iterations;
  }

  int slip_count() const override { return phase_.slip_count; }

  void check(const GrainState& p) const override {
    const int n = phase_.slip_count;
    for (const SlipVector* v :
         {&p.mu, &p.r_s, &p.slip, &p.rate, &p.rate_trend, &p.rate_trend_change})
      if (v->size() != n)
        throw std::invalid_argument("grain state of " + std::to_string(v->size()) +
                                    " slip systems for a phase of " + std::to_string(n));
  }

  GrainState initial_state(const Eigen::Matrix3d& orientation) const override {
    cr::GrainState<N> s;
    s.reset(phase_.slip_count, orientation, initial_mu_);
    GrainState out;
    const cr::RateHistory<N> none{VecN::Zero(phase_.slip_count), VecN::Zero(phase_.slip_count)};
    to_point(s, none, 0.0, out);
    return out;
  }

  void update(const GrainState& state, const Eigen::Matrix3d& velocity_gradient, double dt,
              GrainUpdate& out) const override {
    cr::GrainState<N> s0, s1;
    cr::RateHistory<N> history;
    from_point(state, s0, history);
    cr::Tangent tangent;
    cr::Tangent* t = with_tangent_ ? &tangent : nullptr;
    const cr::GrainStepReport rep =
        continued_ ? cr::cold_implicit_step(phase_, s0, history, state.trend_step,
                                            velocity_gradient, dt, options_, s1, t)
                   : cr::implicit_step_from(phase_, s0, velocity_gradient, dt, options_, s0.rate,
                                            false, s1, t);
    out.report = {rep.ok, rep.iterations, -1, rep.system, rep.ok ? std::string() : rep.why};
    if (!rep.ok) {
      out.state = state;
      out.stress = state.sample_stress();
      out.tangent.setZero();
      return;
    }
    cr::history_after_step(s0, s1, history, state.trend_step, dt, history);
    to_point(s1, history, dt, out.state);
    out.stress = s1.sample_stress();
    if (with_tangent_)
      out.tangent = tangent;
    else
      out.tangent.setZero();
  }

  void update(const GrainState& state, const Eigen::Matrix3d& velocity_gradient, double dt,
              GrainUpdate& out, GrainSensitivity& sensitivity,
              MixedControlSensitivity* mixed) const override {
    update(state, velocity_gradient, dt, out);
    if (!out.report.ok) return;
    cr::GrainState<N> s0, s1;
    cr::RateHistory<N> history;
    from_point(state, s0, history);
    from_point(out.state, s1, history);
    cr::carry_grain_sensitivity(phase_, s0, velocity_gradient, dt, s1, sensitivity, mixed);
  }

  std::string admissibility_violation(const GrainState& state) const override {
    cr::GrainState<N> s;
    cr::RateHistory<N> history;
    from_point(state, s, history);
    return cr::admissibility_violation(phase_, s);
  }

 private:
  static void from_point(const GrainState& p, cr::GrainState<N>& s, cr::RateHistory<N>& h) {
    s.stress = p.stress;
    s.orientation = p.orientation;
    s.mu = p.mu;
    s.r_s = p.r_s;
    s.slip = p.slip;
    s.rate = p.rate;
    h.trend = p.rate_trend;
    h.trend_change = p.rate_trend_change;
  }

  static void to_point(const cr::GrainState<N>& s, const cr::RateHistory<N>& h, double trend_step,
                       GrainState& p) {
    p.stress = s.stress;
    p.orientation = s.orientation;
    p.mu = s.mu;
    p.r_s = s.r_s;
    p.slip = s.slip;
    p.rate = s.rate;
    p.rate_trend = h.trend;
    p.rate_trend_change = h.trend_change;
    p.trend_step = trend_step;
  }

  cr::Phase<N> phase_;
  VecN initial_mu_;
  cr::GrainStepOptions options_;
  bool with_tangent_;
  bool continued_;
};

// Why a phase has no sensitivities: its systems' laws, tau0 or initial_mu differ (the columns
// are one law's constants), or its planes' normal traction follows the stress.
std::string sensitivity_refusal(const GrainParameters& d) {
  if (d.pressure_sensitive)
    return "grain sensitivities need a phase without plane pressure (pressure_sensitive)";
  const std::vector<cr::SlipGroupSettings> groups =
      d.custom_systems.empty() ? d.family_settings
                               : std::vector<cr::SlipGroupSettings>{d.custom_settings};
  for (std::size_t k = 1; k < groups.size(); ++k) {
    const cr::SlipGroupSettings &first = groups.front(), &g = groups[k];
    if (!(g.law == first.law) || g.tau0 != first.tau0 || g.initial_mu != first.initial_mu)
      return "grain sensitivities need one law, tau0 and initial_mu for every slip system: "
             "slip family " +
             std::to_string(k) + " differs from family 0";
  }
  return {};
}

void check_options(const GrainOptions& o) {
  if (!(o.tolerance > 0.0 && o.tolerance < 1.0))
    throw std::invalid_argument("grain option tolerance must lie in (0, 1), got " +
                                std::to_string(o.tolerance));
  if (o.max_iterations < 1)
    throw std::invalid_argument("grain option max_iterations must be at least 1");
}

}  // namespace

GrainPoint::GrainPoint(const GrainParameters& parameters, const GrainOptions& options) {
  check_options(options);
  model_ = cr::visit_phase(parameters, [&](auto built) -> std::unique_ptr<const Model> {
    constexpr int n = decltype(built.phase)::T::VecN::RowsAtCompileTime;
    auto model = std::make_unique<PhaseModel<n>>(std::move(built), options);
    model->sensitivity_refusal = sensitivity_refusal(parameters);
    const cr::SlipGroupSettings& first = parameters.custom_systems.empty()
                                             ? parameters.family_settings.front()
                                             : parameters.custom_settings;
    model->initial_mu_is_mu_s = !(first.initial_mu > 0.0);
    return model;
  });
}

GrainPoint::~GrainPoint() = default;
GrainPoint::GrainPoint(GrainPoint&&) noexcept = default;
GrainPoint& GrainPoint::operator=(GrainPoint&&) noexcept = default;

int GrainPoint::slip_count() const {
  return model_->slip_count();
}

GrainState GrainPoint::initial_state(const Eigen::Matrix3d& orientation) const {
  return model_->initial_state(orientation);
}

std::string GrainPoint::admissibility_violation(const GrainState& state) const {
  model_->check(state);
  return model_->admissibility_violation(state);
}

GrainUpdate GrainPoint::update(const GrainState& state, const Eigen::Matrix3d& velocity_gradient,
                               double dt) const {
  model_->check(state);
  GrainUpdate out;
  model_->update(state, velocity_gradient, dt, out);
  return out;
}

GrainSensitivity GrainPoint::initial_sensitivity() const {
  if (!model_->sensitivity_refusal.empty())
    throw std::invalid_argument(model_->sensitivity_refusal);
  return cr::initial_grain_sensitivity(model_->slip_count(), model_->initial_mu_is_mu_s);
}

GrainUpdate GrainPoint::update(const GrainState& state, const Eigen::Matrix3d& velocity_gradient,
                               double dt, GrainSensitivity& sensitivity) const {
  return sensitivity_update(state, velocity_gradient, dt, sensitivity, nullptr);
}

GrainUpdate GrainPoint::update(const GrainState& state, const Eigen::Matrix3d& velocity_gradient,
                               double dt, GrainSensitivity& sensitivity,
                               MixedControlSensitivity& mixed) const {
  for (const int h : mixed.held)
    if (h < 0 || h > 5)
      throw std::invalid_argument("mixed control: held stress component " + std::to_string(h) +
                                  " is no Mandel index (0 ... 5)");
  return sensitivity_update(state, velocity_gradient, dt, sensitivity, &mixed);
}

GrainUpdate GrainPoint::sensitivity_update(const GrainState& state,
                                           const Eigen::Matrix3d& velocity_gradient, double dt,
                                           GrainSensitivity& sensitivity,
                                           MixedControlSensitivity* mixed) const {
  if (!model_->sensitivity_refusal.empty())
    throw std::invalid_argument(model_->sensitivity_refusal);
  model_->check(state);
  const int n = model_->slip_count();
  for (const cr::SlipGradients* g : {&sensitivity.mu, &sensitivity.r_s, &sensitivity.slip})
    if (g->rows() != n)
      throw std::invalid_argument("grain sensitivity of " + std::to_string(g->rows()) +
                                  " slip systems for a phase of " + std::to_string(n));
  GrainUpdate out;
  model_->update(state, velocity_gradient, dt, out, sensitivity, mixed);
  return out;
}

void GrainPoint::update(std::span<const GrainState> states,
                        std::span<const Eigen::Matrix3d> velocity_gradients, double dt,
                        std::span<GrainUpdate> out) const {
  if (states.size() != velocity_gradients.size() || states.size() != out.size())
    throw std::invalid_argument(
        "grain batch: states, velocity gradients and results differ in size");
  for (const GrainState& s : states) model_->check(s);
  const long n = static_cast<long>(states.size());
  // Each grain's update is a function of its own inputs: bitwise the same at any thread count.
#pragma omp parallel for schedule(static) if (n > 1)
  for (long k = 0; k < n; ++k) {
    const auto i = static_cast<std::size_t>(k);
    model_->update(states[i], velocity_gradients[i], dt, out[i]);
  }
}

}  // namespace subslip::point
