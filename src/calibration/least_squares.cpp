#include "subslip/calibration/least_squares.hpp"

#include <ceres/ceres.h>

#include <Eigen/Dense>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace subslip::calibration {

namespace {

// The normal distribution's 97.5 % quantile: the intervals are linearised, and a fit has
// hundreds of points, where Student's t of its degrees of freedom is this to 1e-3.
constexpr double kQuantile975 = 1.959963984540054;

double to_fitted(const FreeParameter& f, double value) {
  return f.log_scale ? std::log(value) : value;
}
double from_fitted(const FreeParameter& f, double z) {
  return f.log_scale ? std::exp(z) : z;
}

std::vector<double> values_at(const LeastSquaresProblem& problem, const double* z) {
  std::vector<double> values(problem.free.size());
  for (std::size_t j = 0; j < values.size(); ++j) values[j] = from_fitted(problem.free[j], z[j]);
  return values;
}

// One curve's weighted residuals and their Jacobian in the fitted coordinates z: d/dz of a
// constant fitted as z = ln(value) is value d/d(value).
void weighted_residuals(const LeastSquaresProblem& problem, const CurveModel& curve,
                        const double* z, double* residuals, Eigen::MatrixXd* jacobian,
                        std::vector<double>& predicted) {
  const std::vector<double> values = values_at(problem, z);
  Eigen::MatrixXd gradient;
  curve.predict(values, predicted, gradient);
  const double w = std::sqrt(curve.weight);
  const auto n = static_cast<Eigen::Index>(curve.measured.size());
  for (Eigen::Index i = 0; i < n; ++i)
    residuals[i] =
        w * (predicted[static_cast<std::size_t>(i)] - curve.measured[static_cast<std::size_t>(i)]);
  if (!jacobian) return;
  *jacobian = w * gradient;
  for (std::size_t j = 0; j < values.size(); ++j)
    if (problem.free[j].log_scale) jacobian->col(static_cast<Eigen::Index>(j)) *= values[j];
}

class CurveCost : public ceres::CostFunction {
 public:
  CurveCost(const LeastSquaresProblem& problem, const CurveModel& curve)
      : problem_(problem), curve_(curve) {
    set_num_residuals(static_cast<int>(curve.measured.size()));
    mutable_parameter_block_sizes()->push_back(static_cast<int>(problem.free.size()));
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const bool want = jacobians && jacobians[0];
    Eigen::MatrixXd jacobian;
    std::vector<double> predicted;
    try {
      weighted_residuals(problem_, curve_, parameters[0], residuals, want ? &jacobian : nullptr,
                         predicted);
    } catch (const std::exception&) {
      return false;  // a trial the model cannot be computed at: the trust region shrinks
    }
    if (want)  // Ceres' blocks are row-major
      Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
          jacobians[0], jacobian.rows(), jacobian.cols()) = jacobian;
    return true;
  }

 private:
  const LeastSquaresProblem& problem_;
  const CurveModel& curve_;
};

void check_problem(const LeastSquaresProblem& problem) {
  if (problem.free.empty()) throw std::invalid_argument("fit: no free constant");
  std::size_t points = 0;
  for (const CurveModel& c : problem.curves) points += c.measured.size();
  if (points <= problem.free.size())
    throw std::invalid_argument("fit: " + std::to_string(points) + " points for " +
                                std::to_string(problem.free.size()) + " free constants");
  for (std::size_t j = 0; j < problem.free.size(); ++j) {
    const FreeParameter& f = problem.free[j];
    const double start = problem.start[j];
    if (!(start >= f.lower && start <= f.upper)) {
      std::ostringstream msg;
      msg << "fit: the start " << problem.names[j] << " = " << start << " lies outside its bounds ["
          << f.lower << ", " << f.upper << "]";
      throw std::invalid_argument(msg.str());
    }
  }
}

// The weighted Jacobian of every curve at z (rows: points, columns: free constants, fitted
// coordinates), with the model's curves.
Eigen::MatrixXd jacobian_at(const LeastSquaresProblem& problem, const std::vector<double>& z,
                            std::vector<std::vector<double>>& fitted, double& squares) {
  std::size_t rows = 0;
  for (const CurveModel& c : problem.curves) rows += c.measured.size();
  Eigen::MatrixXd J(static_cast<Eigen::Index>(rows), static_cast<Eigen::Index>(z.size()));
  squares = 0.0;
  fitted.clear();
  Eigen::Index row = 0;
  for (const CurveModel& c : problem.curves) {
    const auto n = static_cast<Eigen::Index>(c.measured.size());
    Eigen::VectorXd residuals(n);
    Eigen::MatrixXd block;
    std::vector<double> predicted;
    weighted_residuals(problem, c, z.data(), residuals.data(), &block, predicted);
    for (Eigen::Index i = 0; i < n; ++i) squares += residuals(i) * residuals(i);  // in order
    J.middleRows(row, n) = block;
    row += n;
    fitted.push_back(predicted);
  }
  return J;
}

void add_warnings(const LeastSquaresProblem& problem, FitResult& r) {
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
    text += "); " + (problem.advice ? problem.advice(r.names[j]) : std::string("more data")) +
            " would determine it";
    r.warnings.push_back(text);
  }
}

// Standard errors, intervals and correlations from the Jacobian at the estimate.
void add_statistics(const LeastSquaresProblem& problem, const std::vector<double>& z,
                    FitResult& r) {
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

FitResult least_squares_fit(const LeastSquaresProblem& problem) {
  check_problem(problem);
  std::vector<double> z;
  for (std::size_t j = 0; j < problem.free.size(); ++j)
    z.push_back(to_fitted(problem.free[j], problem.start[j]));
  ceres::Problem least_squares;
  for (const CurveModel& c : problem.curves)
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
  r.names = problem.names;
  r.estimate = values_at(problem, z.data());
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
