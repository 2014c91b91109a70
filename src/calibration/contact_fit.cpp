#include "subslip/calibration/contact_fit.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <sstream>
#include <stdexcept>

#include "subslip/history/contact_history.hpp"

namespace subslip::calibration {

namespace {

const law::LawParameterInfo& info_of(const FreeParameter& f) {
  return law::kLawParameters[static_cast<std::size_t>(f.index)];
}

// The law with the free constants at `values`.
law::LawParameters law_at(const FitProblem& problem, const std::vector<double>& values) {
  law::LawParameters p = problem.model.law;
  for (std::size_t j = 0; j < problem.free.size(); ++j) info_of(problem.free[j]).ref(p) = values[j];
  return p;
}

contact::ContactModel model_with(const FitProblem& problem, const law::LawParameters& law) {
  contact::ContactModel m = problem.model;
  m.law = law;
  if (problem.initial_mu_is_mu_s) m.initial_law_state.mu = law.friction.mu_s;
  return m;
}

// Which data would determine a constant the fit leaves undetermined.
std::string advice(std::string_view name, int speeds) {
  if (name == "eta_v" || name == "n" || name == "r_hat") {
    return speeds < 2 ? "curves at a second sliding speed (and a third: eta_v, n and r_hat set "
                        "how f_t/f_n rises with the speed)"
                      : "curves over a wider range of sliding speeds (r_hat bounds the overstress "
                        "at high speed, n its curvature)";
  }
  if (name == "xi") return "a slower curve or a hold before re-sliding (xi is recovery with time)";
  if (name == "mu_s") return "points at the very start of sliding (the rise to the static peak)";
  if (name == "mu_k" || name == "kappa")
    return "longer slides, to where f_t/f_n settles at kinetic friction";
  if (name == "u_tilde") return "more points on the rise to the peak";
  return "more data";
}

}  // namespace

Prediction predict(const contact::ContactModel& model, bool initial_mu_is_mu_s, const Curve& curve,
                   const PathSteps& steps) {
  contact::Segment slide;
  slide.velocity = contact::Vec2(curve.speed, 0.0);
  slide.duration = curve.slip.back() / curve.speed;
  slide.normal_traction = model.initial_normal_traction;
  slide.increments = steps.increments;
  slide.growth = steps.growth;
  slide.output_at_times = true;
  for (const double s : curve.slip) slide.output_times.push_back(s / curve.speed);
  history::IntegratorOptions opt;
  opt.residual_tolerance = steps.residual_tolerance;
  Prediction p;
  p.gradient.resize(static_cast<Eigen::Index>(curve.slip.size()), law::kParameterCount);
  history::run_history(
      model, {slide}, opt, initial_mu_is_mu_s,
      [&](const contact::ContactState& s, const contact::ContactSensitivity& d, int segment) {
        if (segment < 0) return;  // the state at rest
        p.gradient.row(static_cast<Eigen::Index>(p.ratio.size())) = d.traction_ratio(s);
        p.ratio.push_back(s.traction_ratio());
      });
  return p;
}

FitResult fit(const FitProblem& problem) {
  LeastSquaresProblem ls;
  for (const FreeParameter& f : problem.free) {
    ls.names.emplace_back(info_of(f).name);
    ls.start.push_back(info_of(f).value(problem.model.law));
  }
  ls.free = problem.free;
  ls.max_iterations = problem.max_iterations;
  std::set<double> speeds;
  for (const Curve& c : problem.curves) {
    speeds.insert(c.speed);
    CurveModel m;
    m.measured = c.ratio;
    m.weight = c.weight;
    m.predict = [&problem, &c](const std::vector<double>& values, std::vector<double>& predicted,
                               Eigen::MatrixXd& gradient) {
      const Prediction p = predict(model_with(problem, law_at(problem, values)),
                                   problem.initial_mu_is_mu_s, c, problem.steps);
      predicted = p.ratio;
      gradient.resize(p.gradient.rows(), static_cast<Eigen::Index>(problem.free.size()));
      for (std::size_t j = 0; j < problem.free.size(); ++j)
        gradient.col(static_cast<Eigen::Index>(j)) = p.gradient.col(problem.free[j].index);
    };
    ls.curves.push_back(std::move(m));
  }
  const int speed_count = static_cast<int>(speeds.size());
  ls.advice = [speed_count](std::string_view name) { return advice(name, speed_count); };
  FitResult r = least_squares_fit(ls);
  r.law = law_at(problem, r.estimate);
  return r;
}

}  // namespace subslip::calibration
