#include "subslip/calibration/crystal_fit.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace subslip::calibration {

namespace {

// The free components of the tension: L22 and L33, holding sigma22 and sigma33 (Mandel 1 and 2)
// at zero.
constexpr int kFreeCount = 2;
constexpr int kHeld[kFreeCount] = {1, 2};

// A held stress counts as zero within this fraction of the step's largest stress: the update's
// own round-off is about 1e-14 C |strain| (C the elastic stiffness), far below it, and the
// carried sensitivities take the held stresses as exactly zero, which this leaves at 1e-10 of
// the stress.
constexpr double kHeldStressTolerance = 1e-10;
constexpr int kMaxMixedIterations = 30;
constexpr double kEpsilon = std::numeric_limits<double>::epsilon();

Eigen::Matrix3d direction(int k) {
  Eigen::Matrix3d e = Eigen::Matrix3d::Zero();
  e(kHeld[k], kHeld[k]) = 1.0;
  return e;
}

Eigen::Matrix3d velocity_gradient(double axial_rate, const Eigen::Vector2d& u) {
  return Eigen::Vector3d(axial_rate, u(0), u(1)).asDiagonal();
}

void check_curve(const CrystalCurve& c) {
  const auto fail = [&](const std::string& why) {
    throw std::invalid_argument("crystal curve " + c.name + ": " + why);
  };
  if (!(std::isfinite(c.strain_rate) && c.strain_rate != 0.0))
    fail("the strain rate must be finite and nonzero");
  if (c.strain.empty() || c.strain.size() != c.stress.size())
    fail("needs as many stresses as strains, at least one");
  double last = 0.0;
  for (const double e : c.strain) {
    if (!(std::isfinite(e) && e * c.strain_rate > 0.0 && std::abs(e) > last))
      fail("its strains must be finite, of the strain rate's sign and growing in magnitude");
    last = std::abs(e);
  }
}

// The steps of a path from zero to `strains` (ln F11): equal steps of at most |last| /
// increments between consecutive measured points, each of which a step ends on.
std::vector<std::pair<double, bool>> strain_steps(const std::vector<double>& strains,
                                                  int increments) {
  const double most = std::abs(strains.back()) / std::max(increments, 1);
  std::vector<std::pair<double, bool>> steps;  // (strain increment, ends on a measured point)
  double from = 0.0;
  for (const double to : strains) {
    // A quotient a few ulps above a whole number is that number (equal spacings of the data).
    const double quotient = std::abs(to - from) / most * (1.0 - 8.0 * kEpsilon);
    const int n = std::max(1, static_cast<int>(std::ceil(quotient)));
    for (int k = 1; k <= n; ++k) steps.emplace_back((to - from) / n, k == n);
    from = to;
  }
  return steps;
}

}  // namespace

CrystalPrediction predict(const point::GrainParameters& phase, const CrystalCurve& curve,
                          const CrystalPathSteps& steps) {
  check_curve(curve);
  const point::GrainPoint grain(phase);
  point::GrainState state = grain.initial_state(curve.orientation);
  point::GrainSensitivity d = grain.initial_sensitivity();
  point::MixedControlSensitivity mixed;
  for (int k = 0; k < kFreeCount; ++k) {
    mixed.directions.push_back(direction(k));
    mixed.held.push_back(kHeld[k]);
  }
  CrystalPrediction out;
  out.gradient.resize(static_cast<Eigen::Index>(curve.strain.size()),
                      crystal::kGrainParameterCount);
  Eigen::Vector2d u = Eigen::Vector2d::Zero();  // L22, L33, continued from the last step
  double strain = 0.0;
  for (const auto& [increment, measured] : strain_steps(curve.strain, steps.increments)) {
    const double dt = increment / curve.strain_rate;
    // Newton on L22 and L33 with the update's consistent tangent: d sigma / d u_k = C_t e_k dt.
    bool held = false;
    for (int it = 0; it < kMaxMixedIterations && !held; ++it) {
      const point::GrainUpdate trial =
          grain.update(state, velocity_gradient(curve.strain_rate, u), dt);
      if (!trial.report.ok)
        throw std::runtime_error("crystal curve " + curve.name + ": the grain step at strain " +
                                 std::to_string(strain + increment) +
                                 " failed: " + trial.report.why);
      Eigen::Vector2d r;
      Eigen::Matrix2d jacobian;
      for (int h = 0; h < kFreeCount; ++h) {
        r(h) = trial.stress(kHeld[h]);
        for (int k = 0; k < kFreeCount; ++k)
          jacobian(h, k) = trial.tangent(kHeld[h], kHeld[k]) * dt;
      }
      held = r.lpNorm<Eigen::Infinity>() <=
             kHeldStressTolerance * trial.stress.lpNorm<Eigen::Infinity>();
      if (!held) u -= jacobian.partialPivLu().solve(r);
    }
    if (!held)
      throw std::runtime_error("crystal curve " + curve.name +
                               ": the lateral stresses did not "
                               "vanish within " +
                               std::to_string(kMaxMixedIterations) + " iterations at strain " +
                               std::to_string(strain + increment));
    const point::GrainUpdate step =
        grain.update(state, velocity_gradient(curve.strain_rate, u), dt, d, mixed);
    if (!step.report.ok)
      throw std::runtime_error("crystal curve " + curve.name + ": the grain step at strain " +
                               std::to_string(strain + increment) + " failed: " + step.report.why);
    state = step.state;
    strain += increment;
    if (!measured) continue;
    out.gradient.row(static_cast<Eigen::Index>(out.stress.size())) = d.sample_stress.row(0);
    out.stress.push_back(step.stress(0));
  }
  return out;
}

namespace {

bool is_initial_mu(const FreeParameter& f) {
  return f.index == crystal::kInitialMuColumn;
}

std::string name_of(const FreeParameter& f) {
  return is_initial_mu(f)
             ? std::string("initial_mu")
             : std::string(law::kLawParameters[static_cast<std::size_t>(f.index)].name);
}

// Every slip group's settings (the phase's families, or its custom systems').
std::vector<crystal::SlipGroupSettings*> groups_of(point::GrainParameters& phase) {
  std::vector<crystal::SlipGroupSettings*> out;
  if (!phase.custom_systems.empty()) return {&phase.custom_settings};
  for (crystal::SlipGroupSettings& g : phase.family_settings) out.push_back(&g);
  return out;
}

const crystal::SlipGroupSettings& first_group(const point::GrainParameters& phase) {
  return phase.custom_systems.empty() ? phase.family_settings.front() : phase.custom_settings;
}

double start_of(const CrystalFitProblem& problem, const FreeParameter& f) {
  const crystal::SlipGroupSettings& g = first_group(problem.phase);
  return is_initial_mu(f) ? g.initial_mu
                          : law::kLawParameters[static_cast<std::size_t>(f.index)].value(g.law);
}

// The phase with the free constants at `values` (in every slip group: they share one law).
point::GrainParameters phase_at(const CrystalFitProblem& problem,
                                const std::vector<double>& values) {
  point::GrainParameters phase = problem.phase;
  for (crystal::SlipGroupSettings* g : groups_of(phase)) {
    for (std::size_t j = 0; j < problem.free.size(); ++j) {
      const FreeParameter& f = problem.free[j];
      if (is_initial_mu(f))
        g->initial_mu = values[j];
      else
        law::kLawParameters[static_cast<std::size_t>(f.index)].ref(g->law) = values[j];
    }
  }
  return phase;
}

void check_free(const CrystalFitProblem& problem) {
  const bool from_mu_s = !(first_group(problem.phase).initial_mu > 0.0);
  for (const FreeParameter& f : problem.free) {
    if (f.index == crystal::kTau0Column)
      throw std::invalid_argument(
          "fit: tau0 cannot be free: scaling tau0 by c and mu_s, mu_k, kappa, xi and initial_mu "
          "by 1/c leaves every stress unchanged, so only the CRSS (mu tau0) is determined; fit "
          "mu_s or initial_mu instead");
    if (is_initial_mu(f) && from_mu_s)
      throw std::invalid_argument(
          "fit: initial_mu is free, but the phase starts from mu_s (give "
          "its initial_mu, or fit mu_s)");
    if (!(is_initial_mu(f) || (f.index >= 0 && f.index < law::kParameterCount)))
      throw std::invalid_argument("fit: free constant " + std::to_string(f.index) +
                                  " is no constant of a grain");
  }
}

// Which data would determine a constant a crystal fit leaves undetermined.
std::string crystal_advice(std::string_view name, int rates) {
  if (name == "eta_v" || name == "n" || name == "r_hat")
    return rates < 2 ? "curves at a second strain rate (and a third: eta_v, n and r_hat set how "
                       "the stress rises with the rate)"
                     : "curves over a wider range of strain rates";
  if (name == "mu_s" || name == "initial_mu")
    return "points through the yield point (the initial CRSS)";
  if (name == "mu_k" || name == "kappa")
    return "larger strains, toward where the hardening saturates";
  if (name == "xi") return "a hold or a slower test (xi is recovery with time)";
  if (name == "u_tilde") return "more points through the elastic-plastic transition";
  return "more data";
}

}  // namespace

FitResult fit(const CrystalFitProblem& problem) {
  check_free(problem);
  // One law, tau0 and initial_mu for every slip system, without plane pressure: what the grain's
  // sensitivities need (their message says which family differs).
  (void)point::GrainPoint(problem.phase).initial_sensitivity();
  LeastSquaresProblem ls;
  for (const FreeParameter& f : problem.free) {
    ls.names.push_back(name_of(f));
    ls.start.push_back(start_of(problem, f));
  }
  ls.free = problem.free;
  ls.max_iterations = problem.max_iterations;
  std::vector<double> rates;
  for (const CrystalCurve& c : problem.curves) {
    if (std::find(rates.begin(), rates.end(), c.strain_rate) == rates.end())
      rates.push_back(c.strain_rate);
    CurveModel m;
    m.measured = c.stress;
    m.weight = c.weight;
    m.predict = [&problem, &c](const std::vector<double>& values, std::vector<double>& predicted,
                               Eigen::MatrixXd& gradient) {
      const CrystalPrediction p = predict(phase_at(problem, values), c, problem.steps);
      predicted = p.stress;
      gradient.resize(p.gradient.rows(), static_cast<Eigen::Index>(problem.free.size()));
      for (std::size_t j = 0; j < problem.free.size(); ++j)
        gradient.col(static_cast<Eigen::Index>(j)) = p.gradient.col(problem.free[j].index);
    };
    ls.curves.push_back(std::move(m));
  }
  const int rate_count = static_cast<int>(rates.size());
  ls.advice = [rate_count](std::string_view name) { return crystal_advice(name, rate_count); };
  FitResult r = least_squares_fit(ls);
  r.law = first_group(phase_at(problem, r.estimate)).law;
  return r;
}

}  // namespace subslip::calibration
