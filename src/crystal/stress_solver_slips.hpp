// StressSolver's slip rows, their condensed Newton system and each system's flow points and
// scalar roots (declared in stress_solver.hpp). Internal to src/crystal/.
#pragma once

#include "stress_solver.hpp"

namespace subslip::crystal::implicit_detail {

template <int N>
inline double StressSolver<N>::activation_slip(int a, const SlipPoint& p) const {
  const double tau = tau_of(p.sigma, a);
  const bool against = tau * tau_start_(a) < 0.0;
  const SystemResponse resp = respond(a, std::abs(tau), latent_drives(p.dgamma)(a), against, 0.0);
  return resp.admissible ? resp.slip : 0.0;
}

template <int N>
inline typename StressSolver<N>::VecN StressSolver<N>::latent_drives(const VecN& dgamma) const {
  if (latent_rank_ == 0) return VecN::Zero(n_);
  const VecK mixed = ph_.latent_mix.leftCols(latent_rank_).transpose() * dgamma.cwiseAbs();
  VecN drive = VecN::Zero(n_);
  for (int j = 0; j < latent_rank_; ++j) drive += ph_.latent_factor.col(j) * mixed(j);
  return drive;
}

template <int N>
inline bool StressSolver<N>::within_floor(const FlowPoint& f, double z, int a,
                                          const VecN& dgamma) const {
  if (std::abs(f.g) <= tolerance_) return true;
  const double shear_size = std::abs(tau_trial_(a)) +
                            ph_.interaction.row(a).cwiseAbs().dot(dgamma.cwiseAbs().transpose());
  return std::abs(f.g) <= 4.0 * kEps *
                              (1.0 + f.r + std::abs(f.g_z) * z +
                               std::abs(f.g_dr) * shear_size / (f.mu * ph_.tau0(a)));
}

template <int N>
inline typename StressSolver<N>::RoleChange StressSolver<N>::evaluate_slips(const VecN& dgamma,
                                                                            SlipPoint& p) const {
  p.sigma = trial_;
  p.sigma.noalias() -= ph_.c_schmid * dgamma;
  const VecN tau = ph_.schmid.transpose() * p.sigma;
  const VecN latent_drive = latent_drives(dgamma);
  p.dgamma = dgamma;
  for (VecN* v : {&p.mu, &p.r_s, &p.w, &p.d, &p.l, &p.sign}) v->setZero(n_);
  p.worst = 0.0;
  p.converged = true;
  // The rounding of the largest slip, which the stress C P dgamma cannot resolve below.
  p.slip_resolution = 4.0 * kEps * dgamma.cwiseAbs().maxCoeff();
  if (batched_) {
    batch_flow_points(dgamma, tau, latent_drive);
    return slip_rows<true>(dgamma, tau, latent_drive, p);
  }
  return slip_rows<false>(dgamma, tau, latent_drive, p);
}

template <int N>
template <bool Batched>
inline typename StressSolver<N>::RoleChange StressSolver<N>::slip_rows(const VecN& dgamma,
                                                                       const VecN& tau,
                                                                       const VecN& latent_drive,
                                                                       SlipPoint& p) const {
  const VecN& fn = ph_.tau0;  // no plane pressure in this solver's domain
  RoleChange change;
  for (int a = 0; a < n_; ++a) {
    const auto i = static_cast<size_t>(a);
    if (dgamma(a) == 0.0) {
      const double mu = Batched ? batch_out_.mu[i] : idle_friction(a, latent_drive(a));
      const double r0 = starts_[i][slips_against(a, tau) ? 1 : 0].r0;
      p.mu(a) = mu, p.r_s(a) = r0;
      if (!(std::abs(tau(a)) / (mu * fn(a)) - r0 > tolerance_)) continue;  // idle
      // Loaded past r_s0: active at zero slip, linearised on the side of its shear.
    } else if (tau(a) * dgamma(a) <= 0.0) {
      if (change.kind == RoleChange::none) change = {RoleChange::turned_against, a};
      continue;
    }
    const double z = Batched ? batch_z_[i] : slip_root(a, dgamma(a));
    // From a batch, only what every row reads; the whole point where within_floor needs it.
    const FlowPoint f =
        Batched ? FlowPoint{.g = batch_out_.g[i],
                            .g_s = batch_out_.g_slip[i],
                            .mu = batch_out_.mu[i],
                            .r_s = batch_out_.r_s[i]}
                : flow_point(a, std::abs(tau(a)), latent_drive(a), slips_against(a, tau), z);
    if (!std::isfinite(f.g)) return {RoleChange::inadmissible, a};
    const bool finite_slope = f.g_s < 0.0 && std::isfinite(f.g_s);
    // An idle system whose excess a slip below that rounding would remove is at its root.
    if (dgamma(a) == 0.0 && finite_slope && f.g <= -f.g_s * p.slip_resolution) continue;
    if (!finite_slope) {
      // No finite slope: at zero slip where r_s (from r_s0 = 0) or the power overstress grows
      // like a root of the slip.
      if (dgamma(a) != 0.0) return {RoleChange::inadmissible, a};
      if (change.kind == RoleChange::none) change = {RoleChange::wants_to_slip, a};
      p.worst = std::max(p.worst, f.g);  // its G(0) = r - r_s0 > 0 stays a residual
      p.converged = false;
      continue;
    }
    p.mu(a) = f.mu, p.r_s(a) = f.r_s;
    p.worst = std::max(p.worst, std::abs(f.g));
    p.converged =
        p.converged && (std::abs(f.g) <= tolerance_ ||
                        within_floor(Batched ? batched_flow_point(a, z) : f, z, a, dgamma));
    const double s = sign_of(tau(a));
    p.sign(a) = s;
    if constexpr (Batched) {
      p.w(a) = s * batch_out_.newton_w[i];
      p.d(a) = batch_out_.newton_d[i];
      p.l(a) = s * batch_out_.newton_l[i];
    } else {
      const double inverse_slope = 1.0 / (-f.g_s);
      const double r_per_mu = f.r * (f.per_traction * fn(a));
      p.w(a) = s * f.g * inverse_slope;
      p.d(a) = f.g_dr * f.per_traction * inverse_slope;
      p.l(a) = s * f.g_dr * (-r_per_mu) * f.dmu_de * inverse_slope;
    }
  }
  return change;
}

template <int N>
inline double StressSolver<N>::idle_friction(int a, double latent) const {
  return ph_.laws[static_cast<size_t>(a)].friction_coefficient_after(s0_.mu(a), latent, dt_).value;
}

template <int N>
inline double StressSolver<N>::slip_root(int a, double dgamma) const {
  const double p_exp = exponent_[static_cast<size_t>(a)];
  const double slip = std::abs(dgamma);
  return p_exp == 2.0 ? std::sqrt(slip) : std::pow(slip, 1.0 / p_exp);
}

template <int N>
inline Vec6 StressSolver<N>::k_times(const SlipPoint& p, const VecN& x) const {
  return Vec6(ph_.schmid * p.d.cwiseProduct(x));
}

template <int N>
inline typename StressSolver<N>::VecN StressSolver<N>::k_transpose_times(const SlipPoint& p,
                                                                         const Vec6& y) const {
  return VecN(p.d.cwiseProduct(ph_.schmid.transpose() * y));
}

template <int N>
inline typename StressSolver<N>::Condensed StressSolver<N>::condense(const SlipPoint& p) const {
  Condensed c;
  Mat6 s = ph_.compliance;
  // Symmetric: its lower triangle (which the L D L^T factorisation reads) as one product of the
  // phase's dyads with d (21 rows and the padding, Phase::schmid_dyads).
  using Lower = Eigen::Matrix<double, Phase<N>::kDyadRows, 1>;
  Lower lower = Lower::Zero();
  for (int a = 0; a < n_; ++a) lower += p.d(a) * ph_.schmid_dyads.col(a);
  for (int j = 0, k = 0; j < 6; ++j)
    for (int i = j; i < 6; ++i) s(i, j) += lower(k++);
  c.ldlt.compute(s);
  if (latent_rank_ > 0) {
    // The products are of at most (latent rank) x 12 x 6: evaluated coefficient-wise
    // (lazyProduct), not by Eigen's general matrix kernels, whose set-up costs more here.
    // diag(l) F and R^T diag(sign) column by column (row by row), each a product of two
    // fixed-size columns, not a diagonal product over dynamic sizes.
    c.lf.resize(n_, latent_rank_);
    c.g.resize(latent_rank_, n_);
    for (int j = 0; j < latent_rank_; ++j) {
      c.lf.col(j) = p.l.cwiseProduct(ph_.latent_factor.col(j));
      c.g.row(j) = p.sign.cwiseProduct(ph_.latent_mix.col(j)).transpose();
    }
    // g K^T row by row, as K times a row of g held at fixed size: the fixed 6 x N product,
    // not a coefficient-wise loop over dynamic sizes.
    c.gk.resize(latent_rank_, 6);
    for (int j = 0; j < latent_rank_; ++j)
      c.gk.row(j) = k_times(p, VecN(c.g.row(j).transpose())).transpose();
    c.z.resize(6, latent_rank_);
    for (int j = 0; j < latent_rank_; ++j)
      c.z.col(j) = c.solve_s(Vec6(ph_.schmid.lazyProduct(c.lf.col(j))));
    if (latent_rank_ == 1) {
      // The 1 x 1 M as two dot products: the coefficients the products below would form,
      // without their assignment loops over dynamic sizes.
      c.m_scalar = 1.0 - c.g.row(0).dot(c.lf.col(0)) + c.gk.row(0).dot(c.z.col(0));
    } else {
      MatK m = MatK::Identity(latent_rank_, latent_rank_);
      m.noalias() -= c.g.lazyProduct(c.lf);
      m.noalias() += c.gk.lazyProduct(c.z);
      c.m.compute(m);
    }
  }
  return c;
}

template <int N>
inline bool StressSolver<N>::slip_step(const SlipPoint& p, VecN& delta) const {
  const Condensed c = condense(p);
  const Vec6 a = c.solve_s(ph_.schmid * p.w);
  Vec6 d_sigma = -a;
  VecK eta;
  if (latent_rank_ > 0) {
    const VecK rhs = c.g.lazyProduct(p.w) - c.gk.lazyProduct(a);
    eta = c.solve_m(rhs);
    d_sigma.noalias() -= c.z.lazyProduct(eta);
  }
  delta = p.w + k_transpose_times(p, d_sigma);
  if (latent_rank_ > 0) delta.noalias() += c.lf.lazyProduct(eta);
  return delta.allFinite();
}

template <int N>
inline void StressSolver<N>::set_batched_starts() {
  for (int a = 0; a < n_; ++a) {
    batch_in_.mu0[static_cast<size_t>(a)] = s0_.mu(a);
    batch_in_.normal[static_cast<size_t>(a)] = ph_.tau0(a);
  }
  const auto& law = ph_.laws.front();
  SubloadingStartBatch b;
  for (int a = 0; a < n_; ++a) b.r0[static_cast<size_t>(a)] = std::clamp(s0_.r_s(a), 0.0, 1.0);
  batched_subloading_starts(law.parameters().subloading.u_tilde, n_, b);
  const auto virgin = law.subloading_start(0.0);
  for (int a = 0; a < n_; ++a) {
    const auto i = static_cast<size_t>(a);
    starts_[i][0] = {.r0 = b.r0[i],
                     .cos0 = b.cos0[i],
                     .one_minus_cos0 = b.one_minus_cos0[i],
                     .integral0 = 0.0,
                     .rate0 = b.rate0[i]};
    starts_[i][1] = virgin;
  }
}

template <int N>
inline void StressSolver<N>::batch_flow_points(const VecN& dgamma, const VecN& tau,
                                               const VecN& latent_drive) const {
  const double q = ph_.has_latent ? ph_.latent_self : 1.0;
  FlowBatchInput& in = batch_in_;
  for (int a = 0; a < n_; ++a) {
    const auto i = static_cast<size_t>(a);
    const double z = dgamma(a) == 0.0 ? 0.0 : std::sqrt(std::abs(dgamma(a)));
    batch_z_[i] = z;
    const auto& start = starts_[i][slips_against(a, tau) ? 1 : 0];
    in.slip[i] = z * z;
    in.effective[i] = q * in.slip[i] + latent_drive(a);
    in.r0[i] = start.r0, in.cos0[i] = start.cos0, in.one_minus_cos0[i] = start.one_minus_cos0;
    in.rate0[i] = start.rate0;
    in.shear[i] = std::abs(tau(a));
  }
  batched_flow_points(ph_.laws.front().parameters(), dt_, q, n_, in, batch_out_);
}

template <int N>
inline FlowPoint StressSolver<N>::batched_flow_point(int a, double z) const {
  const auto i = static_cast<size_t>(a);
  const FlowBatchOutput& o = batch_out_;
  const double slip = batch_in_.slip[i];
  return {.g = o.g[i],
          .g_z = slip > 0.0 ? o.g_slip[i] * (2.0 * z) : 0.0,  // dslip/dz = 2 z
          .g_s = o.g_slip[i],
          .g_dr = o.g_r[i],
          .r = o.r[i],
          .dmu_de = o.mu_slope[i],
          .mu = o.mu[i],
          .r_s = o.r_s[i]};
}

template <int N>
inline FlowPoint StressSolver<N>::flow_point(int a, double abs_tau, double latent, bool against,
                                             double z) const {
  const auto& law = ph_.laws[static_cast<size_t>(a)];
  const double p = exponent_[static_cast<size_t>(a)];
  const double slip = p == 2.0 ? z * z : std::pow(z, p);
  const double dslip_dz = p == 2.0 ? 2.0 * z : p * std::pow(z, p - 1.0);
  const double q = ph_.has_latent ? ph_.latent_self : 1.0;
  const double effective = q * slip + latent;
  const auto mu = law.friction_coefficient_after(s0_.mu(a), effective, dt_);
  const auto& start = starts_[static_cast<size_t>(a)][against ? 1 : 0];
  const auto rs = law.subloading_ratio_after(start, slip);
  // r = |tau|/(mu f_n), its slope 1/(mu f_n) and r/mu from one quotient, as the batches take
  // them (a division costs as much as a dozen products there).
  const double per_traction = 1.0 / (mu.value * ph_.tau0(a));
  const double r = abs_tau * per_traction;
  const auto g = law.flow_residual(r, rs.value, slip, dt_);
  if (!g.admissible || !(mu.value > 0.0))
    return {kInf, 0.0, 0.0, 0.0, r, 0.0, mu.value, rs.value, per_traction};
  const double r_per_mu = r * (per_traction * ph_.tau0(a));
  const double dr_dslip = -r_per_mu * mu.d_slip * q;
  const double g_slip = g.d_r * dr_dslip + g.d_rs * rs.d_slip + g.d_slip;
  return {g.value,     slip > 0.0 ? g_slip * dslip_dz : 0.0,
          g_slip,      g.d_r,
          r,           mu.d_slip,
          mu.value,    rs.value,
          per_traction};
}

template <int N>
inline SystemResponse StressSolver<N>::respond(int a, double abs_tau, double latent, bool against,
                                               double guess) const {
  const double fn = ph_.tau0(a);  // no plane pressure in this solver's domain
  const auto& law = ph_.laws[static_cast<size_t>(a)];
  const auto& start = starts_[static_cast<size_t>(a)][against ? 1 : 0];
  SystemResponse out;
  // No slip where zero slip is the root to this root's own tolerance: G(0) = r - r_s0 for every
  // form, r as the state reports it. Not where r <= r_s0 exactly: a system idle at the end of the
  // last step has r_s0 = r there ((3.12)), so at the start stress its excess is round-off of the
  // state, and a test at zero would give it the full onset slope in the Jacobian or none by that
  // round-off, and the iteration two directions (docs/grain_step.md, "Instruction sets").
  const auto mu_idle = law.friction_coefficient_after(s0_.mu(a), latent, dt_);
  if (abs_tau / (mu_idle.value * fn) - start.r0 <= flow_tolerance_) {
    out.mu = mu_idle.value;
    out.r_s = start.r0;
    return out;
  }
  const double p = exponent_[static_cast<size_t>(a)];
  // A first guess where none is warm: the slip that would relax this system's own excess
  // shear through its elastic stiffness. The excess is not positive where r exceeds r_s0 only
  // by rounding (a system idle at the start stress, r_s0 = r there: r computed as a quotient,
  // the excess as a difference); the guess is then zero slip, where G(0) is at its rounding
  // (not the root of a negative number, a NaN that no bracket recovers from).
  const double excess = std::max(abs_tau - start.r0 * mu_idle.value * fn, 0.0);
  double z = guess > 0.0 ? guess : std::pow(excess / stiffness_(a), 1.0 / p);
  double lo = 0.0, hi = kInf;  // G(lo) > 0 > G(hi)
  const double z_bound = std::pow(kSlipBound, 1.0 / p);
  double previous_abs_g = kInf;
  FlowPoint f{};
  bool converged = false;
  for (int it = 1; it <= 200; ++it) {
    out.iterations = it;
    f = flow_point(a, abs_tau, latent, against, z);
    const double resolution = std::isfinite(f.g_z) ? 4.0 * std::abs(f.g_z) * kEps * z : 0.0;
    if (std::isfinite(f.g) && std::abs(f.g) <= std::max(flow_tolerance_, resolution)) {
      converged = true;
      break;
    }
    if (f.g > 0.0) {
      lo = z;
    } else {
      hi = z;
    }
    if (std::isfinite(hi) && hi - lo <= 4.0 * kEps * hi) {  // the bracket is a few ulp wide
      z = hi;
      f = flow_point(a, abs_tau, latent, against, z);
      converged = std::isfinite(f.g);
      break;
    }
    double next;
    const bool newton_ok = std::isfinite(f.g) && std::isfinite(f.g_z) && f.g_z < 0.0 &&
                           std::abs(f.g) < 0.5 * previous_abs_g;
    const double newton = newton_ok ? z - f.g / f.g_z : kInf;
    if (!std::isfinite(hi)) {
      // No upper bracket yet: Newton where it moves up, otherwise grow.
      next = (newton_ok && newton > lo) ? std::max(newton, z) : kBracketGrowth * std::max(z, lo);
      if (next > z_bound) {
        if (z >= z_bound) break;  // beyond any physical slip: outside the domain
        next = z_bound;
      }
      if (!(next > z)) next = kBracketGrowth * z;
    } else {
      next = (newton > lo && newton < hi) ? newton : 0.5 * (lo + hi);
    }
    previous_abs_g = std::isfinite(f.g) ? std::abs(f.g) : previous_abs_g;
    z = next;
  }
  // G must fall with the slip at the root; at zero slip (a shear loaded past r_s0 by no more
  // than the tolerance) a slope that is infinite (r_s growing like sqrt(ds) from r_s0 = 0)
  // means the slip does not grow to first order.
  const bool finite_slope = f.g_s < 0.0 && std::isfinite(f.g_s);
  if (!converged || (z > 0.0 && !finite_slope)) {
    out.admissible = false;
    return out;
  }
  const double slip = p == 2.0 ? z * z : std::pow(z, p);
  // Implicit function: d ds/dx = -(dG/dx)/(dG/ds) for x = |tau|, f_n, h.
  const double scale = finite_slope ? -1.0 / f.g_s : 0.0;
  const double dr_dtau = 1.0 / (f.mu * fn);
  out.slip = slip;
  out.z = z;
  out.mu = f.mu;
  out.r_s = f.r_s;
  out.d_tau = scale * f.g_dr * dr_dtau;
  out.d_latent = scale * f.g_dr * (-f.r / f.mu) * f.dmu_de;
  out.uncertainty = std::max(flow_tolerance_, 4.0 * std::abs(f.g_z) * kEps * z) * std::abs(scale);
  return out;
}

}  // namespace subslip::crystal::implicit_detail
