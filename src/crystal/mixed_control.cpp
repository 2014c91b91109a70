#include "mixed_control.hpp"

#include "subslip/crystal/measures.hpp"
#include "subslip/integrators/inner_tolerance.hpp"

#include <Eigen/LU>
#include <Eigen/SVD>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>

namespace subslip::crystal::aggregate_parts {

namespace {

// The rate at which a segment ramps a free component's stress target from its value at the
// segment's start (0 for a segment of no duration).
double target_ramp(const LoadSegment& seg, const FreeComponent& c, const Mat3& stress_start) {
  return seg.duration > 0.0 ? (seg.stress_target(c.i, c.j) - stress_start(c.i, c.j)) / seg.duration
                            : 0.0;
}

constexpr double kSqrt2 = std::numbers::sqrt2;
constexpr int kMandelIndex[3][3] = {{0, 5, 4}, {5, 1, 3}, {4, 3, 2}};

// The free-stress Jacobian's singular value decomposition J = U S V^T and the residual r in its
// left singular basis, U^T r: both corrections below act on r one singular direction at a time.
struct SingularBasis {
  SingularBasis(const Eigen::MatrixXd& jac, const Eigen::VectorXd& r)
      : svd(jac, Eigen::ComputeFullU | Eigen::ComputeFullV),
        residual(svd.matrixU().transpose() * r) {}
  Eigen::JacobiSVD<Eigen::MatrixXd> svd;
  Eigen::VectorXd residual;
};

// The least change d of the free components of L whose linearised residual r + J d is at most
// `allowed` (2-norm): argmin |d| subject to |r + J d| <= allowed, the Tikhonov step
// d = -(J^T J + lambda I)^-1 J^T r with lambda where the bound is met (Morozov's discrepancy
// principle; lambda = 0, the Newton step, when it is met only there). Newton's own step solves
// the linearisation exactly, so where J is nearly singular (a grain aggregate at a yield vertex:
// a lateral mode that the stresses hardly resist, singular values 1e11 apart) it moves u far
// along that mode to remove a part of r far below the tolerance, out of the region where the
// linearisation holds. The least change removes the part of r that matters and leaves L where
// the stresses do not determine it.
Eigen::VectorXd least_change_step(const Eigen::MatrixXd& jac, const Eigen::VectorXd& r,
                                  double allowed) {
  const SingularBasis basis(jac, r);
  const Eigen::VectorXd& c = basis.residual;
  const Eigen::VectorXd& s = basis.svd.singularValues();
  // The residual left by the step of parameter lambda: components c_i lambda / (s_i^2 + lambda).
  const auto left = [&](double lambda) {
    double sum = 0.0;
    for (int i = 0; i < s.size(); ++i) {
      const double f = s(i) > 0.0 ? lambda / (s(i) * s(i) + lambda) : 1.0;
      sum += f * f * c(i) * c(i);
    }
    return std::sqrt(sum);
  };
  double lambda = 0.0;
  const double s_max = s.size() > 0 ? s(0) : 0.0;
  if (s_max > 0.0 && left(0.0) < allowed && allowed < c.norm()) {
    // left() rises monotonically from left(0) to |r|: bisection on log lambda. The bracket
    // s_max^2 e^-+80 holds every lambda that matters in double precision (above it left() is |r|
    // to 1e-35, below it the Newton step to the same), and 100 halvings of its 160 narrow it to
    // 1e-28, below the rounding of lambda: no iteration count decides the result.
    double lo = std::log(s_max * s_max) - 80.0, hi = std::log(s_max * s_max) + 80.0;
    for (int k = 0; k < 100; ++k) {
      const double mid = 0.5 * (lo + hi);
      (left(std::exp(mid)) < allowed ? lo : hi) = mid;
    }
    lambda = std::exp(lo);
  }
  Eigen::VectorXd along(s.size());
  for (int i = 0; i < s.size(); ++i)
    along(i) = s(i) > 0.0 ? -s(i) * c(i) / (s(i) * s(i) + lambda) : 0.0;
  return basis.svd.matrixV() * along;
}

// The change of the free components of L that removes the free-stress residual r to first
// order (Newton's change, -jac^-1 r), along the directions in which the stresses determine L:
// where a singular value s_i of the Jacobian is so small that a change as large as L itself
// (its largest entry) moves the stresses by no more than the tolerance, the tolerance leaves L
// along that direction undetermined to better than its own size, and it is not changed (at a
// yield vertex of a single crystal s_i / s_max reaches 1e-11; Newton's change along such a
// direction is what took the lateral flow to a far branch: docs/internals.md, "Mixed control").
Eigen::VectorXd error_correction(const Eigen::MatrixXd& jac, const Eigen::VectorXd& r,
                                 double tolerance, const Mat3& l) {
  const SingularBasis basis(jac, r);
  const Eigen::VectorXd& c = basis.residual;
  const Eigen::VectorXd& s = basis.svd.singularValues();
  const double size = l.cwiseAbs().maxCoeff();
  Eigen::VectorXd along = Eigen::VectorXd::Zero(s.size());
  for (int i = 0; i < s.size(); ++i)
    if (s(i) * size > tolerance) along(i) = -c(i) / s(i);
  return basis.svd.matrixV() * along;
}

// d(Mandel strain increment)/du_k per unit dt.
Vec6 strain_direction(const FreeComponent& c) {
  Vec6 e = Vec6::Zero();
  const int m = kMandelIndex[c.i][c.j];
  if (c.i == c.j) {
    e(m) = 1.0;
  } else {
    e(m) = c.symmetric_pair ? kSqrt2 : kSqrt2 / 2.0;  // D_ij = u or u/2, Mandel weight sqrt2
  }
  return e;
}

// Tensor component sigma_ij of a Mandel vector.
double component(const Vec6& v, int i, int j) {
  const int m = kMandelIndex[i][j];
  return i == j ? v(m) : v(m) / kSqrt2;
}

// The free components' entries of a stress (or of its change) in Mandel form, in fc's order: a
// column of the free stresses' Jacobian.
Eigen::VectorXd free_entries(const Vec6& v, const std::vector<FreeComponent>& fc) {
  Eigen::VectorXd out(static_cast<int>(fc.size()));
  for (size_t a = 0; a < fc.size(); ++a) out(static_cast<int>(a)) = component(v, fc[a].i, fc[a].j);
  return out;
}

}  // namespace

// L with the free components set to u.
Mat3 assemble_velocity_gradient(const Mat3& prescribed, const std::vector<FreeComponent>& fc,
                                const Eigen::VectorXd& u) {
  Mat3 l = prescribed;
  for (size_t k = 0; k < fc.size(); ++k) {
    l(fc[k].i, fc[k].j) = u(static_cast<int>(k));
    if (fc[k].symmetric_pair) l(fc[k].j, fc[k].i) = u(static_cast<int>(k));
  }
  return l;
}

// Where a segment's mixed-control iteration starts: the free components of L for which the
// grains' averaged elastic stiffness, in the sample frame, takes the free stresses from the
// segment's start along their ramp with the new prescribed components. The loading has just
// changed, and a change of loading begins elastically (an unloading, a reversal, a hold), so
// this is the start next to the solution the path continues along; the last segment's free
// components are not (a hold after loading started from the loading's lateral flow lands,
// at a yield vertex, on a far branch of the step's equations with a lateral flow of 1e-2 /s
// at constant stress: docs/internals.md, "Mixed control").
template <int N>
Eigen::VectorXd MixedControl<N>::elastic_free_start(const LoadSegment& seg,
                                                    const std::vector<FreeComponent>& fc,
                                                    const Mat3& stress_start) const {
  if (!cauchy_on_l(seg)) return general_elastic_start(seg, fc, stress_start);
  const int k = static_cast<int>(fc.size());
  const Mat6 stiffness = grains_.average_stiffness();
  const Eigen::VectorXd none = Eigen::VectorXd::Zero(k);
  const Vec6 prescribed_rate =
      stiffness * mandel_from_symmetric(
                      symmetric_part(assemble_velocity_gradient(seg.velocity_gradient, fc, none)));
  Eigen::MatrixXd jac(k, k);
  Eigen::VectorXd rhs(k);
  for (int a = 0; a < k; ++a) {
    const FreeComponent& c = fc[static_cast<size_t>(a)];
    rhs(a) = target_ramp(seg, c, stress_start) - component(prescribed_rate, c.i, c.j);
  }
  for (int b = 0; b < k; ++b)
    jac.col(b) = free_entries(stiffness * strain_direction(fc[static_cast<size_t>(b)]), fc);
  const Eigen::VectorXd u = jac.partialPivLu().solve(rhs);
  return u.allFinite() ? u : none;
}

// elastic_free_start for any rate and stress measure: the free components for which the
// stress measure's rate at the committed state, with the grains' averaged elastic stiffness,
// follows the ramp. At the step's start (dt -> 0) the velocity gradient is L, or
// dot_F F_n^-1, affine in the unknowns; the Cauchy stress rate is C : D + W sigma - sigma W, and
// P = J sigma F^-T changes at dP/dt = J (tr(L) sigma + dsigma/dt - sigma L^T) F^-T (from
// dJ/dt = J tr L and d(F^-T)/dt = -L^T F^-T): a k x k linear system.
template <int N>
Eigen::VectorXd MixedControl<N>::general_elastic_start(const LoadSegment& seg,
                                                       const std::vector<FreeComponent>& fc,
                                                       const Mat3& stress_start) const {
  const int k = static_cast<int>(fc.size());
  const Mat6 stiffness = grains_.average_stiffness();
  const Mat3& f = macro_.deformation_gradient;
  const Mat3 f_inv = f.inverse();
  const double j_det = f.determinant();
  const Mat3& sigma = macro_.stress;
  const auto velocity_gradient = [&](const Mat3& rate) -> Mat3 {
    return seg.rate_control == RateControl::velocity_gradient ? rate : Mat3(rate * f_inv);
  };
  const auto stress_rate = [&](const Mat3& l) -> Mat3 {
    const Mat3 w = 0.5 * (l - l.transpose());
    const Mat3 cauchy_rate =
        symmetric_from_mandel(stiffness * mandel_from_symmetric(symmetric_part(l))) + w * sigma -
        sigma * w;
    if (seg.stress_measure == StressMeasure::cauchy) return cauchy_rate;
    return j_det * (l.trace() * sigma + cauchy_rate - sigma * l.transpose()) * f_inv.transpose();
  };
  const Eigen::VectorXd none = Eigen::VectorXd::Zero(k);
  const Mat3 prescribed =
      stress_rate(velocity_gradient(assemble_velocity_gradient(prescribed_rate(seg), fc, none)));
  Eigen::MatrixXd jac(k, k);
  Eigen::VectorXd rhs(k);
  for (int a = 0; a < k; ++a) {
    const FreeComponent& c = fc[static_cast<size_t>(a)];
    rhs(a) = target_ramp(seg, c, stress_start) - prescribed(c.i, c.j);
  }
  for (int b = 0; b < k; ++b) {
    const Mat3 column = stress_rate(velocity_gradient(fc[static_cast<size_t>(b)].direction()));
    for (int a = 0; a < k; ++a)
      jac(a, b) = column(fc[static_cast<size_t>(a)].i, fc[static_cast<size_t>(a)].j);
  }
  const Eigen::VectorXd u = jac.partialPivLu().solve(rhs);
  return u.allFinite() ? u : none;
}

// Under dot_F the step's end is F_{n+1} = F_n + dot_F dt, so A = F_{n+1} F_n^-1 = I + dt B with
// B = dot_F F_n^-1, and the L whose Cayley map (I - L dt/2)^-1 (I + L dt/2) is A is
// L = (2/dt)(A - I)(A + I)^-1 = B (I + B dt/2)^-1 (all functions of B commute); written this
// way it has no cancellation in A - I for small steps. Under L the step's end is its Cayley map.
template <int N>
typename MixedControl<N>::StepKinematics MixedControl<N>::step_kinematics(
    const LoadSegment& seg, const std::vector<FreeComponent>& fc, const Eigen::VectorXd& u,
    double dt) const {
  const Mat3& f0 = macro_.deformation_gradient;
  const Mat3 half_identity = 0.5 * dt * Mat3::Identity();
  StepKinematics k;
  k.f_inv = f0.inverse();
  if (seg.rate_control == RateControl::velocity_gradient) {
    k.l = assemble_velocity_gradient(seg.velocity_gradient, fc, u);
    k.rate = k.l;
    const Mat3 half = 0.5 * dt * k.l;
    k.f = (Mat3::Identity() - half).lu().solve((Mat3::Identity() + half) * f0);
    return k;
  }
  const Mat3 dot_f = assemble_velocity_gradient(seg.deformation_rate, fc, u);
  k.rate = dot_f * k.f_inv;
  // L = B M^-1 with M = I + B dt/2: L^T = M^-T B^T, one LU solve.
  k.l = (Mat3::Identity() + half_identity * k.rate)
            .transpose()
            .lu()
            .solve(k.rate.transpose())
            .transpose();
  k.f = f0 + dot_f * dt;
  return k;
}

template <int N>
Mat3 MixedControl<N>::step_velocity_gradient(const LoadSegment& seg,
                                             const std::vector<FreeComponent>& fc,
                                             const Eigen::VectorXd& u, double dt) const {
  if (seg.rate_control == RateControl::velocity_gradient)
    return assemble_velocity_gradient(seg.velocity_gradient, fc, u);
  return step_kinematics(seg, fc, u, dt).l;
}

template <int N>
Mat3 MixedControl<N>::committed_stress(const LoadSegment& seg) const {
  return seg.stress_measure == StressMeasure::cauchy
             ? macro_.stress
             : first_piola_stress(macro_.stress, macro_.deformation_gradient);
}

// The Jacobian of the free stresses S (sigma or P = J sigma F^-T at the step's end) in the
// unknowns u, for any rate and measure, by the chain rule (docs/internals.md, "Mixed control
// under dot_F and P"). Per unknown b, with E_b its direction in the rate tensor:
//   G_b = dL/du_b:       L: E_b;   dot_F: (I - L dt/2) E_b F_n^-1 (I + B dt/2)^-1
//   H_b = dF_{n+1}/du_b: L: (dt/2) (I - L dt/2)^-1 E_b (F_{n+1} + F_n);   dot_F: E_b dt
//   d sigma = C_mean : sym(G_b) dt + (W_b sigma - sigma W_b) dt,  W_b = skew(G_b)
//   d P = J (tr(F^-1 H_b) sigma + d sigma - sigma F^-T H_b^T) F^-T
// with C_mean the grains' averaged consistent tangent of the iterate (all six strain
// directions: the rate's change moves every component of D once F is not the identity).
template <int N>
Eigen::MatrixXd MixedControl<N>::general_jacobian(const LoadSegment& seg,
                                                  const std::vector<FreeComponent>& fc,
                                                  const Eigen::VectorXd& u, double dt) const {
  const int k = static_cast<int>(fc.size());
  const Tangent tangent = grains_.mean_tangent({0, 1, 2, 3, 4, 5}, 6);
  const Mat3 sigma = symmetric_from_mandel(grains_.trial_average_stress());
  const StepKinematics kin = step_kinematics(seg, fc, u, dt);
  const Mat3& f0 = macro_.deformation_gradient;
  const Mat3 half_l = 0.5 * dt * kin.l;
  const Eigen::PartialPivLU<Mat3> end(kin.f);
  const Mat3 f_inv_t = end.inverse().transpose();
  const double j_det = end.determinant();
  Eigen::MatrixXd jac(k, k);
  for (int b = 0; b < k; ++b) {
    const Mat3 e = fc[static_cast<size_t>(b)].direction();
    Mat3 g, h;
    if (seg.rate_control == RateControl::velocity_gradient) {
      g = e;
      h = 0.5 * dt * (Mat3::Identity() - half_l).lu().solve(e * (kin.f + f0));
    } else {
      const Mat3 m = Mat3::Identity() + 0.5 * dt * kin.rate;
      g = (Mat3::Identity() - half_l) * e * kin.f_inv * m.inverse();
      h = dt * e;
    }
    const Mat3 w = 0.5 * (g - g.transpose());
    const Mat3 dsigma = (symmetric_from_mandel(tangent * mandel_from_symmetric(symmetric_part(g))) +
                         w * sigma - sigma * w) *
                        dt;
    Mat3 ds = dsigma;
    if (seg.stress_measure == StressMeasure::first_piola) {
      const double dj = (f_inv_t.transpose() * h).trace();
      ds = j_det * (dj * sigma + dsigma - sigma * f_inv_t * h.transpose()) * f_inv_t;
    }
    for (int a = 0; a < k; ++a)
      jac(a, b) = ds(fc[static_cast<size_t>(a)].i, fc[static_cast<size_t>(a)].j);
  }
  return jac;
}

// A step failed: the free components do not change smoothly over it (a change of the grains'
// active sets, or an L the stresses hardly determine, as in nearly ideal plasticity, which
// changes by jumps), so there is no trend to continue until two steps have committed again.
template <int N>
void MixedControl<N>::forget_free_trend() {
  path_.trend.setZero();
  path_.correction.setZero();
  path_.from_step = false;
}

// Records a committed step of dt that took the free components to `after`, `correction` (a
// strain) from removing its free-stress error to first order: the path's trend is its change
// per unit time where the last value was a committed step's too (FreePath).
template <int N>
void MixedControl<N>::record_free_step(const Eigen::VectorXd& after,
                                       const Eigen::VectorXd& correction, double dt) {
  FreePath& p = path_;
  const Eigen::VectorXd value = after + (correction - p.correction) / dt;
  if (p.from_step)
    p.trend = (value - p.value) / dt;
  else
    p.trend.setZero(after.size());
  p.value = value;
  p.correction = correction;
  p.from_step = true;
}

// The free stresses of the trial state minus their targets: the Cauchy stress, or P of the
// trial stress at the step's F_{n+1}.
template <int N>
typename MixedControl<N>::MixedResidual MixedControl<N>::free_stress_residual(
    const LoadSegment& seg, const std::vector<FreeComponent>& fc, const Mat3& target,
    const Eigen::VectorXd& u, double dt) const {
  const Vec6 sigma = grains_.trial_average_stress();
  MixedResidual r;
  r.value.resize(static_cast<int>(fc.size()));
  if (seg.stress_measure == StressMeasure::first_piola) {
    const Mat3 p =
        first_piola_stress(symmetric_from_mandel(sigma), step_kinematics(seg, fc, u, dt).f);
    for (size_t a = 0; a < fc.size(); ++a)
      r.value(static_cast<int>(a)) = p(fc[a].i, fc[a].j) - target(fc[a].i, fc[a].j);
  } else {
    for (size_t a = 0; a < fc.size(); ++a)
      r.value(static_cast<int>(a)) = component(sigma, fc[a].i, fc[a].j) - target(fc[a].i, fc[a].j);
  }
  r.merit = 0.5 * r.value.squaredNorm();
  r.size = r.value.cwiseAbs().maxCoeff();
  return r;
}

template <int N>
typename MixedControl<N>::StressResolution MixedControl<N>::stress_resolution(
    const Mat3& l, double dt, const AggregateOptions& opt) const {
  constexpr double kEps = std::numeric_limits<double>::epsilon();
  const double elastic =
      grains_.phase().stiffness.cwiseAbs().maxCoeff() * l.cwiseAbs().maxCoeff() * dt;
  const std::array<double, 2> largest = grains_.largest_stress_and_strength();
  return {16.0 * kEps * (largest[0] + elastic), 8.0 * opt.grain.tolerance * largest[1]};
}

// d(free stresses)/d(free components of L) from the averaged consistent tangents of the trial
// state (exact sums: independent of the thread and rank counts). A free component not paired with
// its transpose also spins: its skew part W turns the stress, d sigma = (W sigma - sigma W) dt
// (with it, L_13 free alone takes as few grain solves per increment as L_13 and L_31 free as a
// pair).
template <int N>
Eigen::MatrixXd MixedControl<N>::free_stress_jacobian(const LoadSegment& seg,
                                                      const std::vector<FreeComponent>& fc,
                                                      const Eigen::VectorXd& u, double dt) const {
  if (!cauchy_on_l(seg)) return general_jacobian(seg, fc, u, dt);
  // The grains' tangents are taken along the free components' strain directions: column b of
  // their mean is d sigma / d u_b per dt (GrainSweep::mean_tangent).
  const int k = static_cast<int>(fc.size());
  std::array<int, 6> rows{};
  for (int a = 0; a < k; ++a) {
    const FreeComponent& c = fc[static_cast<size_t>(a)];
    rows[static_cast<size_t>(a)] = kMandelIndex[c.i][c.j];
  }
  const Tangent mean_tangent = grains_.mean_tangent(rows, k);
  const Mat3 sigma = symmetric_from_mandel(grains_.trial_average_stress());
  Eigen::MatrixXd jac(k, k);
  for (int b = 0; b < k; ++b) {
    const FreeComponent& c = fc[static_cast<size_t>(b)];
    Vec6 dsigma = mean_tangent.col(b) * dt;
    if (!c.symmetric_pair && c.i != c.j) {
      const Mat3 e = c.direction();
      const Mat3 w = 0.5 * (e - e.transpose());
      dsigma += mandel_from_symmetric(w * sigma - sigma * w) * dt;
    }
    jac.col(b) = free_entries(dsigma, fc);
  }
  return jac;
}

// Solves the grains at the free components u; false (and why) when a grain fails. `warm`:
// from the rates of the previous iteration (solve_grains); the first of a step starts cold.
template <int N>
bool MixedControl<N>::evaluate_mixed(const LoadSegment& seg, const std::vector<FreeComponent>& fc,
                                     const Mat3& target, double dt, const Eigen::VectorXd& u,
                                     const AggregateOptions& opt, MixedIterate& out,
                                     std::string& why, bool warm, bool want_tangent) {
  ++stats_.mixed_iterations;
  const Mat3 l = step_velocity_gradient(seg, fc, u, dt);
  if (!grains_.solve(l, dt, want_tangent, opt, stats_, why, warm)) return false;
  out = {u, l, free_stress_residual(seg, fc, target, u, dt)};
  return true;
}

// Backtracking along the Newton update delta on the merit 1/2 |residual|^2 (Armijo): at stiff
// settings (G/tau0 ~ 1e5, strain steps ~ 1e-2) the full update computed from an elastic
// tangent overshoots the yield by orders of magnitude, and an L at which a grain fails counts
// as infinitely bad. Each trial costs one aggregate solve, taken from `budget`; `halvings`
// bounds the trials. On `decreased`, `it` is the new iterate (else the grains hold the last
// trial, not `it`); on `failed`, `why` says why.
template <int N>
typename MixedControl<N>::Search MixedControl<N>::mixed_line_search(
    const LoadSegment& seg, const std::vector<FreeComponent>& fc, const Mat3& target, double dt,
    const Eigen::VectorXd& delta, const AggregateOptions& opt, int halvings, MixedIterate& it,
    int& budget, std::string& why) {
  MixedIterate next;
  std::string grain_why;
  double alpha = 1.0;
  for (int ls = 0; ls < halvings && budget > 0; ++ls, alpha *= 0.5) {
    --budget;
    std::string trial_why;
    if (!evaluate_mixed(seg, fc, target, dt, it.u + alpha * delta, opt, next, trial_why)) {
      if (grain_why.empty()) grain_why = trial_why;
      continue;
    }
    if (next.residual.merit <= (1.0 - 1e-4 * alpha) * it.residual.merit) {
      it = std::move(next);
      return Search::decreased;
    }
  }
  std::ostringstream msg;
  msg << "mixed control: the free components of L did not converge (free stress error "
      << it.residual.size << ", not reduced along the Newton update";
  if (!grain_why.empty()) msg << "; there " << grain_why;
  msg << ")";
  why = msg.str();
  return Search::stalled;
}

// One attempt at the increment: fixed L, or Newton with a line search on the free components
// of L. Converged when the free stresses are within stress_tolerance x scale of their targets
// or within their round-off; or, when the error is already below the grains' own noise
// (StressResolution::grain_noise) and a short line search finds no decrease, at that noise:
// a tolerance tighter than what the state resolves is met as well as it can be, not failed.
//
// The iteration starts from the last step's free components, or with MixedPredictor::trend
// from those continued along their trend over the last step (on a loading path they change
// smoothly, so the first sweep lands at a second-order distance from the step's solution:
// fewer Newton iterations of the grains in the sweeps that follow). The trend is a guess:
// where the step fails from there (an L poorly determined by the stresses, as in nearly ideal
// plasticity, changes by jumps and has no trend) it is tried again from the last step's free
// components before it is cut back.
template <int N>
bool MixedControl<N>::try_step(const LoadSegment& seg, const std::vector<FreeComponent>& fc,
                               const Mat3& target, double dt, Eigen::VectorXd& u,
                               const AggregateOptions& opt, std::string& why) {
  step_correction_ = zero_correction(fc);
  free_stress_error_ = 0.0;
  if (fc.empty())
    return grains_.solve(step_velocity_gradient(seg, fc, u, dt), dt, false, opt, stats_, why);
  if (opt.predictor == MixedPredictor::last)
    return solve_free_components(seg, fc, target, dt, u, opt, why);
  const Eigen::VectorXd start = continued_free(u, dt);
  Eigen::VectorXd solution = start;
  if (!solve_free_components(seg, fc, target, dt, solution, opt, why)) {
    if (start == u) return false;
    solution = u;
    if (!solve_free_components(seg, fc, target, dt, solution, opt, why)) return false;
  }
  u = solution;
  return true;
}

// The free components' path continued along its trend over dt, plus the correction of the
// free-stress error the step inherits (FreePath); a component whose start would change sign
// from u (or start from zero) keeps its value u, as the grains' continued slip rates do
// (continued_rates): a component relaxing towards zero, as the lateral L of a hold does, over
// steps longer than its relaxation would be carried past zero.
template <int N>
Eigen::VectorXd MixedControl<N>::continued_free(const Eigen::VectorXd& u, double dt) const {
  const FreePath& p = path_;
  Eigen::VectorXd start =
      p.from_step ? Eigen::VectorXd(p.value + p.trend * dt + p.correction / dt) : u;
  for (int k = 0; k < start.size(); ++k)
    if (!(start(k) * u(k) > 0.0)) start(k) = u(k);
  return start;
}

// How close the free stresses are brought to their targets: stress_tolerance x scale, or with
// a run tolerance T (stress_tolerance_follows_tolerance) T / kResidualPerTolerance of the
// smallest strength of any slip system. An adaptive step's estimate, in units of the CRSS of the
// system deciding it, resolves nothing below the free-stress error over that CRSS, so a fixed
// relative tolerance was a floor under every run tolerance where a CRSS lies far below the
// stresses (0.163 MPa against the GPa of an HCP crystal's elastic directions: refused below
// about 3e-6), and at a loose run tolerance it only costs sweeps (a solve of the 1000-grain
// Taylor aggregate at 1e-2 or 1e-3 took three where two meet the tied tolerance, and the run's
// error moved by less than 10 %: docs/accuracy.md); tied, the floor is
// what the grains' solves resolve the free stresses to (`grain_noise`: below it the iteration
// could not converge) and the stresses' round-off.
// Backward Euler's own estimate (order 1) reads the slip rates, not the stresses, and a stress
// error leaves the free components of L, and with them the rates, uncertain by that error over
// the aggregate's softest tangent in the free directions, which at a yield vertex or in a
// nearly rate-independent lateral mode is 1e-6 of the elastic one or less, and changes by as
// much from one step to the next as systems load and unload. So its free stresses keep the
// fixed stress_tolerance wherever that is tighter: tied alone, the lateral split of L of a
// pyramidal <c+a> HCP aggregate (CRSS 0.163 MPa, G/tau0 = 1e5) jumped by 40 % from step to
// step and the estimate took 200 times the steps; tied through the softest direction of each
// step's Jacobian, a residual accepted where the mode was stiff was left to a step where it was
// soft, whose solve then failed (a copper [001] crystal's hold at G/tau0 = 1e5: 38409 steps and
// 76411 cutbacks instead of 204 steps).
// (Fixed steps compute nothing here: the two reductions over the grains are for adaptive runs.)
template <int N>
double MixedControl<N>::free_stress_tolerance(const AggregateOptions& opt, double scale,
                                              const Mat3& l, double dt) const {
  const double given = opt.stress_tolerance * scale;
  if (!opt.stress_tolerance_follows_tolerance || !(opt.tolerance > 0.0)) return given;
  const double tied =
      std::max(opt.tolerance / integrators::kResidualPerTolerance * grains_.smallest_strength(),
               stress_resolution(l, dt, opt).grain_noise);
  return opt.order == 1 ? std::min(given, tied) : tied;
}

// try_step's iteration from the free components u (on success their solution).
template <int N>
bool MixedControl<N>::solve_free_components(const LoadSegment& seg,
                                            const std::vector<FreeComponent>& fc,
                                            const Mat3& target, double dt, Eigen::VectorXd& u,
                                            const AggregateOptions& opt, std::string& why) {
  if (cauchy_on_l(seg)) {
    grains_.tangent_directions().resize(6, static_cast<int>(fc.size()));
    for (size_t b = 0; b < fc.size(); ++b)
      grains_.tangent_directions().col(static_cast<int>(b)) = strain_direction(fc[b]);
  } else {
    grains_.tangent_directions() = Mat6::Identity();
  }
  const double scale =
      std::max(target.cwiseAbs().maxCoeff(),
               std::max(macro_.stress.cwiseAbs().maxCoeff(), grains_.phase().tau0.maxCoeff()));
  // At most max_mixed_iterations Newton updates and twice as many aggregate solves in all
  // (line-search trials included): a step that fails is cut back, which is cheaper.
  int budget = 2 * opt.max_mixed_iterations;
  constexpr double kNearTolerance = 100.0;
  constexpr int kNonmonotoneUpdates = 5;
  int nonmonotone = 0;
  MixedIterate it;
  if (!evaluate_mixed(seg, fc, target, dt, u, opt, it, why, false, true)) return false;
  const double tolerance = free_stress_tolerance(opt, scale, it.l, dt);
  // The Jacobian of the step's first iterate serves every update of the step (a chord
  // iteration: the averaged tangent barely changes over the few iterations of one step, and
  // the later grain solves need no tangent); it is renewed where its update does not decrease
  // the error.
  Eigen::MatrixXd jacobian = free_stress_jacobian(seg, fc, it.u, dt);
  bool fresh = true;
  for (int iteration = 0;; ++iteration) {
    const StressResolution resolution = stress_resolution(it.l, dt, opt);
    if (it.residual.size <= std::max(tolerance, resolution.round_off)) {
      u = it.u;
      step_correction_ = dt * error_correction(jacobian, it.residual.value, tolerance, it.l);
      free_stress_error_ = it.residual.size;
      return true;
    }
    if (iteration == opt.max_mixed_iterations || budget == 0) break;
    // Half the tolerance is left to the step's own nonlinearity.
    const Eigen::VectorXd delta = least_change_step(
        jacobian, it.residual.value, 0.5 * std::max(tolerance, resolution.round_off));
    const double previous_size = it.residual.size;
    if (!delta.allFinite()) {
      why = "mixed control: non-finite Jacobian of the free stresses";
      return false;
    }
    const bool at_noise = it.residual.size <= resolution.grain_noise;
    const Search search =
        mixed_line_search(seg, fc, target, dt, delta, opt, at_noise ? 2 : 10, it, budget, why);
    if (search == Search::decreased) {
      // A chord iteration converges linearly; where it contracts the error by less than
      // half per update, Newton's own Jacobian is worth a tangent (docs/internals.md,
      // "Mixed control").
      const bool slow = it.residual.size > 0.5 * previous_size;
      if (slow && !fresh && budget-- > 0) {
        if (!evaluate_mixed(seg, fc, target, dt, it.u, opt, it, why, true, true)) return false;
        jacobian = free_stress_jacobian(seg, fc, it.u, dt);
        fresh = true;
      } else {
        fresh = false;
      }
      continue;
    }
    if (!fresh && budget-- > 0) {  // a stale Jacobian: renewed at the current iterate
      if (!evaluate_mixed(seg, fc, target, dt, it.u, opt, it, why, true, true)) return false;
      jacobian = free_stress_jacobian(seg, fc, it.u, dt);
      fresh = true;
      continue;
    }
    if (at_noise) {
      // No L does better than this one: the grains are re-solved there (the line search left
      // its last trial in them).
      if (!evaluate_mixed(seg, fc, target, dt, it.u, opt, it, why)) return false;
      u = it.u;
      step_correction_ = dt * error_correction(jacobian, it.residual.value, tolerance, it.l);
      free_stress_error_ = it.residual.size;
      return true;
    }
    // Near the tolerance the stress can be noisier than grain_noise says (measured at G/tau0
    // = 1e5 in long holds: ~1e-10 relative, where the Newton update is no descent direction):
    // there a few full, non-monotone updates are taken, which land within the tolerance.
    const bool near =
        it.residual.size <= kNearTolerance * std::max(tolerance, resolution.grain_noise);
    if (!near || nonmonotone++ == kNonmonotoneUpdates || budget-- <= 0) return false;
    if (!evaluate_mixed(seg, fc, target, dt, it.u + delta, opt, it, why)) return false;
  }
  std::ostringstream msg;
  msg << "mixed control: the free components of L did not converge in " << opt.max_mixed_iterations
      << " iterations (free stress error " << it.residual.size << ", tolerance " << tolerance
      << ")";
  why = msg.str();
  return false;
}

#define SUBSLIP_INSTANTIATE_MIXED_CONTROL(N) template class MixedControl<N>;

SUBSLIP_FOR_EACH_SLIP_COUNT(SUBSLIP_INSTANTIATE_MIXED_CONTROL)

}  // namespace subslip::crystal::aggregate_parts
