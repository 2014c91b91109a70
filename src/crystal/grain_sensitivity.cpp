// The forward sensitivities of an implicit grain step (see grain_sensitivity.hpp).
//
// Whichever formulation converged the step (docs/grain_step.md), its end state solves the same
// equations: every slipping system's flow rule R_a(dgamma; s0, p) = 0, with the stress, mu, r_s
// and r written explicitly from the signed slips dgamma, the start state s0 and the constants p
// (the replay below, the kernel's formulas in the same order); a system that does not slip keeps
// dgamma_a = 0 and drops out. By the implicit function theorem at the converged slips,
//   d dgamma / dp = -R_dgamma^-1 (R_p + R_s0 ds0/dp),
// and the end state follows from dgamma by the chain rule: the replay once more, on slips that
// carry their derivatives. R_p + R_s0 ds0/dp and R_dgamma are jets of the replay (Ceres' Jet
// through the law's closed forms, law/parameter_jet.hpp), not differences.
#include "grain_sensitivity.hpp"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "subslip/law/parameter_jet.hpp"

namespace subslip::crystal {

namespace {

using Jet = law::GrainParameterJet;
constexpr int K = kGrainParameterCount;
static_assert(Jet::DIMENSION == K);

double value_of(double x) {
  return x;
}
double value_of(const Jet& x) {
  return x.a;
}

template <class T>
using Vec3Of = Eigen::Matrix<T, 3, 1>;
template <class T>
using Mat3Of = Eigen::Matrix<T, 3, 3>;
template <class T>
using Vec6Of = Eigen::Matrix<T, 6, 1>;
template <int N, class T>
using VecNOf = Eigen::Matrix<T, N, 1, 0, SlipTypes<N>::MaxN, 1>;

// rotation_exp (rotation.cpp) in any scalar: R = I + a [w] + b [w]^2, a = sin(t)/t,
// b = (1 - cos t)/t^2, by the same series below t^2 = 1/100 (no square root of a zero jet).
template <class T>
Mat3Of<T> rotation_exp_of(const Vec3Of<T>& w) {
  using std::cos;
  using std::sin;
  using std::sqrt;
  const T theta2 = w.squaredNorm();
  T a, b;
  if (value_of(theta2) < 1e-2) {
    constexpr double a1 = -1.0 / 6.0, a2 = 1.0 / 120.0, a3 = -1.0 / 5040.0, a4 = 1.0 / 362880.0;
    constexpr double b1 = -1.0 / 24.0, b2 = 1.0 / 720.0, b3 = -1.0 / 40320.0, b4 = 1.0 / 3628800.0;
    a = 1.0 + theta2 * (a1 + theta2 * (a2 + theta2 * (a3 + theta2 * a4)));
    b = 0.5 + theta2 * (b1 + theta2 * (b2 + theta2 * (b3 + theta2 * b4)));
  } else {
    const T theta = sqrt(theta2);
    const T sin_half = sin(0.5 * theta), cos_half = cos(0.5 * theta);
    a = 2.0 * sin_half * cos_half / theta;
    b = 2.0 * sin_half * sin_half / theta2;
  }
  Mat3Of<T> r = b * (w * w.transpose());
  for (int i = 0; i < 3; ++i) r(i, i) += 1.0 - b * theta2;
  r(0, 1) -= a * w.z(), r(1, 0) += a * w.z();
  r(0, 2) += a * w.y(), r(2, 0) -= a * w.y();
  r(1, 2) -= a * w.x(), r(2, 1) += a * w.x();
  return r;
}

// mandel_from_symmetric and symmetric_from_mandel (elasticity.cpp) in any scalar.
template <class T>
Vec6Of<T> mandel_of(const Mat3Of<T>& t) {
  constexpr double kSqrt2 = std::numbers::sqrt2;
  Vec6Of<T> v;
  v << t(0, 0), t(1, 1), t(2, 2), kSqrt2 * 0.5 * (t(1, 2) + t(2, 1)),
      kSqrt2 * 0.5 * (t(0, 2) + t(2, 0)), kSqrt2 * 0.5 * (t(0, 1) + t(1, 0));
  return v;
}
template <class T>
Mat3Of<T> symmetric_of(const Vec6Of<T>& v) {
  constexpr double kSqrt2 = std::numbers::sqrt2;
  const T t23 = v[3] / kSqrt2, t13 = v[4] / kSqrt2, t12 = v[5] / kSqrt2;
  Mat3Of<T> t;
  t << v[0], t12, t13, t12, v[1], t23, t13, t23, v[2];
  return t;
}

// The law's closed forms as the step takes them, in doubles and in jets.
struct DoubleLaw {
  const law::SubloadingFrictionLaw& law;
  double friction_coefficient_after(double mu0, double slip, double dt) const {
    return law.friction_coefficient_after(mu0, slip, dt).value;
  }
  double subloading_ratio_after(double r0, double slip) const {
    return law.subloading_ratio_after(std::clamp(r0, 0.0, 1.0), slip).value;
  }
  double flow_residual(double r, double r_s, double slip, double dt) const {
    return law.flow_residual(r, r_s, slip, dt).value;
  }
};
struct JetLaw {
  law::BasicSubloadingFrictionJet<Jet> jets;
  Jet friction_coefficient_after(const Jet& mu0, const Jet& slip, double dt) const {
    return jets.friction_coefficient_after(mu0, slip, Jet(dt));
  }
  Jet subloading_ratio_after(const Jet& r0, const Jet& slip) const {
    return jets.subloading_ratio_after(r0, slip);
  }
  Jet flow_residual(const Jet& r, const Jet& r_s, const Jet& slip, double dt) const {
    return jets.flow_residual(r, r_s, slip, Jet(dt));
  }
};

// The start of a step, and tau0, in a scalar.
template <int N, class T>
struct StartOf {
  Vec6Of<T> stress;
  Mat3Of<T> orientation;
  VecNOf<N, T> mu, r_s, slip;
  T tau0;
};

template <int N, class T>
struct EndOf {
  Vec6Of<T> stress, sample_stress;
  Mat3Of<T> orientation;
  VecNOf<N, T> mu, r_s, slip, residual;
};

// The strain increment and the spun orientation of a step (step_kinematics, kernel_detail.hpp).
template <class T>
struct KinematicsOf {
  Vec6Of<T> strain_increment;
  Mat3Of<T> spun_orientation;
};
template <class T>
KinematicsOf<T> kinematics_of(const Mat3Of<T>& g0, const Mat3Of<T>& L, double dt, Kinematics kind) {
  const Mat3Of<T> d = 0.5 * (L + L.transpose()), w_sample = 0.5 * (L - L.transpose());
  Mat3Of<T> g_mid = g0, spun = g0;
  if (kind == Kinematics::finite_rotation) {
    const Mat3Of<T> wl = g0 * w_sample * g0.transpose();
    const Vec3Of<T> w(wl(2, 1), wl(0, 2), wl(1, 0));
    g_mid = rotation_exp_of<T>(Vec3Of<T>(-0.5 * dt * w)) * g0;
    spun = rotation_exp_of<T>(Vec3Of<T>(-dt * w)) * g0;
  }
  return {mandel_of<T>(Mat3Of<T>(g_mid * d * g_mid.transpose())) * dt, spun};
}

// The step's end state from its signed slips, as the kernel writes it (step_kinematics,
// StressSolver::evaluate_slips and flow_point, orientation_after_plastic_spin, r_s = min(r_s, r)).
template <int N, class T, class Law>
EndOf<N, T> replay(const Phase<N>& ph, const Law& law, const StartOf<N, T>& s0, const Mat3Of<T>& L,
                   double dt, const VecNOf<N, T>& dgamma) {
  using std::abs;
  const int n = ph.slip_count;
  const KinematicsOf<T> kin = kinematics_of<T>(s0.orientation, L, dt, ph.kinematics);
  const Vec6Of<T> trial = s0.stress + ph.stiffness.template cast<T>() * kin.strain_increment;

  EndOf<N, T> e;
  e.stress = trial - ph.c_schmid.template cast<T>() * dgamma;
  const VecNOf<N, T> tau = ph.schmid.transpose().template cast<T>() * e.stress;
  const Vec6 stress_start = [&] {
    Vec6 s;
    for (int i = 0; i < 6; ++i) s(i) = value_of(s0.stress(i));
    return s;
  }();
  const typename SlipTypes<N>::VecN tau_start = ph.schmid.transpose() * stress_start;
  VecNOf<N, T> slip(n);
  for (int a = 0; a < n; ++a) slip(a) = abs(dgamma(a));
  for (VecNOf<N, T>* v : {&e.mu, &e.r_s, &e.slip, &e.residual}) v->resize(n);
  for (int a = 0; a < n; ++a) {
    // The effective slip that drives mu: sum_b q_ab |dgamma_b| with a latent matrix.
    T effective = slip(a);
    if (ph.has_latent) {
      effective = T(0.0);
      for (int b = 0; b < n; ++b) effective += ph.latent(a, b) * slip(b);
    }
    e.mu(a) = law.friction_coefficient_after(s0.mu(a), effective, dt);
    const T r = abs(tau(a)) / (e.mu(a) * s0.tau0);
    // (3.12): a system that slips (or, idle, is sheared) against its shear at the start starts
    // from r_s = 0.
    const double direction = value_of(dgamma(a)) != 0.0 ? value_of(dgamma(a)) : value_of(tau(a));
    const T r0 = direction * tau_start(a) < 0.0 ? T(0.0) : s0.r_s(a);
    const T r_s = law.subloading_ratio_after(r0, slip(a));
    e.residual(a) = value_of(dgamma(a)) != 0.0 ? law.flow_residual(r, r_s, slip(a), dt) : T(0.0);
    e.r_s(a) = value_of(r) < value_of(r_s) ? r : r_s;
    e.slip(a) = s0.slip(a) + dgamma(a);
  }
  e.orientation = kin.spun_orientation;
  if (ph.kinematics == Kinematics::finite_rotation)
    e.orientation = rotation_exp_of<T>(Vec3Of<T>(ph.slip_spin.template cast<T>() * dgamma)) *
                    kin.spun_orientation;
  e.sample_stress = mandel_of<T>(
      Mat3Of<T>(e.orientation.transpose() * symmetric_of<T>(e.stress) * e.orientation));
  return e;
}

template <class Row>
Jet jet_of(double value, const Row& gradient) {
  Jet j(value);
  j.v = gradient.transpose();
  return j;
}

// The start as jets: each variable with its derivatives `d`, tau0 seeded where `seed_tau0`.
template <int N>
StartOf<N, Jet> start_jets(const Phase<N>& ph, const GrainState<N>& s, const GrainSensitivity& d,
                           bool seed_tau0) {
  const int n = ph.slip_count;
  StartOf<N, Jet> j;
  for (int i = 0; i < 6; ++i) j.stress(i) = jet_of(s.stress(i), d.stress.row(i));
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r)
      j.orientation(r, c) = jet_of(s.orientation(r, c), d.orientation.row(r + 3 * c));
  for (VecNOf<N, Jet>* v : {&j.mu, &j.r_s, &j.slip}) v->resize(n);
  for (int a = 0; a < n; ++a) {
    j.mu(a) = jet_of(s.mu(a), d.mu.row(a));
    j.r_s(a) = jet_of(s.r_s(a), d.r_s.row(a));
    j.slip(a) = jet_of(s.slip(a), d.slip.row(a));
  }
  j.tau0 = seed_tau0 ? Jet(ph.tau0(0), kTau0Column) : Jet(ph.tau0(0));
  return j;
}

template <int N>
void write_gradients(const EndOf<N, Jet>& e, GrainSensitivity& d) {
  for (int i = 0; i < 6; ++i) {
    d.stress.row(i) = e.stress(i).v.transpose();
    d.sample_stress.row(i) = e.sample_stress(i).v.transpose();
  }
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) d.orientation.row(r + 3 * c) = e.orientation(r, c).v.transpose();
  for (int a = 0; a < e.mu.size(); ++a) {
    d.mu.row(a) = e.mu(a).v.transpose();
    d.r_s.row(a) = e.r_s(a).v.transpose();
    d.slip.row(a) = e.slip(a).v.transpose();
  }
}

}  // namespace

GrainSensitivity initial_grain_sensitivity(int n, bool initial_mu_is_mu_s) {
  static_assert(law::kLawParameters[0].name == "mu_s");
  GrainSensitivity d;
  for (SlipGradients* g : {&d.mu, &d.r_s, &d.slip}) g->setZero(n, K);
  d.mu.col(initial_mu_is_mu_s ? 0 : kInitialMuColumn).setOnes();
  return d;
}

namespace {

// The step's flow rules linearised in the slips at the converged ones: which systems slip, and
// the LU of R_dgamma over them (jets of the replay, K slips at a time, everything else constant).
struct SlipLinearisation {
  std::vector<int> active;
  Eigen::FullPivLU<Eigen::MatrixXd> lu;
};

template <int N>
SlipLinearisation linearise_in_slips(const Phase<N>& ph, const JetLaw& constant,
                                     const StartOf<N, Jet>& fixed, const Mat3Of<Jet>& L, double dt,
                                     const typename SlipTypes<N>::VecN& dgamma) {
  const int n = ph.slip_count;
  SlipLinearisation lin;
  for (int a = 0; a < n; ++a)
    if (dgamma(a) != 0.0) lin.active.push_back(a);
  const int m = static_cast<int>(lin.active.size());
  if (m == 0) return lin;
  VecNOf<N, Jet> slips(n);
  for (int a = 0; a < n; ++a) slips(a) = Jet(dgamma(a));
  Eigen::MatrixXd r_dgamma(m, m);
  for (int first = 0; first < m; first += K) {
    VecNOf<N, Jet> seeded_slips = slips;
    const int count = std::min(K, m - first);
    for (int k = 0; k < count; ++k)
      seeded_slips(lin.active[first + k]) = Jet(dgamma(lin.active[first + k]), k);
    const EndOf<N, Jet> e = replay(ph, constant, fixed, L, dt, seeded_slips);
    for (int i = 0; i < m; ++i)
      r_dgamma.block(i, first, 1, count) = e.residual(lin.active[i]).v.head(count).transpose();
  }
  lin.lu.compute(r_dgamma);
  if (!lin.lu.isInvertible())
    throw std::runtime_error("grain sensitivities: the step's flow rules are singular in its " +
                             std::to_string(m) + " slipping systems' slips");
  return lin;
}

// The end state in jets whose derivatives are those of `start`, `law` and `L`, the converged
// slips following them by the implicit function theorem: d dgamma = -R_dgamma^-1 R_x, R_x the
// residuals' derivatives at the slips held constant.
template <int N>
EndOf<N, Jet> differentiated_end(const Phase<N>& ph, const JetLaw& law,
                                 const StartOf<N, Jet>& start, const Mat3Of<Jet>& L, double dt,
                                 const typename SlipTypes<N>::VecN& dgamma,
                                 const SlipLinearisation& lin) {
  const int n = ph.slip_count, m = static_cast<int>(lin.active.size());
  VecNOf<N, Jet> slips(n);
  for (int a = 0; a < n; ++a) slips(a) = Jet(dgamma(a));
  if (m > 0) {
    const EndOf<N, Jet> at_root = replay(ph, law, start, L, dt, slips);
    Eigen::MatrixXd r_x(m, K);
    for (int i = 0; i < m; ++i) r_x.row(i) = at_root.residual(lin.active[i]).v.transpose();
    const Eigen::MatrixXd d_dgamma = -lin.lu.solve(r_x);
    for (int i = 0; i < m; ++i) slips(lin.active[i]).v = d_dgamma.row(i).transpose();
  }
  return replay(ph, law, start, L, dt, slips);
}

// Every end variable x of `e` gets x' = x'_p + x'_u du_dp: its derivatives with respect to the
// constants at fixed L, plus through the free components u of L (their derivatives, in `by_u`'s
// first columns, with respect to u).
template <int N>
void chain_free_components(EndOf<N, Jet>& e, const EndOf<N, Jet>& by_u,
                           const Eigen::Matrix<double, Eigen::Dynamic, K>& du_dp) {
  const auto k = du_dp.rows();
  const auto add = [&](Jet& x, const Jet& x_u) { x.v += du_dp.transpose() * x_u.v.head(k); };
  for (int i = 0; i < 6; ++i) add(e.stress(i), by_u.stress(i));
  for (int i = 0; i < 6; ++i) add(e.sample_stress(i), by_u.sample_stress(i));
  for (int i = 0; i < 9; ++i) add(e.orientation(i), by_u.orientation(i));
  for (int a = 0; a < e.mu.size(); ++a) {
    add(e.mu(a), by_u.mu(a));
    add(e.r_s(a), by_u.r_s(a));
    add(e.slip(a), by_u.slip(a));
  }
}

Mat3Of<Jet> constant_jets(const Mat3& L) {
  return L.cast<Jet>();
}

}  // namespace

template <int N>
void carry_grain_sensitivity(const Phase<N>& ph, const GrainState<N>& s0, const Mat3& L, double dt,
                             const GrainState<N>& s1, GrainSensitivity& d,
                             MixedControlSensitivity* mixed) {
  const auto& law = ph.laws.front();
  const JetLaw seeded{law::BasicSubloadingFrictionJet<Jet>(law, true)};
  const JetLaw constant{law::BasicSubloadingFrictionJet<Jet>(law, false)};
  // The converged slips (rate = dgamma / dt: zero exactly where the step did not slip).
  const typename SlipTypes<N>::VecN dgamma = s1.rate * dt;
  GrainSensitivity none;
  for (SlipGradients* g : {&none.mu, &none.r_s, &none.slip}) g->setZero(ph.slip_count, K);
  const StartOf<N, Jet> fixed = start_jets(ph, s0, none, false);
  const SlipLinearisation lin =
      linearise_in_slips(ph, constant, fixed, constant_jets(L), dt, dgamma);
  EndOf<N, Jet> e = differentiated_end(ph, seeded, start_jets(ph, s0, d, true), constant_jets(L),
                                       dt, dgamma, lin);
  if (mixed && !mixed->directions.empty()) {
    const auto k = static_cast<int>(mixed->directions.size());
    if (k > K || mixed->held.size() != mixed->directions.size())
      throw std::invalid_argument("grain sensitivities under mixed control: " + std::to_string(k) +
                                  " free directions for " + std::to_string(mixed->held.size()) +
                                  " held stress components (at most " + std::to_string(K) + ")");
    // The end state's derivatives with respect to the free components, the start and the law
    // held constant.
    Mat3Of<Jet> l_free = constant_jets(L);
    for (int c = 0; c < k; ++c)
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) l_free(i, j).v(c) = mixed->directions[c](i, j);
    const EndOf<N, Jet> by_u = differentiated_end(ph, constant, fixed, l_free, dt, dgamma, lin);
    // The held stresses keep their values: d sigma_h/du du/dp + d sigma_h/dp = 0.
    Eigen::MatrixXd s_u(k, k), s_p(k, K);
    for (int h = 0; h < k; ++h) {
      const Jet& sigma = by_u.sample_stress(mixed->held[h]);
      s_u.row(h) = sigma.v.head(k).transpose();
      s_p.row(h) = e.sample_stress(mixed->held[h]).v.transpose();
    }
    const Eigen::FullPivLU<Eigen::MatrixXd> lu(s_u);
    if (!lu.isInvertible())
      throw std::runtime_error(
          "grain sensitivities under mixed control: the held stresses do "
          "not depend on the free components of L independently");
    mixed->free_gradient = -lu.solve(s_p);
    chain_free_components(e, by_u, mixed->free_gradient);
  }
  write_gradients(e, d);
}

template <int N>
ReplayedStep<N> replayed_grain_step(const Phase<N>& ph, const GrainState<N>& s0, const Mat3& L,
                                    double dt, const typename SlipTypes<N>::VecN& dgamma) {
  const StartOf<N, double> start{s0.stress, s0.orientation, s0.mu, s0.r_s, s0.slip, ph.tau0(0)};
  const EndOf<N, double> e = replay(ph, DoubleLaw{ph.laws.front()}, start, Mat3Of<double>(L), dt,
                                    VecNOf<N, double>(dgamma));
  ReplayedStep<N> out;
  out.state.stress = e.stress;
  out.state.orientation = e.orientation;
  out.state.mu = e.mu;
  out.state.r_s = e.r_s;
  out.state.slip = e.slip;
  out.state.rate = dgamma / dt;
  out.residual = e.residual;
  return out;
}

#define SUBSLIP_GRAIN_SENSITIVITY(N)                                                           \
  template void carry_grain_sensitivity<N>(const Phase<N>&, const GrainState<N>&, const Mat3&, \
                                           double, const GrainState<N>&, GrainSensitivity&,    \
                                           MixedControlSensitivity*);                          \
  template ReplayedStep<N> replayed_grain_step<N>(const Phase<N>&, const GrainState<N>&,       \
                                                  const Mat3&, double,                         \
                                                  const typename SlipTypes<N>::VecN&);
SUBSLIP_FOR_EACH_SLIP_COUNT(SUBSLIP_GRAIN_SENSITIVITY)
#undef SUBSLIP_GRAIN_SENSITIVITY

}  // namespace subslip::crystal
