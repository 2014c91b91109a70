// The semismooth Newton grain step (see semismooth_grain_step.hpp).
#include "semismooth_grain_step.hpp"

#include <Eigen/LU>
#include <Eigen/QR>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>

#include "kernel_detail.hpp"
#include "subslip/integrators/scalar_root.hpp"

namespace subslip::crystal::detail {

namespace {

// What the Newton iteration needs at one iterate of the signed slips.
template <int N>
struct Iterate {
  using T = SlipTypes<N>;
  // x are the unknowns z_a = sign(g_a) |g_a|^(1/p_a), g_a the signed slip increment (p_a = 1
  // unless the power overstress is used); slip = |g|, dgamma = g, dslip_dx = d|g|/d|z|.
  typename T::VecN x, slip, dgamma, dslip_dx, direction, effective, tau, fn, mu, d_mu, rs, d_rs, r,
      rows;
  typename T::VecN g_value, g_dr, g_drs, g_dslip;
  // The same system at zero slip of its own, every other slip as it is: its loading ratio in
  // the positive direction r0 (with mu0 and fn0 there), and the value B of its residual at zero.
  typename T::VecN r0, mu0, d_mu0, fn0, at_zero;
  Eigen::Matrix<bool, N, 1, 0, T::MaxN, 1> open;  // slip plane open (f_n <= 0): tau_a = 0
  double merit = 0.0;
  bool admissible = true;
  int bad_system = -1;
};

// Below this subloading ratio at the start of a step, a system that starts to slip gets its own
// scalar root first (see ImplicitSolver::needs_scalar_start).
constexpr double kSteepStartRatio = 1e-3;

// Armijo's constant of the line search on the merit 1/2 |rows|^2.
constexpr double kArmijo = 1e-4;

// The residual of each system is a function of its signed slip g_a that is continuous through
// g_a = 0 and, under (A1), increasing in g_a on both sides (docs/grain_step.md, "The semismooth
// step on signed slips"): with H+(g) = -G(g; +) for g >= 0 and H-(g) = G(-g; -) for g <= 0 (each
// direction on its own subloading branch, along or against the start shear, (3.12)) and
// B = mid(H-(0), 0, H+(0)) the value at zero,
//   Phi_a = B + H+(g) - H+(0)  (g >= 0),   Phi_a = B + H-(g) - H-(0)  (g <= 0).
// Its roots are the law's: slip in a direction only where that direction is loaded past its r_s
// at zero slip, and the flow rule there; no slip where neither is. A system whose shear turns
// passes through zero on a continuous residual, so no direction goes stale.
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
    for (int a = 0; a < n_; ++a) {
      const auto& law = ph.laws[static_cast<size_t>(a)];
      auto& along = starts_[static_cast<size_t>(a)][0];
      auto& against = starts_[static_cast<size_t>(a)][1];
      along.subloading = law.subloading_start(s0.r_s(a));
      // (3.12): a system that slips against its shear at the start of the step has seen that
      // shear pass through zero, and r_s with it: it starts from r_s = 0. Its slip is spread
      // over the whole step, like any other: when the crossing happens is not known (the other
      // systems' slip moves the shear too), and placing it where the elastic predictor crosses
      // zero makes the step's response jump as that predictor passes zero (the slip time drops
      // from dt to 0), which stalled the mixed control of stiff HCP <c+a> aggregates.
      against.subloading = law.subloading_start(0.0);
      for (SystemStart* st : {&along, &against}) {
        st->exponent = law.slip_exponent();
        st->r_s_at_zero = law.subloading_ratio_after(st->subloading, 0.0).value;
      }
      // From a small r_s, dr_s/dslip = U(r_s) is infinite (r_s = 0) or huge at zero slip.
      along.steep_start = s0.r_s(a) < kSteepStartRatio;
      against.steep_start = true;
      mu_without_slip_[static_cast<size_t>(a)] = law.friction_coefficient_after(s0.mu(a), 0.0, dt);
    }
  }

  // How system a starts the step when it slips in direction `direction` (+1 or -1).
  struct SystemStart {
    law::SubloadingFrictionLaw::SubloadingStart subloading;
    double r_s_at_zero = 0.0;  // r_s at zero slip
    double exponent = 1.0;     // p of the unknown z = slip^(1/p)
    bool steep_start = false;  // r_s starts (nearly) at 0, where U(r_s) is (nearly) infinite
  };
  const SystemStart& start(int a, double direction) const {
    return starts_[static_cast<size_t>(a)][direction * tau_start_(a) < 0.0 ? 1 : 0];
  }

  // Slip magnitude of an unknown z and back (the exponent is the law's, in either direction).
  double slip_of(int a, double z) const {
    const double p = start(a, 1.0).exponent, m = std::abs(z);
    return p == 1.0 ? m : std::pow(m, p);
  }
  double unknown_of(int a, double direction, double slip) const {
    const double p = start(a, 1.0).exponent;
    return direction * (p == 1.0 ? slip : std::pow(slip, 1.0 / p));
  }
  // The unknown of a signed slip increment g.
  double unknown_of_slip(int a, double g) const {
    return g == 0.0 ? 0.0 : unknown_of(a, sign_of(g), std::abs(g));
  }
  // The size of each unknown in the units the Jacobian's columns are in (z; g on an open plane).
  VecN unknown_sizes(const Iterate<N>& it) const {
    VecN out = it.x.cwiseAbs();
    for (int a = 0; a < n_; ++a)
      if (it.open(a)) out(a) = std::abs(it.dgamma(a));
    return out;
  }

  void evaluate(const VecN& x, Iterate<N>& it) const {
    it.x = x;
    for (VecN* v : {&it.slip, &it.dgamma, &it.dslip_dx, &it.direction, &it.mu, &it.d_mu, &it.rs,
                    &it.d_rs, &it.r, &it.g_value, &it.g_dr, &it.g_drs, &it.g_dslip, &it.rows,
                    &it.r0, &it.mu0, &it.d_mu0, &it.fn0, &it.at_zero})
      v->resize(n_);  // every entry is set below, an inadmissible system's too
    for (int a = 0; a < n_; ++a) {
      it.slip(a) = slip_of(a, x(a));
      const double p = start(a, 1.0).exponent;
      it.dslip_dx(a) = p == 1.0 ? 1.0 : p * std::pow(std::abs(x(a)), p - 1.0);
    }
    for (int a = 0; a < n_; ++a) it.dgamma(a) = x(a) < 0.0 ? -it.slip(a) : it.slip(a);
    const VecN& dgamma = it.dgamma;
    it.tau = tau_trial_ - ph_.interaction * dgamma;
    it.fn = ph_.pressure_sensitive ? VecN(fn_trial_ + ph_.normal_interaction * dgamma) : ph_.tau0;
    it.effective = ph_.has_latent ? VecN(ph_.latent * it.slip) : it.slip;
    it.open.setConstant(n_, false);
    it.admissible = true;
    it.bad_system = -1;
    // Every system is evaluated, also after an inadmissible one: the sweeps that move an
    // inadmissible iterate back (make_admissible) read every system's values.
    for (int a = 0; a < n_; ++a) {
      if (evaluate_system(a, x, it) || !it.admissible) continue;
      it.admissible = false, it.bad_system = a;
    }
    it.merit =
        it.admissible ? 0.5 * it.rows.squaredNorm() : std::numeric_limits<double>::infinity();
  }

  // System a at the iterate x (whose slips, shears, normal tractions and effective slips are
  // set); false where it is inadmissible there (mu <= 0, no normal traction at its own zero
  // slip, r >= r_hat): then its residual is infinite and its other values those at zero slip.
  bool evaluate_system(int a, const VecN& x, Iterate<N>& it) const {
    const auto& law = ph_.laws[static_cast<size_t>(a)];
    const auto mu = law.friction_coefficient_after(s0_.mu(a), it.effective(a), dt_);
    it.mu(a) = it.mu0(a) = mu.value, it.d_mu(a) = it.d_mu0(a) = mu.d_slip;
    it.fn0(a) = it.fn(a);
    it.r(a) = it.r0(a) = it.at_zero(a) = 0.0;
    it.g_dr(a) = it.g_drs(a) = it.g_dslip(a) = 0.0;
    it.g_value(a) = it.rows(a) = std::numeric_limits<double>::infinity();
    it.direction(a) = x(a) != 0.0 ? sign_of(x(a)) : sign_of(it.tau(a));
    const auto rs_here =
        law.subloading_ratio_after(start(a, it.direction(a)).subloading, it.slip(a));
    it.rs(a) = rs_here.value, it.d_rs(a) = rs_here.d_slip;
    if (!(mu.value > 0.0) || std::isnan(it.fn(a))) return false;
    if (!(it.fn(a) > 0.0)) {
      // An open slip plane carries no shear, like an open contact: the system slips freely
      // until tau_a = 0. Its row is that shear in ratio units (r = 0, no flow rule),
      // increasing in its own slip.
      it.open(a) = true;
      // Its unknown is its slip itself (d slip / d unknown = 1 in the Jacobian; the step's
      // update carries it back to z): with z = g^(1/p) its column would vanish at z = 0, where
      // nothing couples it to the others' rows, and Newton's step would never move it.
      it.dslip_dx(a) = 1.0;
      it.rows(a) = -it.tau(a) / (mu.value * ph_.tau0(a));
      it.g_value(a) = 0.0;
      return true;
    }
    if (!at_own_zero_slip(a, it.dgamma(a), it)) return false;
    const double b = it.at_zero(a);
    // The side the residual is on: that of the slip, or at zero the side it leaves to.
    it.direction(a) = x(a) > 0.0   ? 1.0
                      : x(a) < 0.0 ? -1.0
                      : b != 0.0   ? -sign_of(b)
                                   : sign_of(it.tau(a));
    const double d = it.direction(a);
    const SystemStart& st = start(a, d);
    const auto rs = law.subloading_ratio_after(st.subloading, it.slip(a));
    it.rs(a) = rs.value, it.d_rs(a) = rs.d_slip;
    it.r(a) = d * it.tau(a) / (mu.value * it.fn(a));
    const auto g = law.flow_residual(it.r(a), rs.value, it.slip(a), dt_);
    it.g_value(a) = g.value, it.g_dr(a) = g.d_r, it.g_drs(a) = g.d_rs, it.g_dslip(a) = g.d_slip;
    if (!g.admissible) return false;
    // Phi_a = B - d (G(|g|; d) - G(0; d)), G(0; d) = d r0 - r_s(0; d) (no rate term at zero
    // slip); exactly B at zero slip.
    const double g_at_zero = d * it.r0(a) - st.r_s_at_zero;
    it.rows(a) = x(a) == 0.0 ? b : b - d * (g.value - g_at_zero);
    return true;
  }

  // System a's effective slip with its own slip taken out (the others' as they are).
  double others_effective(int a, const Iterate<N>& it) const {
    const double own = (ph_.has_latent ? ph_.latent(a, a) : 1.0) * it.slip(a);
    return std::max(it.effective(a) - own, 0.0);
  }

  // System a with its own slip taken out (the others' as they are): mu0, fn0, r0 and the
  // residual's value there, B = mid(H-(0), 0, H+(0)) = -(r0 - r_s+(0)) where r0 exceeds the
  // positive direction's r_s, -r0 - r_s-(0) where -r0 exceeds the negative one's, 0 in between.
  bool at_own_zero_slip(int a, double own_dgamma, Iterate<N>& it) const {
    it.mu0(a) = it.mu(a), it.d_mu0(a) = it.d_mu(a), it.fn0(a) = it.fn(a);
    double tau0 = it.tau(a);
    if (own_dgamma != 0.0) {
      // Without latent hardening a system's effective slip is its own, and taking it out leaves
      // none: mu0 is the step's mu at zero slip, the same at every iterate.
      const auto mu0 = ph_.has_latent ? ph_.laws[static_cast<size_t>(a)].friction_coefficient_after(
                                            s0_.mu(a), others_effective(a, it), dt_)
                                      : mu_without_slip_[static_cast<size_t>(a)];
      it.mu0(a) = mu0.value, it.d_mu0(a) = mu0.d_slip;
      tau0 += ph_.interaction(a, a) * own_dgamma;
      if (ph_.pressure_sensitive) it.fn0(a) -= ph_.normal_interaction(a, a) * own_dgamma;
    }
    if (!(it.mu0(a) > 0.0) || !(it.fn0(a) > 0.0)) return false;
    it.r0(a) = tau0 / (it.mu0(a) * it.fn0(a));
    const double rs_positive = start(a, 1.0).r_s_at_zero, rs_negative = start(a, -1.0).r_s_at_zero;
    it.at_zero(a) = std::max(-it.r0(a) - rs_negative, std::min(0.0, rs_positive - it.r0(a)));
    return true;
  }

  // d(rows)/dx at an iterate (semismooth Newton: each row differentiated on its side). Where B
  // is a flow rule's value at zero (the system loaded past r_s in some direction) it cancels
  // against G(0; d), and the row is -d G(|g|; d):
  //   dr_a/dg_b = -d_a A_ab/(mu_a fn_a) - (r_a/mu_a) dmu_a q_ab d_b - (r_a/fn_a) N_ab,
  //   J_ab = -d_a (dG_a/dr_a dr_a/dg_b + delta_ab d_a (dG_a/dr_s dr_s/dslip + dG_a/dslip)),
  // i.e. the derivative of the magnitude rows -G conjugated by the directions. Where B = 0 the
  // row keeps + dr0_a/dg_b (b != a), r0_a not depending on a's own slip.
  MatNN jacobian(const Iterate<N>& it) const {
    const VecN& d = it.direction;
    const VecN g_dr_over_mu = it.g_dr.cwiseQuotient(it.mu);
    const VecN elastic_row = g_dr_over_mu.cwiseQuotient(it.fn);
    MatNN j = elastic_row.asDiagonal() * ph_.interaction;
    const VecN hardening_row =
        g_dr_over_mu.cwiseProduct(it.r).cwiseProduct(it.d_mu).cwiseProduct(d);
    if (ph_.has_latent) {
      j.noalias() += hardening_row.asDiagonal() * ph_.latent * d.asDiagonal();
    } else {
      j.diagonal() += hardening_row.cwiseProduct(d);
    }
    if (ph_.pressure_sensitive) {
      const VecN pressure_row = it.g_dr.cwiseProduct(it.r).cwiseQuotient(it.fn).cwiseProduct(d);
      j.noalias() += pressure_row.asDiagonal() * ph_.normal_interaction;
    }
    j.diagonal() -= it.g_drs.cwiseProduct(it.d_rs) + it.g_dslip;
    for (int a = 0; a < n_; ++a) {
      if (it.open(a)) {
        // d(-tau_a/(mu_a tau0_a))/dg_b = A_ab/(mu_a tau0_a) (mu frozen: its term vanishes with
        // tau_a at the solution).
        j.row(a) = ph_.interaction.row(a) / (it.mu(a) * ph_.tau0(a));
        continue;
      }
      if (it.at_zero(a) != 0.0 || idle(it, a)) continue;  // (an idle row is dropped below)
      // B = 0: + dr0_a/dg_b for b != a.
      const double r0 = it.r0(a), mu0 = it.mu0(a), fn0 = it.fn0(a);
      for (int b = 0; b < n_; ++b) {
        if (b == a) continue;
        double dr0 = -ph_.interaction(a, b) / (mu0 * fn0);
        if (ph_.has_latent) dr0 -= r0 / mu0 * it.d_mu0(a) * ph_.latent(a, b) * d(b);
        if (ph_.pressure_sensitive) dr0 -= r0 / fn0 * ph_.normal_interaction(a, b);
        j(a, b) += dr0;
      }
    }
    j = j * it.dslip_dx.asDiagonal();  // d/dg -> d/dx
    for (int a = 0; a < n_; ++a) {
      if (!idle(it, a)) continue;
      // An idle system's row is Phi_a = H(g_a) - H(0) with B = 0: zero at g_a = 0 whatever the
      // other slips, so its entries off the diagonal vanish (the two terms above are equal
      // there and cancel only to rounding), and its Newton step, -rows_a / J_aa, is exactly
      // zero. Its column then multiplies zero; dropping it too keeps the step of every other
      // system that of the system without a: no rounding-level step of an idle system that
      // pointed against its direction and had to be pinned and re-solved.
      const double own = j(a, a);
      j.row(a).setZero();
      j.col(a).setZero();
      j(a, a) = own;
    }
    for (int a = 0; a < n_; ++a) {
      // A system at zero slip whose side has no finite slope there in x (z = slip^(1/p) with
      // p > 1: dslip/dz = 0; r_s from 0: U(0) infinite) has no column to move it: its row is
      // the unit row, the step leaves it where it is (a scalar start moves it, see
      // needs_scalar_start), and at a solution it is idle.
      if (it.open(a) || it.x(a) != 0.0 || (std::isfinite(j(a, a)) && j(a, a) != 0.0)) continue;
      j.row(a).setZero();
      j(a, a) = 1.0;
    }
    return j;
  }

  // d(rows)/d(strain increment), for the consistent tangent.
  typename T::MatN6 strain_jacobian(const Iterate<N>& it) const {
    typename T::MatN6 j = T::MatN6::Zero(n_, 6);
    for (int a = 0; a < n_; ++a) {
      if (it.open(a)) {
        j.row(a) = -ph_.c_schmid.col(a).transpose() / (it.mu(a) * ph_.tau0(a));
        continue;
      }
      if (idle(it, a)) continue;  // its row is zero at g_a = 0 for any strain (see jacobian)
      const double d = it.direction(a);
      Eigen::Matrix<double, 1, 6> dr = d * ph_.c_schmid.col(a).transpose() / (it.mu(a) * it.fn(a));
      if (ph_.pressure_sensitive) dr += it.r(a) / it.fn(a) * ph_.c_normal_dyad.col(a).transpose();
      j.row(a) = -d * it.g_dr(a) * dr;
      if (it.at_zero(a) != 0.0) continue;
      // B = 0: the row also carries G(0; d), d r0 with r0 at zero own slip.
      Eigen::Matrix<double, 1, 6> dr0 = ph_.c_schmid.col(a).transpose() / (it.mu0(a) * it.fn0(a));
      if (ph_.pressure_sensitive)
        dr0 += it.r0(a) / it.fn0(a) * ph_.c_normal_dyad.col(a).transpose();
      j.row(a) += dr0;
    }
    return j;
  }

  const VecN& tau_trial() const { return tau_trial_; }

  // No slip, and the residual at zero slip between the two directions' r_s (B = 0): the
  // system neither slips nor is loaded to.
  static bool idle(const Iterate<N>& it, int a) {
    return !it.open(a) && it.x(a) == 0.0 && it.at_zero(a) == 0.0;
  }

  // Newton cannot move a system off zero slip where its slope there is infinite or huge
  // (dr_s/dslip = U(r_s) from r_s = 0 or nearly 0, as after a reversal; dG/dslip with the power
  // overstress, G ~ -slip^(1/n)), or where its Jacobian column vanishes (in z = slip^(1/p),
  // p > 1, dslip/dz = 0). Such a system, where its residual at zero says it slips, gets its own
  // scalar root instead (the coupled Newton holds it meanwhile); from there its slopes are
  // moderate.
  bool needs_scalar_start(const Iterate<N>& it, int a) const {
    if (it.open(a)) return false;
    if (it.x(a) == 0.0) {
      if (it.at_zero(a) == 0.0) return false;
      const SystemStart& st = start(a, it.direction(a));
      if (st.exponent != 1.0 || st.steep_start) return true;
    }
    return !std::isfinite(it.d_rs(a)) || !std::isfinite(it.g_dslip(a));
  }

  bool newton_can_start(const Iterate<N>& it) const {
    for (int a = 0; a < n_; ++a)
      if (needs_scalar_start(it, a)) return false;
    return true;
  }

  // The flow rule of system a alone in its direction, the other systems' slips frozen at `it`:
  // one bracketed scalar equation exactly like a single contact's. Returns the unknown x_a (0 if
  // no slip).
  double solve_single(int a, const Iterate<N>& it, double tolerance) const {
    const auto& law = ph_.laws[static_cast<size_t>(a)];
    const double stiffness = ph_.interaction(a, a);
    const double d = it.direction(a);
    const double fn = it.fn0(a);
    // Shear on a (signed along d) and effective slip with a's own slip taken out.
    const double tau_free = d * (it.tau(a) + stiffness * it.dgamma(a));
    const double effective_other = others_effective(a, it);
    if (!(tau_free > 0.0)) return 0.0;
    const SystemStart& st = start(a, d);
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
    const double z_max = std::abs(unknown_of(a, 1.0, tau_free / stiffness));
    const auto root = safeguarded_newton(residual, 0.0, z_max, 0.5 * z_max, tolerance,
                                         4.0 * std::numeric_limits<double>::epsilon(), 1e-300);
    return d * root.x;
  }

  // A start the coupled Newton can work from: finite slopes (no system at zero slip that must
  // leave it with r_s = 0, where dr_s/dslip = U(0) is infinite) and admissible (every
  // r_a < r_hat). Offending systems get their own scalar solution (a Jacobi sweep); a few sweeps
  // suffice since slip on one system only relaxes the others (A is positive semi-definite).
  bool make_admissible(VecN& x, Iterate<N>& it, double tolerance, int rounds = 8) const {
    evaluate(x, it);
    for (int round = 0; round < rounds; ++round) {
      bool changed = false;
      for (int a = 0; a < n_; ++a) {
        if (it.open(a) || (!needs_scalar_start(it, a) && std::isfinite(it.g_value(a)))) continue;
        const double z = solve_single(a, it, tolerance);
        changed = changed || z != x(a);
        x(a) = z;
      }
      if (!changed) break;
      evaluate(x, it);
    }
    return it.admissible;
  }

  // Moves an inadmissible start (some r_a >= r_hat, typically a large elastic trial) into the
  // admissible set: each offending system gets the slip that, through its own diagonal
  // stiffness, brings r_a to the middle of [r_s,a, r_hat]. Slip on a system relaxes the others
  // too (A is positive semi-definite), so a few rounds suffice; the Newton iteration then starts
  // from an admissible point and converges to the same root whatever the start.
  bool make_admissible(VecN& x, Iterate<N>& it, int rounds = 30) const {
    for (int round = 0; round < rounds; ++round) {
      evaluate(x, it);
      if (it.admissible) return true;
      const int bad = it.bad_system;
      if (bad >= 0 && (!(it.fn(bad) > 0.0) || !(it.fn0(bad) > 0.0) || !(it.mu(bad) > 0.0)))
        return false;
      // Every system's values are set, an inadmissible one's too (evaluate_system).
      for (int a = 0; a < n_; ++a) {
        const auto& o = ph_.laws[static_cast<size_t>(a)].parameters().overstress;
        if (o.form == law::OverstressForm::rate_independent) continue;
        const double d = it.direction(a), mu = it.mu(a), fn = it.fn(a);
        if (!(mu > 0.0) || !(fn > 0.0) || d * it.tau(a) / (mu * fn) < o.r_hat) continue;
        const double target = 0.5 * (it.rs(a) + o.r_hat);
        const double more = (d * it.tau(a) - target * mu * fn) / ph_.interaction(a, a);
        x(a) = unknown_of(a, d, it.slip(a) + more);
      }
    }
    evaluate(x, it);
    return it.admissible;
  }

  // An admissible start from x: the Jacobi sweep freezes the other systems' slip and normal
  // traction; when that does not reach the admissible set (pressure-sensitive planes, or a large
  // trial with too little slip), every offending system is moved below r_hat first and swept
  // again.
  bool admissible_start(VecN& x, Iterate<N>& it, double tolerance) const {
    return make_admissible(x, it, tolerance) ||
           (make_admissible(x, it) && make_admissible(x, it, tolerance));
  }

  // Whether every slipping system of a root of the rows is on its flow rule or within tolerance
  // of zero slip (its own slope times its slip within `allowed`: a leftover that
  // drop_leftover_slip could not remove without unsettling the others). Under (A1) it is (each
  // Phi_a is strictly increasing in g_a, so Phi_a = 0 with B = 0 means g_a = 0); a law whose
  // friction coefficient softens with slip can make G(g) = G(0) at some g away from 0, a root of
  // the rows that is none of the law's.
  bool on_the_flow_rule(const Iterate<N>& it, const VecN& allowed) const {
    auto off = [&](int a) {
      return !it.open(a) && it.x(a) != 0.0 && std::abs(it.g_value(a)) > allowed(a);
    };
    bool any = false;
    for (int a = 0; a < n_ && !any; ++a) any = off(a);
    if (!any) return true;
    const MatNN j = jacobian(it);
    for (int a = 0; a < n_; ++a)
      if (off(a) && std::abs(j(a, a) * it.x(a)) > allowed(a)) return false;
    return true;
  }

  // A converged system whose residual at zero says it does not slip (B = 0) has a slip within
  // tolerance of zero, not zero. Left in, such a slip against the start shear selects the
  // reversal start (r_s from 0) for a system whose shear never changed sign: r_s jumps from r to
  // 0, and the next step must relax that whole overstress however short it is (HCP <c+a> at
  // G/tau0 = 1e5: adaptive steps refused down to dt = 2e-14 s). Those slips are set to zero where
  // the iterate stays converged (every row within `allowed`) with them at zero, and those
  // systems stay idle.
  void drop_leftover_slip(Iterate<N>& it, Iterate<N>& scratch, const VecN& allowed) const {
    VecN x = it.x;
    std::array<bool, T::MaxN> dropped{};
    bool any = false;
    for (int a = 0; a < n_; ++a) {
      if (x(a) == 0.0 || it.open(a) || it.at_zero(a) != 0.0) continue;
      x(a) = 0.0;
      dropped[static_cast<size_t>(a)] = any = true;
    }
    if (!any) return;
    evaluate(x, scratch);
    if (!scratch.admissible || (scratch.rows.cwiseAbs() - allowed).maxCoeff() > 0.0) return;
    for (int a = 0; a < n_; ++a)
      if (dropped[static_cast<size_t>(a)] && scratch.at_zero(a) != 0.0) return;  // idle no longer
    std::swap(it, scratch);
  }

 private:
  const Phase<N>& ph_;
  const GrainState<N>& s0_;
  double dt_;
  int n_;
  VecN tau_trial_, fn_trial_, tau_start_;
  std::array<std::array<SystemStart, 2>, T::MaxN> starts_;  // along, against the start shear
  // Each system's friction coefficient after the step with no effective slip.
  std::array<law::ValueAndSlope, T::MaxN> mu_without_slip_;
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

// The Newton step of the grain iteration. The line search follows it bent at zero (a slip it
// would carry to the other side of zero than its row's stops there), which leaves the other
// systems with a step computed for a slip the stopped one never takes: with a stiff,
// rank-deficient A (G/tau0 ~ 1e5, FCC: rank 5 of 12, or any yield vertex) the step has large
// components along A's null space, and the bent direction is no descent direction. So such
// systems are pinned (row step_a = -x_a, landing exactly on zero) and the others re-solved:
// with Pin::at_zero only systems already at zero, with Pin::crossing also slipping ones the step
// would carry through zero. Systems the solver holds (scalar starts) keep their x.
enum class Pin { at_zero, crossing };

template <int N>
struct NewtonStep {
  typename SlipTypes<N>::VecN step;
  bool pins_slipping_system = false;  // some pinned x_a != 0
};

// `full` is the plain Newton step -j^-1 rows (computed once per iteration, for both pin modes).
template <int N, class Held>
NewtonStep<N> newton_step(const typename SlipTypes<N>::MatNN& j, const Iterate<N>& it,
                          const typename SlipTypes<N>::VecN& full, Pin pin, Held&& held_by_solver) {
  using VecN = typename SlipTypes<N>::VecN;
  NewtonStep<N> out{full};
  if (!out.step.allFinite()) return out;
  typename SlipTypes<N>::MatNN held = j;
  VecN rows = it.rows;
  bool any = false;
  for (int a = 0; a < out.step.size(); ++a) {
    const bool held_here = held_by_solver(a);
    const bool crosses = !it.open(a) && it.direction(a) * (it.x(a) + out.step(a)) < 0.0;
    const bool pinned = !held_here && crosses && (it.x(a) == 0.0 || pin == Pin::crossing);
    if (!pinned && !held_here) continue;
    out.pins_slipping_system = out.pins_slipping_system || (pinned && it.x(a) != 0.0);
    held.row(a).setZero();
    held(a, a) = 1.0;
    rows(a) = pinned ? it.x(a) : 0.0;
    any = true;
  }
  if (!any) return out;
  const VecN reduced = -solve_newton_system<N>(held, rows, it.open.any());
  if (reduced.allFinite()) out.step = reduced;
  return out;
}

// Newton's iteration on the merit 1/2 |rows|^2 from x at the trial stress of `solver`: whether
// it ends on a root of the rows that is on the law's flow rules (then `it` holds it). Its
// iterations are added to the report, which names why where it does not converge.
template <int N>
bool solve_rows(const ImplicitSolver<N>& solver, typename SlipTypes<N>::VecN x,
                const GrainStepOptions& opt, Iterate<N>& it, Iterate<N>& trial,
                GrainStepReport& rep) {
  using VecN = typename SlipTypes<N>::VecN;
  using MatNN = typename SlipTypes<N>::MatNN;
  const int n = static_cast<int>(x.size());
  if (!solver.admissible_start(x, it, opt.tolerance)) {
    rep.why = "no admissible start (r >= r_hat or slip plane open)", rep.system = it.bad_system;
    return false;
  }
  int iterations = 0;
  // The line search gives up where Armijo's decrease kArmijo alpha merit falls below the
  // merit's own rounding: no trial closer to the iterate can show a decrease.
  const double smallest_alpha = 4.0 * std::numeric_limits<double>::epsilon() / kArmijo;
  bool converged = false;
  for (; iterations < opt.max_iterations; ++iterations) {
    const MatNN j = solver.jacobian(it);
    // Converged when every row is within tolerance or within what double precision resolves
    // at this x (a few ulp of x_a times the row's slope): very stiff rows stop there.
    // (An infinite slope, e.g. an overflowed power-form derivative, resolves nothing.)
    const VecN resolution = (4.0 * std::numeric_limits<double>::epsilon() *
                             j.diagonal().cwiseAbs().cwiseProduct(solver.unknown_sizes(it)))
                                .unaryExpr([](double v) { return std::isfinite(v) ? v : 0.0; });
    const VecN allowed = resolution.cwiseMax(opt.tolerance);
    if ((it.rows.cwiseAbs() - allowed).maxCoeff() <= 0.0) {
      solver.drop_leftover_slip(it, trial, allowed);
      converged = solver.on_the_flow_rule(it, allowed);
      break;
    }
    // Backtracking line search on the merit 1/2 |rows|^2 along the Newton step, bent at zero: a
    // slip the step would carry to the other side of zero than the one its row was linearised
    // on stops at zero, where its direction is re-derived (the residual is continuous through
    // zero, but on a side whose r_s starts from 0 its slope is infinite at zero, so the
    // linearisation says nothing beyond it). A trial point beyond r_hat counts as infinitely
    // bad, so the iterate never leaves the admissible set.
    auto line_search = [&](const VecN& step) {
      for (double alpha = 1.0; alpha >= smallest_alpha; alpha *= 0.5) {
        VecN xt = it.x + alpha * step;
        for (int a = 0; a < n; ++a) {
          if (it.open(a))
            xt(a) = solver.unknown_of_slip(a, it.dgamma(a) + alpha * step(a));  // (a slip step)
          else if (it.direction(a) * xt(a) < 0.0)
            xt(a) = 0.0;
        }
        solver.evaluate(xt, trial);
        // Systems the Newton step holds (see needs_scalar_start) follow the others through
        // their own scalar roots, so that the merit measures the step of the systems it moved.
        if (trial.admissible && !solver.newton_can_start(trial))
          solver.make_admissible(xt, trial, opt.tolerance);
        if (trial.merit <= (1.0 - kArmijo * alpha) * it.merit) return true;
      }
      return false;
    };
    auto held = [&](int a) { return solver.needs_scalar_start(it, a); };
    const VecN full = -solve_newton_system<N>(j, it.rows, it.open.any());
    bool accepted = false;
    for (const Pin pin : {Pin::at_zero, Pin::crossing}) {
      const NewtonStep<N> newton = newton_step(j, it, full, pin, held);
      if (pin == Pin::crossing && !newton.pins_slipping_system) break;
      if (!newton.step.allFinite()) continue;
      if ((accepted = line_search(newton.step))) break;
    }
    if (!accepted) break;
    std::swap(it, trial);
  }
  rep.iterations += iterations;
  if (!converged) {
    rep.why = "slip increments did not converge";
    it.rows.cwiseAbs().maxCoeff(&rep.system);  // the system with the largest residual
  }
  return converged;
}

// The warm start of a solve: the slip rates `rate` over dt where their signs agree with the
// solver's trial shears.
template <int N>
typename SlipTypes<N>::VecN warm_start(const ImplicitSolver<N>& solver,
                                       const typename SlipTypes<N>::VecN& rate, double dt) {
  typename SlipTypes<N>::VecN x(rate.size());
  for (int a = 0; a < rate.size(); ++a) {
    const double previous = rate(a) * dt;
    const double direction = sign_of(solver.tau_trial()(a));
    x(a) = previous * direction > 0.0 ? solver.unknown_of_slip(a, previous) : 0.0;
  }
  return x;
}

// Continuation in the step's strain increment (docs/grain_step.md, "Continuation in the strain
// increment"): the rows from the same start state with the strain increment and the step length
// scaled by theta, trial stress sigma_0 + theta C de over theta dt, for theta from 0 (no slip)
// to 1 (the step), each stage started from the secant through the last two roots. Where the
// roots form a path x(theta) with a regular Jacobian, a stage short enough starts inside the
// region where Newton's iteration converges to the next point of the path, so halving a stage
// that fails and doubling one after two that converge reaches theta = 1; the root found there
// is the step's, the same backward-Euler equations, not the end of shorter steps. The stride
// ends at sqrt(eps) of the increment (a stage that short changes the trial stress by less than
// the rows resolve: a path that does not go on there has a turning point) and after
// kMostStages stages (a bound on the work); the aggregate's cutback is what follows.
constexpr int kMostStages = 64;

template <int N>
bool continue_along_increment(const Phase<N>& ph, const GrainState<N>& s0, const Vec6& increment,
                              double dt, const ImplicitSolver<N>& full,
                              const typename SlipTypes<N>::VecN& rate, const GrainStepOptions& opt,
                              Iterate<N>& it, Iterate<N>& trial, GrainStepReport& rep) {
  using VecN = typename SlipTypes<N>::VecN;
  const double smallest_stride = std::sqrt(std::numeric_limits<double>::epsilon());
  double reached = 0.0, before = 0.0, stride = 0.5;
  bool failed_last = true;  // the full step just failed
  VecN x = rate, slips = VecN::Zero(rate.size()), slips_before = slips;
  std::optional<ImplicitSolver<N>> part;
  for (int stage = 0; stage < kMostStages && stride >= smallest_stride; ++stage) {
    const double target = std::min(1.0, reached + stride);
    const bool last = target == 1.0;
    if (!last) part.emplace(ph, s0, s0.stress + target * increment, target * dt);
    const ImplicitSolver<N>& solver = last ? full : *part;
    if (reached == 0.0) {
      x = warm_start(solver, rate, target * dt);
    } else {
      // The secant through the last two roots, in slips (the path is smooth in the slips; in
      // the unknowns z = g^(1/p) it is not, near zero).
      const double ahead = (target - reached) / (reached - before);
      for (int a = 0; a < x.size(); ++a)
        x(a) = solver.unknown_of_slip(a, slips(a) + ahead * (slips(a) - slips_before(a)));
    }
    if (!solve_rows(solver, x, opt, it, trial, rep)) {
      stride *= 0.5, failed_last = true;
      continue;
    }
    if (last) return true;
    slips_before = slips, slips = it.dgamma, before = reached, reached = target;
    if (!failed_last) stride *= 2.0;
    stride = std::min(stride, 1.0 - reached);
    failed_last = false;
  }
  return false;
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
  GrainStepReport rep;
  const StepKinematics kin = step_kinematics(s0.orientation, L, dt, ph.kinematics);
  const Vec6 stress_trial = s0.stress + ph.stiffness * kin.strain_increment;
  ImplicitSolver<N> solver(ph, s0, stress_trial, dt);

  // Warm start: the previous slip rate where its sign agrees with the trial shear.
  const VecN& start = start_rate != nullptr ? *start_rate : s0.rate;
  Iterate<N> it, trial;
  // Newton from the warm start; where that does not converge, the continuation in the strain
  // increment from the start state.
  rep.iterations = 0;
  if (!solve_rows(solver, warm_start(solver, start, dt), opt, it, trial, rep) &&
      !(opt.continuation && continue_along_increment(ph, s0, Vec6(stress_trial - s0.stress), dt,
                                                     solver, start, opt, it, trial, rep)))
    return rep;
  rep.why = "", rep.system = -1;

  const VecN& dgamma = it.dgamma;
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
  if (!admissible_state(ph, s1, r_abs, fn1, rep, OpenPlanes::resolved, admitted_flow_residual(opt)))
    return rep;

  if (tangent) {
    const typename T::MatNN j = solver.jacobian(it);
    const typename T::MatN6 dx =
        -solve_newton_system<N>(j, solver.strain_jacobian(it), it.open.any());
    const typename T::MatN6 dgamma_de = it.dslip_dx.asDiagonal() * dx;
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
SUBSLIP_FOR_EACH_SLIP_COUNT(SUBSLIP_INSTANTIATE_SEMISMOOTH)

}  // namespace subslip::crystal::detail
