#include "cvode_solver.hpp"

#include <cvode/cvode_ls.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunlinsol/sunlinsol_spgmr.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace subslip::cvode::detail {

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kEulerGamma = std::numbers::egamma;

void check(int flag, const char* call) {
  if (flag < 0) throw std::runtime_error(std::string("CVODE set-up failed in ") + call);
}

}  // namespace

// ----- SubloadingVariable -----------------------------------------------------------------------

SubloadingVariable::SubloadingVariable(const law::SubloadingFrictionLaw& law)
    : law_(&law),
      function_(law.parameters().subloading.function),
      k_(function_ == law::SubloadingFunction::cot ? 0.5 * kPi * law.parameters().subloading.u_tilde
                                                   : law.parameters().subloading.u_tilde),
      start_(law.subloading_start(0.0)) {}

double SubloadingVariable::z_of(double r_s) const {
  if (r_s <= 0.0) return 0.0;
  if (r_s >= 1.0) return 1.0;
  return -std::expm1(-k_ * law_->subloading_slip_integral(r_s));
}

double SubloadingVariable::ratio_of(double z) const {
  if (!(z > 0.0)) return 0.0;
  if (z >= 1.0) return 1.0;
  // H = -ln(1 - z) / k, then the law's exact inverse of the slip integral from r_s = 0.
  return law_->subloading_ratio_after(start_, -std::log1p(-z) / k_).value;
}

double SubloadingVariable::slope(double r_s) const {
  // dz/dr_s = k exp(-k H(r_s)) / U(r_s), written in closed form so that it stays finite where
  // U is infinite (r_s = 0) or zero (r_s = 1).
  const double r = std::clamp(r_s, 0.0, 1.0);
  switch (function_) {
    case law::SubloadingFunction::cot:  // z = 1 - cos(pi r / 2)
      return 0.5 * kPi * std::sin(0.5 * kPi * r);
    case law::SubloadingFunction::reciprocal:  // z = 1 - (1 - r) e^r
      return r * std::exp(r);
    case law::SubloadingFunction::neg_log: {  // z = 1 - exp(Ei(ln r))
      if (r <= 0.0) return 0.0;
      const double minus_log = -std::log(r);
      if (minus_log < 1e-12) return std::exp(kEulerGamma) * r;  // limit at r -> 1
      return std::exp(std::expint(-minus_log)) / minus_log;
    }
  }
  return 0.0;
}

// ----- Solver -----------------------------------------------------------------------------------

Solver::Solver(int size, RhsFunction rhs, void* user, const CvodeOptions& options,
               const std::vector<double>& absolute_tolerance, bool krylov,
               const Preconditioner& preconditioner)
    : rhs_(rhs), user_(user), preconditioner_(preconditioner) {
  if (!(options.rtol > 0.0) || !(options.atol_scale > 0.0))
    throw std::invalid_argument("CVODE: rtol and atol_scale must be > 0");
  check(SUNContext_Create(nullptr, &ctx_), "SUNContext_Create");
  y_ = N_VNew_Serial(size, ctx_);
  atol_ = N_VNew_Serial(size, ctx_);
  scratch_ = N_VNew_Serial(size, ctx_);
  weights_ = N_VNew_Serial(size, ctx_);
  if (!y_ || !atol_ || !scratch_ || !weights_) throw std::runtime_error("CVODE: out of memory");
  N_VConst(0.0, y_);
  std::copy(absolute_tolerance.begin(), absolute_tolerance.end(), N_VGetArrayPointer(atol_));
  mem_ = CVodeCreate(CV_BDF, ctx_);
  if (!mem_) throw std::runtime_error("CVODE: CVodeCreate failed");
  check(CVodeSetErrHandlerFn(mem_, &Solver::error_handler, this), "CVodeSetErrHandlerFn");
  check(CVodeInit(mem_, &Solver::rhs_callback, 0.0, y_), "CVodeInit");
  check(CVodeSVtolerances(mem_, options.rtol, atol_), "CVodeSVtolerances");
  check(CVodeSetUserData(mem_, this), "CVodeSetUserData");
  check(CVodeSetMaxNumSteps(mem_, options.max_steps), "CVodeSetMaxNumSteps");
  check(CVodeSetMaxOrd(mem_, std::clamp(options.max_order, 1, 5)), "CVodeSetMaxOrd");
  check(CVodeSetMaxNonlinIters(mem_, options.max_nonlinear_iterations), "MaxNonlinIters");
  check(CVodeSetMaxConvFails(mem_, options.max_convergence_failures), "MaxConvFails");
  check(CVodeSetMaxErrTestFails(mem_, options.max_error_test_failures), "MaxErrTestFails");
  const double convergence_coefficient = options.nonlinear_convergence_coefficient > 0.0
                                             ? options.nonlinear_convergence_coefficient
                                         : krylov ? 0.01
                                                  : 0.001;
  check(CVodeSetNonlinConvCoef(mem_, convergence_coefficient), "CVodeSetNonlinConvCoef");
  if (options.initial_step > 0.0) check(CVodeSetInitStep(mem_, options.initial_step), "InitStep");
  if (krylov) {
    const bool preconditioned = preconditioner.solve != nullptr;
    linear_ = SUNLinSol_SPGMR(y_, preconditioned ? SUN_PREC_LEFT : SUN_PREC_NONE,
                              options.krylov_dimension, ctx_);
    check(CVodeSetLinearSolver(mem_, linear_, nullptr), "CVodeSetLinearSolver");
    if (preconditioned)
      check(CVodeSetPreconditioner(mem_, &Solver::setup_callback, &Solver::solve_callback),
            "CVodeSetPreconditioner");
  } else {
    matrix_ = SUNDenseMatrix(size, size, ctx_);
    linear_ = SUNLinSol_Dense(y_, matrix_, ctx_);
    check(CVodeSetLinearSolver(mem_, linear_, matrix_), "CVodeSetLinearSolver");
    check(CVodeSetJacFn(mem_, &Solver::jacobian_callback), "CVodeSetJacFn");
  }
}

int Solver::rhs_callback(double t, N_Vector y, N_Vector ydot, void* self) {
  auto& s = *static_cast<Solver*>(self);
  return s.rhs_(t, N_VGetArrayPointer(y), N_VGetArrayPointer(ydot), s.user_);
}

int Solver::jacobian_callback(double t, N_Vector y, N_Vector fy, SUNMatrix j, void* self, N_Vector,
                              N_Vector, N_Vector) {
  // CVODE's own difference quotients (forward, increment sqrt(eps) max(|y_j|, 1 / ewt_j)), with
  // one change: where the forward point is outside the admissible set (the right-hand side
  // refuses it, e.g. r >= r_hat close to the limit), the backward difference is taken instead
  // of failing the Jacobian and with it the step.
  auto& s = *static_cast<Solver*>(self);
  const double* y0 = N_VGetArrayPointer(y);
  const double* f0 = N_VGetArrayPointer(fy);
  const int n = static_cast<int>(N_VGetLength(y));
  const std::vector<double>& w = s.error_weights();
  s.column_.resize(static_cast<size_t>(n));
  s.perturbed_.assign(y0, y0 + n);
  const double root_eps = std::sqrt(std::numeric_limits<double>::epsilon());
  for (int c = 0; c < n; ++c) {
    const auto cs = static_cast<size_t>(c);
    const double h = root_eps * std::max(std::abs(y0[c]), 1.0 / w[cs]);
    double* col = SUNDenseMatrix_Column(j, c);
    bool ok = false;
    for (double sign : {1.0, -1.0}) {
      s.perturbed_[cs] = y0[c] + sign * h;
      ++s.jacobian_rhs_evaluations_;
      if (s.rhs_(t, s.perturbed_.data(), s.column_.data(), s.user_) != 0) continue;
      const double step = s.perturbed_[cs] - y0[c];  // the increment actually represented
      for (int r = 0; r < n; ++r) col[r] = (s.column_[static_cast<size_t>(r)] - f0[r]) / step;
      ok = true;
      break;
    }
    s.perturbed_[cs] = y0[c];
    if (!ok) return 1;  // recoverable: CVODE retries with a smaller step
  }
  return 0;
}

int Solver::setup_callback(double t, N_Vector y, N_Vector, booleantype jok, booleantype* jcur,
                           double gamma, void* self) {
  auto& s = *static_cast<Solver*>(self);
  bool recomputed = false;
  const int flag =
      s.preconditioner_.setup(t, N_VGetArrayPointer(y), jok == SUNTRUE, recomputed, gamma, s.user_);
  *jcur = recomputed ? SUNTRUE : SUNFALSE;
  return flag;
}

int Solver::solve_callback(double, N_Vector, N_Vector, N_Vector r, N_Vector z, double, double, int,
                           void* self) {
  auto& s = *static_cast<Solver*>(self);
  s.preconditioner_.solve(N_VGetArrayPointer(r), N_VGetArrayPointer(z), s.user_);
  return 0;
}

Solver::~Solver() {
  if (mem_) CVodeFree(&mem_);
  if (linear_) SUNLinSolFree(linear_);
  if (matrix_) SUNMatDestroy(matrix_);
  for (N_Vector v : {y_, atol_, scratch_, weights_})
    if (v) N_VDestroy(v);
  if (ctx_) SUNContext_Free(&ctx_);
}

void Solver::error_handler(int code, const char* module, const char* function, char* msg,
                           void* self) {
  // CVODE's messages go into the failure report instead of stderr (warnings are dropped).
  if (code > 0) return;
  static_cast<Solver*>(self)->message_ =
      std::string(module) + "::" + function + ": " + (msg ? msg : "");
}

void Solver::restart(double t0, double t_stop) {
  check(CVodeReInit(mem_, t0, y_), "CVodeReInit");
  jacobian_rhs_evaluations_ = 0;  // counted per segment, as CVODE counts
  check(CVodeSetStopTime(mem_, t_stop), "CVodeSetStopTime");
  initialised_ = true;
  t_ = t0;
  message_.clear();
}

bool Solver::integrate_to(double t_out, const std::function<void(double, const double*)>& on_step) {
  if (t_out <= t_) return true;
  if (!on_step) {
    const int flag = CVode(mem_, t_out, y_, &t_, CV_NORMAL);
    if (flag < 0) return false;
    t_ = t_out;
    return true;
  }
  // One step at a time; steps beyond t_out are interpolated back to it (the solver keeps its
  // history, so the next call continues from where the last step ended).
  double t_step = 0.0;
  if (CVodeGetCurrentTime(mem_, &t_step) < 0) return false;
  while (t_step < t_out) {
    const int flag = CVode(mem_, t_out, scratch_, &t_step, CV_ONE_STEP);
    if (flag < 0) return false;
    if (t_step < t_out) on_step(t_step, N_VGetArrayPointer(scratch_));
  }
  if (CVodeGetDky(mem_, t_out, 0, y_) < 0) return false;
  t_ = t_out;
  return true;
}

void Solver::add_counters(CvodeStats& s) const {
  if (!initialised_) return;
  long v = 0;
  auto add = [&](int (*get)(void*, long*), long& field) {
    v = 0;
    get(mem_, &v);
    field += v;
  };
  add(CVodeGetNumSteps, s.steps);
  add(CVodeGetNumRhsEvals, s.rhs_evaluations);
  add(CVodeGetNumLinRhsEvals, s.rhs_evaluations);  // Krylov: Jacobian-vector products
  s.rhs_evaluations += jacobian_rhs_evaluations_;  // dense: the difference quotients
  add(CVodeGetNumNonlinSolvIters, s.nonlinear_iterations);
  add(CVodeGetNumErrTestFails, s.error_test_failures);
  add(CVodeGetNumNonlinSolvConvFails, s.nonlinear_convergence_failures);
  if (matrix_) {
    add(CVodeGetNumJacEvals, s.jacobian_evaluations);
  } else {
    add(CVodeGetNumLinIters, s.linear_iterations);
    add(CVodeGetNumPrecSolves, s.preconditioner_solves);
  }
  int order = 0;
  CVodeGetLastOrder(mem_, &order);
  s.last_order = order;
}

const std::vector<double>& Solver::error_weights() {
  CVodeGetErrWeights(mem_, weights_);
  const double* w = N_VGetArrayPointer(weights_);
  weight_values_.assign(w, w + N_VGetLength(weights_));
  return weight_values_;
}

std::vector<double> output_times(double t0, const std::vector<double>& increments,
                                 int output_every) {
  std::vector<double> out;
  double t = t0;
  const size_t every = static_cast<size_t>(std::max(output_every, 1));
  for (size_t i = 0; i < increments.size(); ++i) {
    t += increments[i];
    if (i + 1 == increments.size() || (i + 1) % every == 0) out.push_back(t);
  }
  return out;
}

double scale_of(std::initializer_list<double> values, double floor) {
  double s = floor;
  for (double v : values) s = std::max(s, std::abs(v));
  return s;
}

}  // namespace subslip::cvode::detail
