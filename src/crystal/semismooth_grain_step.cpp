// The semismooth Newton grain step (see semismooth_grain_step.hpp).
#include "semismooth_grain_step.hpp"

#include <Eigen/LU>
#include <Eigen/QR>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "kernel_detail.hpp"
#include "subslip/integrators/scalar_root.hpp"

namespace subslip::crystal::detail {

namespace {

// What the Newton iteration needs at one iterate of the slip magnitudes x.
template <int N>
struct Iterate {
  using T = SlipTypes<N>;
  // x are the unknowns z_a = slip_a^(1/p_a) (p_a = 1 unless the power overstress is used).
  typename T::VecN x, slip, dslip_dx, effective, sign, tau, fn, mu, d_mu, rs, d_rs, r, merit_rows;
  typename T::VecN g_value, g_dr, g_drs, g_dslip;
  Eigen::Matrix<bool, N, 1, 0, T::MaxN, 1> active;  // row is the flow rule (else x_a = 0)
  Eigen::Matrix<bool, N, 1, 0, T::MaxN, 1> open;    // slip plane open (f_n <= 0): tau_a = 0
  double merit = 0.0;
  bool admissible = true;
  int bad_system = -1;
};

// Below this subloading ratio at the start of a step, a system that starts to slip gets its own
// scalar root first (see ImplicitSolver::needs_scalar_start).
constexpr double kSteepStartRatio = 1e-3;

// When a grain solve releases its systems from stale slip directions (see
// ImplicitSolver::stale_direction): after kReleaseAfterIterations Newton iterations, once every
// other row has converged, or in any case after kReleaseAnywayAfterIterations; at most
// kMaxDirectionReleases times (where directions cycle, slip one way turning another system's
// shear and back, the iteration then ends as before). Ordinary solves converge in fewer than 8
// iterations (2.6 per solve for FCC, 4.2 for BCC 48 in the benchmark) and meet stale directions
// only transiently. Releasing at every iteration sent systems of the nearly coplanar BCC families
// back and forth between directions, and releasing far from a solution (the 31.8 s hold step of
// crystal_law_edges.yaml from an overshooting warm start) reversed systems against a shear that the
// other systems' overshoot had turned, and the axial stress collapsed from -30.6 to -3 MPa. Stale
// slips that the line search halves for tens of iterations are released either way.
constexpr int kReleaseAfterIterations = 8;
constexpr int kReleaseAnywayAfterIterations = 30;
constexpr int kMaxDirectionReleases = 10;

template <int N>
class ImplicitSolver {
 public:
  using T = SlipTypes<N>;
  using VecN = typename T::VecN;
  using MatNN = typename T::MatNN;

  ImplicitSolver(const Phase<N>& ph, const GrainState<N>& s0, const Vec6& stress_trial, double dt)
      : ph_(ph), s0_(s0), dt_(dt), n_(ph.slip_count) {
    tau_trial_ = ph.schmid.transpose() * stress_trial;
    fn_trial_ = normal_traction(ph, stress_trial);
    tau_start_ = ph.schmid.transpose() * s0.stress;
    // Row scale c_a of min(c x, -G): how fast G falls with x, so that both branches measure
    // the same thing. That is the elastic stiffness of system a in ratio units, or, for a
    // viscous law over a short step, the overstress term's slope (eta_v (r_hat - r)/(n dt) can
    // exceed it by 1e11): with the elastic scale alone, a system slipping 1e-14 in a step would
    // sit on the x = 0 branch while G is still 1e-12 from its root, and Newton would throw
    // that slip away (G(0) ~ 0.2).
    scale_.resize(n_);
    const VecN fn_start = normal_traction(ph, s0.stress);
    for (int a = 0; a < n_; ++a) {
      const auto& law = ph.laws[static_cast<size_t>(a)];
      scale_(a) = std::max(
          ph.interaction(a, a) / (s0.mu(a) * ph.tau0(a)),
          law.viscous_slope_at_zero_slip(
              fn_start(a) > 0.0 ? std::abs(tau_start_(a)) / (s0.mu(a) * fn_start(a)) : 0.0, dt));
      auto& along = starts_[static_cast<size_t>(a)][0];
      auto& against = starts_[static_cast<size_t>(a)][1];
      along = {law.subloading_start(s0.r_s(a)), law.slip_exponent(), false};
      // (3.12): a system that slips against its shear at the start of the step has seen that
      // shear pass through zero, and r_s with it: it starts from r_s = 0. Its slip is spread
      // over the whole step, like any other: when the crossing happens is not known (the other
      // systems' slip moves the shear too), and placing it where the elastic predictor crosses
      // zero makes the step's response jump as that predictor passes zero (the slip time drops
      // from dt to 0), which stalled the mixed control of stiff HCP <c+a> aggregates.
      against = {law.subloading_start(0.0), law.slip_exponent(), true};
      // From a small r_s, dr_s/dslip = U(r_s) is infinite (r_s = 0) or huge at zero slip.
      along.steep_start = s0.r_s(a) < kSteepStartRatio;
    }
  }

  // How system a starts the step when it slips in direction `sign`.
  struct SystemStart {
    law::SubloadingFrictionLaw::SubloadingStart subloading;
    double exponent;   // p of the unknown z = slip^(1/p)
    bool steep_start;  // r_s starts (nearly) at 0, where U(r_s) is (nearly) infinite
  };
  const SystemStart& start(int a, double sign) const {
    return starts_[static_cast<size_t>(a)][sign * tau_start_(a) < 0.0 ? 1 : 0];
  }

  // Slip magnitude of an unknown z and back.
  double slip_of(int a, double sign, double z) const {
    const double p = start(a, sign).exponent;
    return p == 1.0 ? z : std::pow(z, p);
  }
  double unknown_of(int a, double sign, double slip) const {
    const double p = start(a, sign).exponent;
    return p == 1.0 ? slip : std::pow(slip, 1.0 / p);
  }

  void evaluate(const VecN& x, const VecN& sign, Iterate<N>& it) const {
    it.x = x;
    it.sign = sign;
    it.slip.resize(n_), it.dslip_dx.resize(n_);
    for (int a = 0; a < n_; ++a) it.slip(a) = slip_of(a, sign(a), x(a));
    const VecN dgamma = sign.cwiseProduct(it.slip);
    it.tau = tau_trial_ - ph_.interaction * dgamma;
    // An idle system may slip either way: its direction is that of its current shear (which
    // its own sign does not affect, its slip being zero).
    for (int a = 0; a < n_; ++a) {
      if (x(a) == 0.0) it.sign(a) = sign_of(it.tau(a));
      const double p = start(a, it.sign(a)).exponent;
      it.dslip_dx(a) = p == 1.0 ? 1.0 : p * std::pow(x(a), p - 1.0);
    }
    it.fn = ph_.pressure_sensitive ? VecN(fn_trial_ + ph_.normal_interaction * dgamma) : ph_.tau0;
    it.effective = ph_.has_latent ? VecN(ph_.latent * it.slip) : it.slip;
    const VecN& effective = it.effective;
    for (VecN* v : {&it.mu, &it.d_mu, &it.rs, &it.d_rs, &it.r, &it.g_value, &it.g_dr, &it.g_drs,
                    &it.g_dslip, &it.merit_rows})
      v->setZero(n_);
    it.active.setConstant(n_, false);
    it.open.setConstant(n_, false);
    it.admissible = true;
    it.bad_system = -1;
    for (int a = 0; a < n_; ++a) {
      const auto& law = ph_.laws[static_cast<size_t>(a)];
      const auto mu = law.friction_coefficient_after(s0_.mu(a), effective(a), dt_);
      const SystemStart& st = start(a, it.sign(a));
      const auto rs = law.subloading_ratio_after(st.subloading, it.slip(a));
      it.mu(a) = mu.value, it.d_mu(a) = mu.d_slip, it.rs(a) = rs.value, it.d_rs(a) = rs.d_slip;
      if (!(mu.value > 0.0) || std::isnan(it.fn(a))) {
        it.admissible = false, it.bad_system = a;
        it.merit = std::numeric_limits<double>::infinity();
        return;
      }
      if (!(it.fn(a) > 0.0)) {
        // An open slip plane carries no shear, like an open contact: the system slips freely
        // until tau_a = 0. Its row is that shear in ratio units (r = 0, no flow rule).
        it.open(a) = true;
        it.g_value(a) = it.sign(a) * it.tau(a) / (mu.value * ph_.tau0(a));
        it.active(a) = scale_(a) * x(a) > -it.g_value(a);
        it.merit_rows(a) = it.active(a) ? -it.g_value(a) : scale_(a) * x(a);
        continue;
      }
      it.r(a) = it.sign(a) * it.tau(a) / (mu.value * it.fn(a));
      const auto g = law.flow_residual(it.r(a), rs.value, it.slip(a), dt_);
      it.g_value(a) = g.value, it.g_dr(a) = g.d_r, it.g_drs(a) = g.d_rs, it.g_dslip(a) = g.d_slip;
      const double inactive_row = scale_(a) * x(a);
      it.active(a) = inactive_row > -g.value;
      it.merit_rows(a) = it.active(a) ? -g.value : inactive_row;
      if (!g.admissible) it.admissible = false, it.bad_system = a;
    }
    it.merit =
        it.admissible ? 0.5 * it.merit_rows.squaredNorm() : std::numeric_limits<double>::infinity();
  }

  // d(rows)/dx at an iterate (semismooth Newton: each row differentiated on its branch), as
  // diagonal scalings of the phase's constant matrices:
  //   dr_a/dslip_b = -s_a A_ab s_b/(mu_a fn_a) - (r_a/mu_a) dmu_a q_ab - (r_a/fn_a) N_ab s_b,
  //   row_a = -G_a, so J_ab = -dG_a/dr_a dr_a/dslip_b - delta_ab (dG_a/dr_s dr_s/dslip +
  //   dG_a/dslip).
  MatNN jacobian(const Iterate<N>& it) const {
    const VecN g_dr_over_mu = it.g_dr.cwiseQuotient(it.mu);
    const VecN elastic_row = g_dr_over_mu.cwiseProduct(it.sign).cwiseQuotient(it.fn);
    MatNN j = elastic_row.asDiagonal() * ph_.interaction * it.sign.asDiagonal();
    const VecN hardening_row = g_dr_over_mu.cwiseProduct(it.r).cwiseProduct(it.d_mu);
    if (ph_.has_latent) {
      j.noalias() += hardening_row.asDiagonal() * ph_.latent;
    } else {
      j.diagonal() += hardening_row;
    }
    if (ph_.pressure_sensitive) {
      const VecN pressure_row = it.g_dr.cwiseProduct(it.r).cwiseQuotient(it.fn);
      j.noalias() += pressure_row.asDiagonal() * ph_.normal_interaction * it.sign.asDiagonal();
    }
    j.diagonal() -= it.g_drs.cwiseProduct(it.d_rs) + it.g_dslip;
    for (int a = 0; a < n_; ++a) {
      // Open plane: d(-s_a tau_a/(mu_a tau0_a))/dslip_b = s_a A_ab s_b/(mu_a tau0_a) (mu frozen:
      // its term vanishes with tau_a at the solution).
      if (!it.open(a)) continue;
      j.row(a) =
          it.sign(a) / (it.mu(a) * ph_.tau0(a)) * ph_.interaction.row(a) * it.sign.asDiagonal();
    }
    j = j * it.dslip_dx.asDiagonal();  // d/dslip -> d/dx
    for (int a = 0; a < n_; ++a) {
      if (it.active(a)) continue;
      j.row(a).setZero();
      j(a, a) = scale_(a);
    }
    return j;
  }

  // d(rows)/d(strain increment), for the consistent tangent.
  typename T::MatN6 strain_jacobian(const Iterate<N>& it) const {
    typename T::MatN6 j = T::MatN6::Zero(n_, 6);
    for (int a = 0; a < n_; ++a) {
      if (!it.active(a)) continue;
      if (it.open(a)) {
        j.row(a) = -it.sign(a) / (it.mu(a) * ph_.tau0(a)) * ph_.c_schmid.col(a).transpose();
        continue;
      }
      Eigen::Matrix<double, 1, 6> dr =
          it.sign(a) * ph_.c_schmid.col(a).transpose() / (it.mu(a) * it.fn(a));
      if (ph_.pressure_sensitive) dr += it.r(a) / it.fn(a) * ph_.c_normal_dyad.col(a).transpose();
      j.row(a) = -it.g_dr(a) * dr;
    }
    return j;
  }

  const VecN& tau_trial() const { return tau_trial_; }

  // Newton cannot start an active system at zero slip where its slope is infinite or huge
  // (dr_s/dslip = U(r_s) from r_s = 0 or nearly 0, as after a reversal; dG/dslip with the power
  // overstress, G ~ -slip^(1/n)), or where its Jacobian column vanishes (in z = slip^(1/p),
  // p > 1, dslip/dz = 0). Such a system gets its own scalar root instead (the coupled Newton
  // holds it meanwhile); from there its slopes are moderate.
  bool needs_scalar_start(const Iterate<N>& it, int a) const {
    if (!it.active(a)) return false;
    const SystemStart& st = start(a, it.sign(a));
    const bool steep = it.x(a) == 0.0 && (st.exponent != 1.0 || st.steep_start);
    return steep || !std::isfinite(it.d_rs(a)) || !std::isfinite(it.g_dslip(a));
  }

  bool newton_can_start(const Iterate<N>& it) const {
    for (int a = 0; a < n_; ++a)
      if (needs_scalar_start(it, a)) return false;
    return true;
  }

  // The flow rule of system a alone, the other systems' slips frozen at `it`: one bracketed
  // scalar equation exactly like a single contact's. Returns the unknown x_a (0 if no slip).
  double solve_single(int a, const Iterate<N>& it, double tolerance) const {
    const auto& law = ph_.laws[static_cast<size_t>(a)];
    const double stiffness = ph_.interaction(a, a);
    const double fn = it.fn(a);
    // Shear on a (signed along its slip) and effective slip with a's own slip taken out.
    const double tau_free = it.sign(a) * it.tau(a) + stiffness * it.slip(a);
    const double effective_other = it.effective(a) - it.slip(a);
    if (!(tau_free > 0.0)) return 0.0;
    if (!(fn > 0.0)) return unknown_of(a, it.sign(a), tau_free / stiffness);  // open: tau_a = 0
    const SystemStart& st = start(a, it.sign(a));
    const double p = st.exponent;
    auto residual = [&](double z) {
      const double slip = p == 1.0 ? z : std::pow(z, p);
      const auto mu = law.friction_coefficient_after(s0_.mu(a), effective_other + slip, dt_);
      const auto rs = law.subloading_ratio_after(st.subloading, slip);
      const double r = (tau_free - stiffness * slip) / (mu.value * fn);
      const double dr = -stiffness / (mu.value * fn) - r / mu.value * mu.d_slip;
      const auto g = law.flow_residual(r, rs.value, slip, dt_);
      if (!g.admissible) return std::pair{g.value, 0.0};
      const double dslip_dz = p == 1.0 ? 1.0 : p * std::pow(z, p - 1.0);
      return std::pair{g.value, (g.d_r * dr + g.d_rs * rs.d_slip + g.d_slip) * dslip_dz};
    };
    if (residual(0.0).first <= 0.0) return 0.0;
    const double z_max = unknown_of(a, it.sign(a), tau_free / stiffness);
    const auto root = safeguarded_newton(residual, 0.0, z_max, 0.5 * z_max, tolerance,
                                         4.0 * std::numeric_limits<double>::epsilon(), 1e-300);
    return root.x;
  }

  // A start the coupled Newton can work from: finite slopes (no system at zero slip with
  // r_s = 0, where dr_s/dslip = U(0) is infinite) and admissible (every r_a < r_hat). Offending
  // systems get their own scalar solution (a Jacobi sweep); a few sweeps suffice since slip on
  // one system only relaxes the others (A is positive semi-definite).
  bool make_admissible(VecN& x, VecN& sign, Iterate<N>& it, double tolerance,
                       int rounds = 8) const {
    evaluate(x, sign, it);
    for (int round = 0; round < rounds; ++round) {
      bool changed = false;
      for (int a = 0; a < n_; ++a) {
        if (!needs_scalar_start(it, a) && std::isfinite(it.g_value(a))) continue;
        sign(a) = it.sign(a);
        const double z = solve_single(a, it, tolerance);
        changed = changed || z != x(a);
        x(a) = z;
      }
      if (!changed) break;
      evaluate(x, sign, it);
    }
    return it.admissible;
  }

  // Moves an inadmissible start (some r_a >= r_hat, typically a large elastic trial) into the
  // admissible set: each offending system gets the slip that, through its own diagonal
  // stiffness, brings r_a to the middle of [r_s,a, r_hat]. Slip on a system relaxes the others
  // too (A is positive semi-definite), so a few rounds suffice; the Newton iteration then starts
  // from an admissible point and converges to the same root whatever the start.
  bool make_admissible(VecN& x, VecN& sign, Iterate<N>& it, int rounds = 30) const {
    for (int round = 0; round < rounds; ++round) {
      evaluate(x, sign, it);
      if (it.admissible) return true;
      if (it.bad_system >= 0 && !(it.fn(it.bad_system) > 0.0)) return false;
      for (int a = 0; a < n_; ++a) {
        const auto& o = ph_.laws[static_cast<size_t>(a)].parameters().overstress;
        if (o.form == law::OverstressForm::rate_independent || it.r(a) < o.r_hat) continue;
        const double target = 0.5 * (it.rs(a) + o.r_hat);
        if (x(a) == 0.0) sign(a) = sign_of(it.tau(a));
        const double more =
            (sign(a) * it.tau(a) - target * it.mu(a) * it.fn(a)) / ph_.interaction(a, a);
        x(a) = unknown_of(a, sign(a), it.slip(a) + more);
      }
    }
    evaluate(x, sign, it);
    return it.admissible;
  }

  // An admissible start from (x, sign): the Jacobi sweep freezes the other systems' slip and
  // normal traction; when that does not reach the admissible set (pressure-sensitive planes, or
  // a large trial with too little slip), every offending system is moved below r_hat first and
  // swept again.
  bool admissible_start(VecN& x, VecN& sign, Iterate<N>& it, double tolerance) const {
    return make_admissible(x, sign, it, tolerance) ||
           (make_admissible(x, sign, it) && make_admissible(x, sign, it, tolerance));
  }

  // A system on the x = 0 branch (inactive row) whose slip is still positive in a direction its
  // shear has turned against. The Newton step takes such a slip to zero, but at zero its
  // direction follows the shear and its row there (slip the other way) is large, so the line
  // search halves the slip instead, iteration after iteration (54 times in the regression test),
  // until c x is within tolerance: the iterate "converges" with the system loaded in the wrong
  // direction (finding 6 of docs/extreme_cases.md: r = 1.9 > r_hat in FCC at G/tau0 = 1e5).
  bool stale_direction(const Iterate<N>& it, int a) const {
    return !it.active(a) && it.x(a) > 0.0 && it.sign(a) * it.tau(a) < 0.0;
  }

  // The unknowns of `it` with the slips of the systems `which(a)` selects set to zero; `zeroed`
  // marks the systems that had slip. Their directions are re-derived from their shear when the
  // result is evaluated.
  using SystemFlags = std::array<bool, T::MaxN>;
  template <class Which>
  VecN with_slips_zeroed(const Iterate<N>& it, Which&& which, SystemFlags& zeroed) const {
    VecN x = it.x;
    zeroed.fill(false);
    for (int a = 0; a < n_; ++a) {
      if (x(a) == 0.0 || !which(a)) continue;
      x(a) = 0.0;
      zeroed[static_cast<size_t>(a)] = true;
    }
    return x;
  }
  static bool any_of(const SystemFlags& flags) {
    return std::find(flags.begin(), flags.end(), true) != flags.end();
  }

  // Whether to release the stale directions of an iterate (see kReleaseAfterIterations): at most
  // kMaxDirectionReleases times, and once every other row is within `allowed` or in any case
  // after kReleaseAnywayAfterIterations.
  bool should_release(const Iterate<N>& it, const VecN& allowed, int iterations,
                      int releases) const {
    if (iterations < kReleaseAfterIterations || releases >= kMaxDirectionReleases) return false;
    if (iterations >= kReleaseAnywayAfterIterations) return true;
    for (int a = 0; a < n_; ++a)
      if (!stale_direction(it, a) && std::abs(it.merit_rows(a)) > allowed(a)) return false;
    return true;
  }

  // Sets the slips of stale-direction systems to zero, so that their direction is that of their
  // shear, and makes that iterate the current one when it is an admissible start. False when
  // there is none or no admissible start from it.
  bool release_stale_directions(Iterate<N>& it, Iterate<N>& scratch, double tolerance) const {
    SystemFlags released;
    VecN x = with_slips_zeroed(
        it, [&](int a) { return stale_direction(it, a); }, released);
    VecN sign = it.sign;
    if (!any_of(released) || !admissible_start(x, sign, scratch, tolerance)) return false;
    std::swap(it, scratch);
    return true;
  }

  // A converged system on the x = 0 branch (inactive row) has a slip within tolerance/c of zero,
  // not zero. Left in, such a slip against the start shear selects the reversal start (r_s from
  // 0) for a system whose shear never changed sign: r_s jumps from r to 0, and the next step must
  // relax that whole overstress however short it is (HCP <c+a> at G/tau0 = 1e5: adaptive steps
  // refused down to dt = 2e-14 s). Those slips are set to zero where the iterate stays converged
  // (every row within `allowed`) with them at zero and their directions re-derived from their
  // shear, and those systems stay idle. (Where not, a system's shear has turned against its stale
  // direction and it would slip the other way: release_stale_directions handles those during the
  // iteration; one left when its releases ran out is kept as it is.)
  void drop_leftover_slip(Iterate<N>& it, Iterate<N>& scratch, const VecN& allowed) const {
    SystemFlags dropped;
    const VecN x = with_slips_zeroed(
        it, [&](int a) { return !it.active(a); }, dropped);
    if (!any_of(dropped)) return;
    evaluate(x, it.sign, scratch);
    if (!scratch.admissible || (scratch.merit_rows.cwiseAbs() - allowed).maxCoeff() > 0.0) return;
    for (int a = 0; a < n_; ++a)
      if (dropped[static_cast<size_t>(a)] && scratch.active(a)) return;  // idle no longer
    std::swap(it, scratch);
  }

 private:
  const Phase<N>& ph_;
  const GrainState<N>& s0_;
  double dt_;
  int n_;
  VecN tau_trial_, fn_trial_, tau_start_, scale_;
  std::array<std::array<SystemStart, 2>, T::MaxN> starts_;  // along, against the start shear
};

// j^-1 rhs. Coplanar systems of an open plane have dependent rows (FCC: P_1 + P_2 + P_3 = 0):
// then the minimum-norm solution. That case is rare, so it goes through one dynamic-size
// decomposition (allocating) instead of one per slip count: compile time and code size.
template <int N, class Rhs>
typename Rhs::PlainObject solve_newton_system(const typename SlipTypes<N>::MatNN& j, const Rhs& rhs,
                                              bool dependent_rows) {
  if (dependent_rows) {
    const Eigen::MatrixXd jd = j;
    const Eigen::MatrixXd rd = rhs;
    return typename Rhs::PlainObject(
        Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(jd).solve(rd));
  }
  return Eigen::PartialPivLU<typename SlipTypes<N>::MatNN>(j).solve(rhs);
}

// The Newton step of the grain iteration. A system whose step would take its slip below zero
// cannot follow it (x >= 0), which leaves the other systems with a step computed for a slip the
// pinned one never takes: with a stiff, rank-deficient A (G/tau0 ~ 1e5, FCC: rank 5 of 12) that
// direction is no descent direction and the line search stalls. So such systems are pinned
// (row step_a = -x_a) and the others re-solved: with Pin::at_zero only systems already at zero
// slip, with Pin::below_zero also slipping ones the step would take below zero (they then land on
// zero). Systems the solver holds (scalar starts) keep their x.
enum class Pin { at_zero, below_zero };

template <int N>
struct NewtonStep {
  typename SlipTypes<N>::VecN step;
  Eigen::Matrix<bool, N, 1, 0, SlipTypes<N>::MaxN, 1> pinned;  // step_a = -x_a exactly
  bool pins_slipping_system = false;                           // some pinned x_a > 0
};

// `full` is the plain Newton step -j^-1 rows (computed once per iteration, for both pin modes).
template <int N, class Held>
NewtonStep<N> newton_step(const typename SlipTypes<N>::MatNN& j, const Iterate<N>& it,
                          const typename SlipTypes<N>::VecN& full, Pin pin, Held&& held_by_solver) {
  using VecN = typename SlipTypes<N>::VecN;
  NewtonStep<N> out{full, {}};
  out.pinned.setConstant(it.x.size(), false);
  if (!out.step.allFinite()) return out;
  typename SlipTypes<N>::MatNN held = j;
  VecN rows = it.merit_rows;
  bool any = false;
  for (int a = 0; a < out.step.size(); ++a) {
    const bool held_here = held_by_solver(a);
    const bool below_zero = it.x(a) + out.step(a) < 0.0;
    out.pinned(a) = !held_here && below_zero && (it.x(a) == 0.0 || pin == Pin::below_zero);
    if (!out.pinned(a) && !held_here) continue;
    out.pins_slipping_system = out.pins_slipping_system || (out.pinned(a) && it.x(a) > 0.0);
    held.row(a).setZero();
    held(a, a) = 1.0;
    rows(a) = out.pinned(a) ? it.x(a) : 0.0;
    any = true;
  }
  if (!any) return out;
  const VecN reduced = -solve_newton_system<N>(held, rows, it.open.any());
  if (reduced.allFinite()) {
    out.step = reduced;
  } else {
    out.pinned.setConstant(false);
    out.pins_slipping_system = false;
  }
  return out;
}

}  // namespace

template <int N>
GrainStepReport semismooth_grain_step(const Phase<N>& ph, const GrainState<N>& s0, const Mat3& L,
                                      double dt, const GrainStepOptions& opt, GrainState<N>& s1,
                                      Tangent* tangent,
                                      const typename SlipTypes<N>::VecN* start_rate,
                                      SlipTangent<N>* slip_tangent) {
  using T = SlipTypes<N>;
  using VecN = typename T::VecN;
  const int n = ph.slip_count;
  GrainStepReport rep;
  const StepKinematics kin = step_kinematics(s0.orientation, L, dt, ph.kinematics);
  const Vec6 stress_trial = s0.stress + ph.stiffness * kin.strain_increment;
  ImplicitSolver<N> solver(ph, s0, stress_trial, dt);

  // Warm start: the previous slip rate where its sign agrees with the trial shear.
  const VecN& start = start_rate != nullptr ? *start_rate : s0.rate;
  VecN sign(n), x(n);
  for (int a = 0; a < n; ++a) {
    sign(a) = sign_of(solver.tau_trial()(a));
    const double previous = start(a) * dt;
    x(a) = (previous * sign(a) > 0.0) ? solver.unknown_of(a, sign(a), std::abs(previous)) : 0.0;
  }
  Iterate<N> it, trial;
  if (!solver.admissible_start(x, sign, it, opt.tolerance)) {
    rep.why = "no admissible start (r >= r_hat or slip plane open)", rep.system = it.bad_system;
    return rep;
  }

  bool converged = false;
  int releases = 0;  // of stale slip directions (see kReleaseAfterIterations)
  for (rep.iterations = 0; rep.iterations < opt.max_iterations && !converged; ++rep.iterations) {
    const typename T::MatNN j = solver.jacobian(it);
    // Converged when every row is within tolerance or within what double precision resolves
    // at this x (a few ulp of x_a times the row's slope): very stiff rows stop there.
    // (An infinite slope, e.g. an overflowed power-form derivative, resolves nothing.)
    const VecN resolution =
        (4.0 * std::numeric_limits<double>::epsilon() * j.diagonal().cwiseAbs().cwiseProduct(it.x))
            .unaryExpr([](double v) { return std::isfinite(v) ? v : 0.0; });
    const VecN allowed = resolution.cwiseMax(opt.tolerance);
    if (solver.should_release(it, allowed, rep.iterations, releases) &&
        solver.release_stale_directions(it, trial, opt.tolerance)) {
      ++releases;
      continue;
    }
    if ((it.merit_rows.cwiseAbs() - allowed).maxCoeff() <= 0.0) {
      solver.drop_leftover_slip(it, trial, allowed);
      converged = true;
      break;
    }
    // Backtracking line search on the merit 1/2 |rows|^2, projected onto x >= 0; a trial point
    // beyond r_hat counts as infinitely bad, so the iterate never leaves the admissible set.
    auto line_search = [&](const NewtonStep<N>& newton) {
      double alpha = 1.0;
      for (int ls = 0; ls < 40; ++ls, alpha *= 0.5) {
        // x >= 0; a slipping system (flow-rule row) may shrink by at most 99 % per iteration
        // (fraction to the boundary) unless the step pins it: a system that should stop is
        // switched to the x_a = 0 row by the semismooth branch and then lands on zero exactly.
        VecN xt = it.x + alpha * newton.step;
        for (int a = 0; a < n; ++a)
          xt(a) = std::max(xt(a), it.active(a) && !newton.pinned(a) ? 0.01 * it.x(a) : 0.0);
        solver.evaluate(xt, it.sign, trial);
        // Systems the Newton step holds (see needs_scalar_start) follow the others through
        // their own scalar roots, so that the merit measures the step of the systems it moved.
        if (!solver.newton_can_start(trial)) {
          VecN st = trial.sign;
          solver.make_admissible(xt, st, trial, opt.tolerance);
        }
        if (trial.merit <= (1.0 - 1e-4 * alpha) * it.merit) return true;
      }
      return false;
    };
    // Systems the step drives below zero first shrink gradually (the others' slips adjust);
    // where that stalls (nearly degenerate active sets, e.g. HCP <c+a> at G/tau0 = 1e5), they
    // are pinned at zero instead.
    auto held = [&](int a) { return solver.needs_scalar_start(it, a); };
    const VecN full = -solve_newton_system<N>(j, it.merit_rows, it.open.any());
    bool accepted = false;
    for (const Pin pin : {Pin::at_zero, Pin::below_zero}) {
      const NewtonStep<N> newton = newton_step(j, it, full, pin, held);
      if (pin == Pin::below_zero && !newton.pins_slipping_system) break;
      if (!newton.step.allFinite()) continue;
      if ((accepted = line_search(newton))) break;
    }
    if (!accepted) break;
    std::swap(it, trial);
  }
  if (!converged) {
    rep.why = "slip increments did not converge";
    it.merit_rows.cwiseAbs().maxCoeff(&rep.system);  // the system with the largest residual
    return rep;
  }

  const VecN dgamma = it.sign.cwiseProduct(it.slip);
  s1.stress = stress_trial - ph.c_schmid * dgamma;
  s1.mu = it.mu;
  s1.slip = s0.slip + dgamma;
  s1.rate = dgamma / dt;
  // r from the stress as stored (not from it.tau): with a large elastic trial the two differ by
  // rounding of order eps |sigma_trial| / CRSS, and r_s <= r must hold for what is output.
  const VecN fn1 = normal_traction(ph, s1.stress);
  const VecN r_abs = loading_ratio_of(ph, s1.stress, it.mu, fn1);
  s1.r_s = it.rs.cwiseMin(r_abs);  // (3.12): r_s follows r down where no slip occurs
  s1.orientation = orientation_after_plastic_spin(ph, kin.spun_orientation, dgamma);
  const double flow_tolerance =
      std::max(opt.tolerance, 16.0 * std::numeric_limits<double>::epsilon());
  if (!admissible_state(ph, s1, r_abs, fn1, rep, OpenPlanes::resolved, flow_tolerance)) return rep;

  if (tangent) {
    const typename T::MatNN j = solver.jacobian(it);
    const typename T::MatN6 dx =
        -solve_newton_system<N>(j, solver.strain_jacobian(it), it.open.any());
    const typename T::MatN6 dgamma_de = it.sign.cwiseProduct(it.dslip_dx).asDiagonal() * dx;
    tangents_from_slip_sensitivity(ph, s1, dgamma_de,
                                   lattice_directions(opt.tangent_directions, kin.mid_orientation),
                                   tangent, slip_tangent);
  }
  rep.ok = true;
  return rep;
}

#define SUBSLIP_INSTANTIATE_SEMISMOOTH(N)                                                  \
  template GrainStepReport semismooth_grain_step<N>(                                       \
      const Phase<N>&, const GrainState<N>&, const Mat3&, double, const GrainStepOptions&, \
      GrainState<N>&, Tangent*, const typename SlipTypes<N>::VecN*, SlipTangent<N>*);
SUBSLIP_INSTANTIATE_SEMISMOOTH(1)
SUBSLIP_INSTANTIATE_SEMISMOOTH(3)
SUBSLIP_INSTANTIATE_SEMISMOOTH(6)
SUBSLIP_INSTANTIATE_SEMISMOOTH(12)
SUBSLIP_INSTANTIATE_SEMISMOOTH(24)
SUBSLIP_INSTANTIATE_SEMISMOOTH(48)
SUBSLIP_INSTANTIATE_SEMISMOOTH(Eigen::Dynamic)

}  // namespace subslip::crystal::detail
