#include "subslip/calibration/contact_fit.hpp"

#include <ceres/ceres.h>

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

// The normal distribution's 97.5 % quantile: the intervals are linearised, and a friction fit has
// hundreds of points, where Student's t of its degrees of freedom is this to 1e-3.
constexpr double kQuantile975 = 1.959963984540054;

const law::LawParameterInfo& info_of(const FreeParameter& f) {
  return law::kLawParameters[static_cast<std::size_t>(f.index)];
}

double to_fitted(const FreeParameter& f, double value) {
  return f.log_scale ? std::log(value) : value;
}
double from_fitted(const FreeParameter& f, double z) {
  return f.log_scale ? std::exp(z) : z;
}

// The law with the free constants at the fitted coordinates z.
law::LawParameters law_at(const FitProblem& problem, const double* z) {
  law::LawParameters p = problem.model.law;
  for (std::size_t j = 0; j < problem.free.size(); ++j)
    info_of(problem.free[j]).ref(p) = from_fitted(problem.free[j], z[j]);
  return p;
}

contact::ContactModel model_with(const FitProblem& problem, const law::LawParameters& law) {
  contact::ContactModel m = problem.model;
  m.law = law;
  if (problem.initial_mu_is_mu_s) m.initial_law_state.mu = law.friction.mu_s;
  return m;
}

// The weighted residuals of one curve and their Jacobian in the fitted coordinates.
class CurveCost : public ceres::CostFunction {
 public:
  CurveCost(const FitProblem& problem, const Curve& curve) : problem_(problem), curve_(curve) {
    set_num_residuals(static_cast<int>(curve.slip.size()));
    mutable_parameter_block_sizes()->push_back(static_cast<int>(problem.free.size()));
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const law::LawParameters law = law_at(problem_, parameters[0]);
    Prediction p;
    try {
      p = predict(model_with(problem_, law), problem_.initial_mu_is_mu_s, curve_, problem_.steps);
    } catch (const std::exception&) {
      return false;  // a trial the path cannot be computed for: the trust region shrinks
    }
    const double w = std::sqrt(curve_.weight);
    const std::size_t n = curve_.slip.size(), free = problem_.free.size();
    for (std::size_t i = 0; i < n; ++i) residuals[i] = w * (p.ratio[i] - curve_.ratio[i]);
    if (jacobians && jacobians[0]) {
      for (std::size_t j = 0; j < free; ++j) {
        const FreeParameter& f = problem_.free[j];
        // d/dz of a constant fitted as z = ln(value) is value d/d(value).
        const double chain = f.log_scale ? info_of(f).value(law) : 1.0;
        for (std::size_t i = 0; i < n; ++i)
          jacobians[0][i * free + j] =
              w * p.gradient(static_cast<Eigen::Index>(i), f.index) * chain;
      }
    }
    return true;
  }

 private:
  const FitProblem& problem_;
  const Curve& curve_;
};

void check_problem(const FitProblem& problem) {
  if (problem.free.empty()) throw std::invalid_argument("fit: no free constant");
  std::size_t points = 0;
  for (const Curve& c : problem.curves) points += c.slip.size();
  if (points <= problem.free.size())
    throw std::invalid_argument("fit: " + std::to_string(points) + " points for " +
                                std::to_string(problem.free.size()) + " free constants");
  for (const FreeParameter& f : problem.free) {
    const double start = info_of(f).value(problem.model.law);
    if (!(start >= f.lower && start <= f.upper)) {
      std::ostringstream msg;
      msg << "fit: the start " << info_of(f).name << " = " << start << " lies outside its bounds ["
          << f.lower << ", " << f.upper << "]";
      throw std::invalid_argument(msg.str());
    }
  }
}

// The weighted Jacobian of every curve at z (rows: points, columns: free constants, fitted
// coordinates), with the model's curves.
Eigen::MatrixXd jacobian_at(const FitProblem& problem, const std::vector<double>& z,
                            std::vector<std::vector<double>>& fitted, double& squares) {
  const law::LawParameters law = law_at(problem, z.data());
  std::size_t rows = 0;
  for (const Curve& c : problem.curves) rows += c.slip.size();
  Eigen::MatrixXd J(static_cast<Eigen::Index>(rows), static_cast<Eigen::Index>(z.size()));
  squares = 0.0;
  fitted.clear();
  Eigen::Index row = 0;
  for (const Curve& c : problem.curves) {
    const Prediction p =
        predict(model_with(problem, law), problem.initial_mu_is_mu_s, c, problem.steps);
    const double w = std::sqrt(c.weight);
    for (std::size_t i = 0; i < c.slip.size(); ++i, ++row) {
      const double r = w * (p.ratio[i] - c.ratio[i]);
      squares += r * r;
      for (std::size_t j = 0; j < z.size(); ++j) {
        const FreeParameter& f = problem.free[j];
        const double chain = f.log_scale ? info_of(f).value(law) : 1.0;
        J(row, static_cast<Eigen::Index>(j)) =
            w * p.gradient(static_cast<Eigen::Index>(i), f.index) * chain;
      }
    }
    fitted.push_back(p.ratio);
  }
  return J;
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

void add_warnings(const FitProblem& problem, FitResult& r) {
  std::set<double> speeds;
  for (const Curve& c : problem.curves) speeds.insert(c.speed);
  const std::size_t p = problem.free.size();
  for (std::size_t j = 0; j < p; ++j) {
    const FreeParameter& f = problem.free[j];
    std::vector<std::string> why;
    if (!std::isfinite(r.standard_error[j])) why.push_back("the data do not constrain it at all");
    for (std::size_t k = 0; k < p; ++k) {
      const double c = r.correlation(static_cast<Eigen::Index>(j), static_cast<Eigen::Index>(k));
      if (k != j && std::abs(c) > 0.99) {
        std::ostringstream s;
        s << "correlation " << c << " with " << r.names[k];
        why.push_back(s.str());
      }
    }
    if (!(r.upper[j] - r.lower[j] <= f.upper - f.lower))
      why.push_back("its 95 % interval is wider than its bounds");
    if (why.empty()) continue;
    std::string text = r.names[j] + " is not determined by the data (";
    for (std::size_t k = 0; k < why.size(); ++k) text += (k ? "; " : "") + why[k];
    text += "); " + advice(r.names[j], static_cast<int>(speeds.size())) + " would determine it";
    r.warnings.push_back(text);
  }
}

// Standard errors, intervals and correlations from the Jacobian at the estimate.
void add_statistics(const FitProblem& problem, const std::vector<double>& z, FitResult& r) {
  double squares = 0.0;
  const Eigen::MatrixXd J = jacobian_at(problem, z, r.fitted, squares);
  const auto p = static_cast<Eigen::Index>(z.size());
  r.points = static_cast<int>(J.rows());
  const double dof = static_cast<double>(J.rows() - p);
  r.residual_sd = std::sqrt(squares / dof);
  // The covariance of the fitted coordinates, s^2 (J^T J)^-1, through the SVD of J: a direction
  // the data do not see (a singular value at round-off) has an infinite variance.
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(J, Eigen::ComputeThinV);
  const Eigen::VectorXd sv = svd.singularValues();
  Eigen::VectorXd inverse_square(p);
  for (Eigen::Index k = 0; k < p; ++k) {
    const bool seen = sv(k) > 1e-12 * sv(0);
    inverse_square(k) = seen ? 1.0 / (sv(k) * sv(k)) : std::numeric_limits<double>::infinity();
  }
  const Eigen::MatrixXd& V = svd.matrixV();
  Eigen::MatrixXd cov = Eigen::MatrixXd::Zero(p, p);
  for (Eigen::Index k = 0; k < p; ++k) {
    if (std::isinf(inverse_square(k))) {
      for (Eigen::Index i = 0; i < p; ++i)
        if (V(i, k) != 0.0) cov(i, i) = std::numeric_limits<double>::infinity();
      continue;
    }
    cov += inverse_square(k) * V.col(k) * V.col(k).transpose();
  }
  cov *= r.residual_sd * r.residual_sd;
  r.correlation = Eigen::MatrixXd::Identity(p, p);
  for (Eigen::Index i = 0; i < p; ++i) {
    const FreeParameter& f = problem.free[static_cast<std::size_t>(i)];
    const double se_z = std::sqrt(cov(i, i));
    const double value = r.estimate[static_cast<std::size_t>(i)];
    const double zi = z[static_cast<std::size_t>(i)];
    r.standard_error.push_back(f.log_scale ? value * se_z : se_z);
    r.lower.push_back(from_fitted(f, zi - kQuantile975 * se_z));
    r.upper.push_back(from_fitted(f, zi + kQuantile975 * se_z));
    for (Eigen::Index k = 0; k < p; ++k) {
      if (k != i) r.correlation(i, k) = cov(i, k) / std::sqrt(cov(i, i) * cov(k, k));
      if (!std::isfinite(r.correlation(i, k))) r.correlation(i, k) = std::nan("");
    }
  }
  add_warnings(problem, r);
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
  check_problem(problem);
  std::vector<double> z;
  for (const FreeParameter& f : problem.free)
    z.push_back(to_fitted(f, info_of(f).value(problem.model.law)));
  ceres::Problem least_squares;
  for (const Curve& c : problem.curves)
    least_squares.AddResidualBlock(new CurveCost(problem, c), nullptr, z.data());
  for (std::size_t j = 0; j < z.size(); ++j) {
    const FreeParameter& f = problem.free[j];
    least_squares.SetParameterLowerBound(z.data(), static_cast<int>(j), to_fitted(f, f.lower));
    least_squares.SetParameterUpperBound(z.data(), static_cast<int>(j), to_fitted(f, f.upper));
  }
  ceres::Solver::Options options;
  options.minimizer_type = ceres::TRUST_REGION;
  options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = problem.max_iterations;
  options.function_tolerance = 1e-12;
  options.gradient_tolerance = 1e-14;
  options.parameter_tolerance = 1e-10;
  options.num_threads = 1;
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &least_squares, &summary);

  FitResult r;
  r.law = law_at(problem, z.data());
  for (const FreeParameter& f : problem.free) {
    r.names.emplace_back(info_of(f).name);
    r.estimate.push_back(info_of(f).value(r.law));
  }
  r.iterations = static_cast<int>(summary.iterations.size()) - 1;
  r.converged = summary.termination_type == ceres::CONVERGENCE;
  std::ostringstream how;
  how << (r.converged ? "converged" : "did not converge") << " after " << r.iterations
      << " iterations (" << summary.message << ")";
  if (!r.converged) {
    how << "; stopped at";
    for (std::size_t j = 0; j < z.size(); ++j)
      how << (j ? ", " : " ") << r.names[j] << " = " << r.estimate[j];
  }
  r.termination = how.str();
  add_statistics(problem, z, r);
  return r;
}

}  // namespace subslip::calibration
