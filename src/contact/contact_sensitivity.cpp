#include "contact_sensitivity.hpp"

#include <algorithm>

#include "path_minimum.hpp"
#include "subslip/law/parameter_jet.hpp"

namespace subslip::contact {

namespace {

using law::ParameterJet;
using JetVec2 = Eigen::Matrix<ParameterJet, 2, 1>;

// A state's variables as jets of the constants.
struct JetState {
  JetVec2 traction_t;
  ParameterJet mu, r_s, r, vp_slip, vp_rate;
};

JetState jets(const ContactState& s, const ContactSensitivity& d) {
  return {JetVec2(law::make_jet(s.traction_t.x(), d.traction_t.row(0)),
                  law::make_jet(s.traction_t.y(), d.traction_t.row(1))),
          law::make_jet(s.law.mu, d.mu),
          law::make_jet(s.law.r_s, d.r_s),
          law::make_jet(s.r, d.r),
          law::make_jet(s.vp_slip, d.vp_slip),
          law::make_jet(s.vp_rate, d.vp_rate)};
}

ContactSensitivity gradients(const JetState& s) {
  ContactSensitivity d;
  d.traction_t.row(0) = law::gradient(s.traction_t.x());
  d.traction_t.row(1) = law::gradient(s.traction_t.y());
  d.mu = law::gradient(s.mu);
  d.r_s = law::gradient(s.r_s);
  d.r = law::gradient(s.r);
  d.vp_slip = law::gradient(s.vp_slip);
  d.vp_rate = law::gradient(s.vp_rate);
  return d;
}

}  // namespace

law::ParameterGradient ContactSensitivity::traction_ratio(const ContactState& s) const {
  const double ft = s.traction_t.norm();
  if (!(ft > 0.0) || !(s.traction_n > 0.0)) return law::ParameterGradient::Zero();
  // d|f_t| = (f_t / |f_t|) . d f_t; f_n is prescribed.
  return (s.traction_t.transpose() * traction_t) / (ft * s.traction_n);
}

ContactSensitivity initial_sensitivity(bool initial_mu_is_mu_s) {
  ContactSensitivity d;
  if (initial_mu_is_mu_s) d.mu(0, 0) = 1.0;  // kLawParameters[0] is mu_s
  static_assert(law::kLawParameters[0].name == "mu_s");
  return d;
}

namespace detail {

ContactSensitivity open_step_sensitivity(const law::SubloadingFrictionLaw& law,
                                         const ContactState& s0, const ContactSensitivity& d0,
                                         double dt) {
  // As open_contact: no traction, r = r_s = 0, mu recovers over dt.
  const law::SubloadingFrictionJet jet_law(law);
  ContactSensitivity d;
  d.mu = law::gradient(jet_law.friction_coefficient_after(law::make_jet(s0.law.mu, d0.mu),
                                                          ParameterJet(0.0), ParameterJet(dt)));
  d.vp_slip = d0.vp_slip;
  return d;
}

ContactSensitivity opening_step_sensitivity(const law::SubloadingFrictionLaw& law,
                                            const ContactStiffness& c, const ContactState& s0,
                                            const ContactSensitivity& d0, const Vec2& du_t,
                                            double dt) {
  // As slide_into_opening: no traction, r = r_s = 0, the trial traction's length slid.
  const law::SubloadingFrictionJet jet_law(law);
  const JetState start = jets(s0, d0);
  const JetVec2 trial = start.traction_t + (c.alpha_t * du_t).cast<ParameterJet>();
  // (|trial| is not differentiable at zero, where nothing slides: ds = 0 with no gradient.)
  const ParameterJet ds =
      trial.x().a == 0.0 && trial.y().a == 0.0 ? ParameterJet(0.0) : trial.norm() / c.alpha_t;
  ContactSensitivity d;
  d.mu = law::gradient(jet_law.friction_coefficient_after(start.mu, ds, ParameterJet(dt)));
  d.vp_slip = law::gradient(start.vp_slip + ds);
  d.vp_rate = law::gradient(ds / dt);
  return d;
}

ContactSensitivity step_sensitivity(const law::SubloadingFrictionLaw& law,
                                    const ContactStiffness& c, const ContactState& s0,
                                    const ContactSensitivity& d0, const Vec2& du_t, double fn1,
                                    double dt, const std::optional<SlipRoot>& root) {
  // implicit_step's formulas, in the same order, on jets.
  const law::SubloadingFrictionJet jet_law(law);
  const JetState start = jets(s0, d0);
  const ParameterJet zero(0.0), step(dt);
  const JetVec2 trial = start.traction_t + (c.alpha_t * du_t).cast<ParameterJet>();
  const ParameterJet ft_trial = trial.norm();
  const ParameterJet mu_elastic = jet_law.friction_coefficient_after(start.mu, zero, step);
  const ParameterJet r_trial = ft_trial / (fn1 * mu_elastic);
  const auto lowest = detail::lowest_ratio_on_path(
      start.traction_t, s0.traction_n, trial, fn1, [&](const ParameterJet& l) {
        return jet_law.friction_coefficient_after(start.mu, zero, l * dt);
      });
  const bool dips = lowest.ratio < start.r_s;
  const ParameterJet rs_start = dips ? lowest.ratio : start.r_s;
  const ParameterJet slip_time = dips && lowest.at < 1.0 ? (1.0 - lowest.at) * dt : step;

  JetState end = start;
  if (!root) {
    end.traction_t = trial;
    end.mu = mu_elastic;
    end.r = r_trial;
    end.r_s = std::min(rs_start, r_trial);
    end.vp_rate = zero;
    return gradients(end);
  }
  // The flow rule's residual at the converged slip, as a function of (ds, constants, start).
  auto end_state = [&](const ParameterJet& ds, ParameterJet* residual) {
    end.mu = jet_law.friction_coefficient_after(start.mu, ds, step);
    const ParameterJet ft = ft_trial - c.alpha_t * ds;
    end.r = ft / (fn1 * end.mu);
    const ParameterJet rs = jet_law.subloading_ratio_after(rs_start, ds);
    if (residual) *residual = jet_law.flow_residual(end.r, rs, ds, slip_time);
    end.traction_t = trial * (ft / ft_trial);
    end.r_s = std::min(rs, end.r);
    end.vp_slip = start.vp_slip + ds;
    end.vp_rate = ds / slip_time;
  };
  // G(ds; p, s0) = 0 at the root: at constant ds the residual's jet is dG/dp + dG/ds0 ds0/dp,
  // and dds/dp = -(that) / (dG/dds).
  ParameterJet residual;
  end_state(ParameterJet(root->slip), &residual);
  end_state(law::make_jet(root->slip, -law::gradient(residual) / root->slope), nullptr);
  return gradients(end);
}

}  // namespace detail

}  // namespace subslip::contact
