#include "subslip/crystal/crystal_kernel.hpp"

#include "kernel_detail.hpp"
#include "subslip/crystal/flow_point_batch.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>

#include <Eigen/Eigenvalues>

namespace subslip::crystal {

namespace {

using namespace detail;

// The friction-coefficient evolution (3.4) as dmu = slip |du_vp| + time dt at a given mu (the
// crystal reading: |du_vp| is the effective slip sum_b q_ab |dgamma_b|).
struct FrictionRateCoefficients {
  double slip, time;
};
FrictionRateCoefficients friction_rate_coefficients(const law::SubloadingFrictionLaw& law,
                                                    double mu) {
  const auto& f = law.parameters().friction;
  return {f.kappa * (1.0 - mu / f.mu_k), f.xi * (1.0 - mu / f.mu_s)};
}

// The orientation after a forward-Euler step: the lattice spins with W - W_p (lattice
// components omega), and g maps sample to crystal components, so g1 = exp(-[omega] dt) g0.
template <int N>
Mat3 rotated_orientation(const Phase<N>& ph, const Mat3& g0, const Vec3& lattice_spin,
                         const typename SlipTypes<N>::VecN& rate, double dt) {
  if (ph.kinematics == Kinematics::small_strain) return g0;
  const Vec3 omega = lattice_spin - ph.slip_spin * rate;
  return rotation_exp(-omega * dt) * g0;
}

// Writes q = s I + F R^T with the fewest columns: s is q's most repeated eigenvalue (symmetric
// q), so q - s I has rank n minus its multiplicity and its other eigenpairs give F and R. A
// non-symmetric q keeps s = 0, F = q, R = I. Once per phase, so dynamic sizes are fine here.
template <int N>
void factor_latent(Phase<N>& ph) {
  const int n = ph.slip_count;
  ph.latent_self = 1.0;
  ph.latent_rank = 0;
  ph.latent_factor.setZero(n, n);
  ph.latent_mix.setZero(n, n);
  if (!ph.has_latent) return;
  const Eigen::MatrixXd q = ph.latent;
  const double size = std::max(q.cwiseAbs().maxCoeff(), 1e-300);
  if (!q.isApprox(q.transpose(), 1e-14)) {
    ph.latent_self = 0.0;
    ph.latent_rank = n;
    ph.latent_factor = ph.latent;
    ph.latent_mix.setIdentity(n, n);
    return;
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(q);
  const Eigen::VectorXd& values = eig.eigenvalues();  // ascending
  const double same = 1e-10 * size;
  int best_first = 0, best_count = 0;
  for (int i = 0; i < n;) {
    int j = i;
    while (j < n && values(j) - values(i) <= same) ++j;
    if (j - i > best_count) best_first = i, best_count = j - i;
    i = j;
  }
  double shift = values.segment(best_first, best_count).mean();
  if (std::abs(shift) <= same) shift = 0.0;
  ph.latent_self = shift;
  int k = 0;
  for (int i = 0; i < n; ++i) {
    if (i >= best_first && i < best_first + best_count) continue;
    ph.latent_mix.col(k) = eig.eigenvectors().col(i);
    ph.latent_factor.col(k) = (values(i) - shift) * eig.eigenvectors().col(i);
    ++k;
  }
  ph.latent_rank = k;
}

}  // namespace

template <int N>
void Phase<N>::assemble(const std::vector<Vec3>& s, const std::vector<Vec3>& m, const Mat6& c) {
  const int n = static_cast<int>(s.size());
  slip_count = n;
  stiffness = c;
  compliance = c.inverse();
  schmid.resize(6, n), plane_normal_dyad.resize(6, n), slip_spin.resize(3, n);
  for (int a = 0; a < n; ++a) {
    const Mat3 sm = s[static_cast<size_t>(a)] * m[static_cast<size_t>(a)].transpose();
    schmid.col(a) = mandel_from_symmetric(0.5 * (sm + sm.transpose()));
    plane_normal_dyad.col(a) =
        mandel_from_symmetric(m[static_cast<size_t>(a)] * m[static_cast<size_t>(a)].transpose());
    slip_spin.col(a) = 0.5 * m[static_cast<size_t>(a)].cross(s[static_cast<size_t>(a)]);
  }
  c_schmid = c * schmid;
  schmid_dyads.setZero(kDyadRows, n);
  for (int a = 0; a < n; ++a)
    for (int j = 0, k = 0; j < 6; ++j)
      for (int i = j; i < 6; ++i) schmid_dyads(k++, a) = schmid(i, a) * schmid(j, a);
  interaction = schmid.transpose() * c_schmid;
  c_normal_dyad = c * plane_normal_dyad;
  normal_interaction = plane_normal_dyad.transpose() * c_schmid;
  if (tau0.size() != n) tau0 = SlipTypes<N>::VecN::Ones(n);
  if (latent.rows() != n) latent = SlipTypes<N>::MatNN::Identity(n, n);
  factor_latent(*this);
  // The batch leaves out the plane-pressure coefficient of the slips' Newton step.
  batched_flow_points =
      !pressure_sensitive && detail::flow_batches_pay() && detail::has_batched_flow_points(laws, n);
  // (No laws yet: a zero bound, so the quick test never passes and the full one decides.)
  ratio_limit = SlipTypes<N>::VecN::Zero(n);
  if (static_cast<int>(laws.size()) == n) {
    for (int a = 0; a < n; ++a) {
      const auto& o = laws[static_cast<size_t>(a)].parameters().overstress;
      ratio_limit(a) = o.form == law::OverstressForm::rate_independent ? 1.0 : o.r_hat;
    }
  }
}

template <int N>
void GrainState<N>::reset(int n, const Mat3& g, const typename SlipTypes<N>::VecN& mu0) {
  stress.setZero();
  orientation = g;
  mu = mu0;
  r_s = SlipTypes<N>::VecN::Zero(n);
  slip = SlipTypes<N>::VecN::Zero(n);
  rate = SlipTypes<N>::VecN::Zero(n);
}

template <int N>
Vec6 GrainState<N>::sample_stress() const {
  return mandel_from_symmetric(orientation.transpose() * symmetric_from_mandel(stress) *
                               orientation);
}

template <int N>
void slip_rates(const Phase<N>& ph, const GrainState<N>& s, SlipRates<N>& out) {
  const int n = ph.slip_count;
  out.tau = ph.schmid.transpose() * s.stress;
  out.fn = normal_traction(ph, s.stress);
  out.r.resize(n);
  out.rate.resize(n);
  for (int a = 0; a < n; ++a) {
    out.r(a) = std::abs(out.tau(a)) / (s.mu(a) * out.fn(a));
    out.rate(a) =
        ph.laws[static_cast<size_t>(a)].slip_rate(out.r(a), s.r_s(a)) * sign_of(out.tau(a));
  }
}

template <int N>
void grain_rates(const Phase<N>& ph, const GrainState<N>& s, const SlipRates<N>& slip,
                 const Mat3& L, GrainRates<N>& out) {
  using VecN = typename SlipTypes<N>::VecN;
  const int n = ph.slip_count;
  const LatticeKinematics k = lattice_kinematics(s.orientation, L);
  out.strain_rate = k.strain_rate;
  out.spin = k.spin;
  out.stress_rate = ph.stiffness * k.strain_rate - ph.c_schmid * slip.rate;
  out.lattice_spin = ph.kinematics == Kinematics::small_strain
                         ? Vec3::Zero()
                         : Vec3(k.spin - ph.slip_spin * slip.rate);
  const VecN magnitude = slip.rate.cwiseAbs();
  const VecN effective = ph.has_latent ? VecN(ph.latent * magnitude) : magnitude;
  out.mu_rate.resize(n);
  for (int a = 0; a < n; ++a) {
    const auto c = friction_rate_coefficients(ph.laws[static_cast<size_t>(a)], s.mu(a));
    out.mu_rate(a) = c.slip * effective(a) + c.time;
  }
}

template <int N>
typename SlipTypes<N>::VecN loading_ratio(const Phase<N>& ph, const GrainState<N>& s) {
  return loading_ratio_of(ph, s.stress, s.mu, normal_traction(ph, s.stress));
}

template <int N>
typename SlipTypes<N>::VecN normal_traction(const Phase<N>& ph, const GrainState<N>& s) {
  return detail::normal_traction(ph, s.stress);
}

template <int N>
typename SlipTypes<N>::VecN yield_scale(const Phase<N>& ph, const GrainState<N>& s) {
  // (Without the pressure-sensitive reading f_n = tau0: the CRSS.)
  return s.mu.cwiseProduct(ph.tau0.cwiseMax(detail::normal_traction(ph, s.stress)));
}

template <int N>
GrainStepReport restore_extrapolated_state(const Phase<N>& ph, const GrainState<N>& finest,
                                           GrainState<N>& s, double flow_residual) {
  const typename SlipTypes<N>::VecN fn = normal_traction(ph, s.stress);
  const typename SlipTypes<N>::VecN r = loading_ratio_of(ph, s.stress, s.mu, fn);
  for (int a = 0; a < ph.slip_count; ++a) {
    if (!(s.r_s(a) < 1.0) && finest.r_s(a) < 1.0) s.r_s(a) = finest.r_s(a);
    s.r_s(a) = std::clamp(s.r_s(a), 0.0, r(a));
  }
  GrainStepReport rep;
  // A saturated rate-independent system is at r = 1 in every solution, and their combination
  // rounds about it: admitted as far as the solutions' own steps admit it.
  rep.ok = admissible_state(ph, s, r, fn, rep, OpenPlanes::resolved, flow_residual);
  return rep;
}

// The first slip system for which a forward Euler step of dt is above its stability limit, or
// -1. A system relaxes a perturbation of its resolved shear stress at the rate
// lambda_a = A_aa phi_r / (mu_a f_n,a) (the contact's alpha_t phi_r / (f_n mu) with alpha_t ->
// A_aa), and forward Euler is stable only for dt lambda_a <= 2; beyond it the stress oscillates
// with a growing amplitude long before it leaves the admissible set. (Coupled systems can make
// a grain's fastest mode faster still; such steps are caught when they leave the admissible set.)
template <int N>
int unstable_system(const Phase<N>& ph, const GrainState<N>& s0, const SlipRates<N>& slip,
                    double dt) {
  for (int a = 0; a < ph.slip_count; ++a) {
    if (!(slip.fn(a) > 0.0)) continue;
    const double lambda = ph.laws[static_cast<size_t>(a)].traction_relaxation_rate(
        ph.interaction(a, a), slip.r(a), s0.r_s(a), s0.mu(a), slip.fn(a));
    if (!(dt * lambda <= 2.0)) return a;
  }
  return -1;
}

template <int N>
GrainStepReport explicit_grain_step(const Phase<N>& ph, const GrainState<N>& s0, const Mat3& L,
                                    double dt, GrainState<N>& s1, Tangent* tangent,
                                    integrators::ExplicitStability stability) {
  using VecN = typename SlipTypes<N>::VecN;
  const int n = ph.slip_count;
  GrainStepReport rep;
  for (const auto& law : ph.laws) {
    if (law.is_rate_independent()) {
      rep.why = "forward Euler needs an overstress form (rate_independent is implicit only)";
      return rep;
    }
  }
  // Forward Euler of the grain rates, except r_s (method 2 below) and the orientation (the
  // exponential map of the lattice spin, which keeps it a rotation).
  SlipRates<N> slip;
  GrainRates<N> rates;
  slip_rates(ph, s0, slip);
  if (const int a = stability == integrators::ExplicitStability::refuse_unstable_steps
                        ? unstable_system(ph, s0, slip, dt)
                        : -1;
      a >= 0) {
    rep.why = "forward Euler step above the stability limit 2/lambda of a slip system";
    rep.system = a;
    return rep;
  }
  grain_rates(ph, s0, slip, L, rates);
  const VecN dgamma = slip.rate * dt;
  s1.stress = s0.stress + ph.stiffness * (rates.strain_rate * dt) - ph.c_schmid * dgamma;
  const VecN magnitude = dgamma.cwiseAbs();
  const VecN effective = ph.has_latent ? VecN(ph.latent * magnitude) : magnitude;
  const VecN tau1 = ph.schmid.transpose() * s1.stress;
  const VecN fn1 = normal_traction(ph, s1.stress);
  VecN r1(n);
  s1.mu.resize(n), s1.r_s.resize(n);
  for (int a = 0; a < n; ++a) {
    const auto& law = ph.laws[static_cast<size_t>(a)];
    const double mu0 = s0.mu(a), rs0 = s0.r_s(a);
    const auto c = friction_rate_coefficients(law, mu0);
    s1.mu(a) = mu0 + c.slip * effective(a) + c.time * dt;
    double rs1 = rs0;
    if (magnitude(a) > 0.0) {
      // Method 2: forward Euler of (3.11); U(0) is infinite, so slip from r_s = 0 uses (2.28).
      rs1 = rs0 > 0.0 ? rs0 + law.subloading_rate(rs0) * magnitude(a)
                      : law.subloading_ratio_after(0.0, magnitude(a)).value;
    }
    r1(a) = std::abs(tau1(a)) / (s1.mu(a) * fn1(a));
    // (3.12) along the step's straight stress path: a shear that changes sign passes through
    // r = 0 and takes r_s with it (the next step's slip regrows it).
    if (tau1(a) * slip.tau(a) < 0.0) rs1 = 0.0;
    s1.r_s(a) = std::min(rs1, r1(a));
  }
  s1.slip = s0.slip + dgamma;
  s1.rate = dgamma / dt;
  s1.orientation = rotated_orientation(ph, s0.orientation, rates.spin, s1.rate, dt);
  if (!admissible_state(ph, s1, r1, fn1, rep)) return rep;
  if (tangent) {
    *tangent = mandel_rotation_operator(s1.orientation.transpose()) * ph.stiffness *
               mandel_rotation_operator(s0.orientation);
  }
  rep.ok = true;
  return rep;
}

#define SUBSLIP_INSTANTIATE_KERNEL(N)                                                            \
  template struct Phase<N>;                                                                      \
  template struct GrainState<N>;                                                                 \
  template GrainStepReport explicit_grain_step<N>(const Phase<N>&, const GrainState<N>&,         \
                                                  const Mat3&, double, GrainState<N>&, Tangent*, \
                                                  integrators::ExplicitStability);               \
  template SlipTypes<N>::VecN loading_ratio<N>(const Phase<N>&, const GrainState<N>&);           \
  template SlipTypes<N>::VecN normal_traction<N>(const Phase<N>&, const GrainState<N>&);         \
  template SlipTypes<N>::VecN yield_scale<N>(const Phase<N>&, const GrainState<N>&);             \
  template GrainStepReport restore_extrapolated_state<N>(const Phase<N>&, const GrainState<N>&,  \
                                                         GrainState<N>&, double);                \
  template void slip_rates<N>(const Phase<N>&, const GrainState<N>&, SlipRates<N>&);             \
  template void grain_rates<N>(const Phase<N>&, const GrainState<N>&, const SlipRates<N>&,       \
                               const Mat3&, GrainRates<N>&);

SUBSLIP_FOR_EACH_SLIP_COUNT(SUBSLIP_INSTANTIATE_KERNEL)

}  // namespace subslip::crystal
