// StressSolver's slip rows, their condensed Newton system and each system's flow points and
// scalar roots (declared in stress_solver.hpp). Internal to src/crystal/.
#pragma once

#include "stress_solver.hpp"

namespace subslip::crystal::implicit_detail {

template <int N>
inline double StressSolver<N>::activation_slip(int a, const SlipPoint& p) const {
  const double tau = tau_of(p.sigma, a);
  const VecN fn = normal_traction(ph_, p.sigma);
  const bool against = tau * tau_start_(a) < 0.0;
  const SystemResponse resp =
      respond(a, std::abs(tau), fn(a), latent_drives(p.dgamma)(a), against, 0.0);
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
inline bool StressSolver<N>::within_floor(const FlowPoint& f, double z, int a, const VecN& dgamma,
                                          double fn) const {
  if (std::abs(f.g) <= tolerance_) return true;
  const double shear_size = std::abs(tau_trial_(a)) +
                            ph_.interaction.row(a).cwiseAbs().dot(dgamma.cwiseAbs().transpose());
  return std::abs(f.g) <=
         4.0 * kEps *
             (1.0 + f.r + std::abs(f.g_z) * z + std::abs(f.g_dr) * shear_size / (f.mu * fn));
}

template <int N>
inline bool StressSolver<N>::is_saturated(int a, const FlowPoint& f, double fn) const {
  if (!ph_.laws[static_cast<size_t>(a)].is_rate_independent() || !std::isfinite(f.g_s) ||
      f.g_s > 0.0)
    return false;
  return -f.g_s * f.mu * fn <= kEps * f.g_dr * stiffness_(a);
}

template <int N>
inline typename StressSolver<N>::RoleChange StressSolver<N>::evaluate_slips(const VecN& dgamma,
                                                                            SlipPoint& p) const {
  p.sigma = trial_;
  p.sigma.noalias() -= ph_.c_schmid * dgamma;
  const VecN tau = ph_.schmid.transpose() * p.sigma;
  const VecN fn = normal_traction(ph_, p.sigma);
  const VecN latent_drive = latent_drives(dgamma);
  p.dgamma = dgamma;
  for (VecN* v : {&p.mu, &p.r_s, &p.w, &p.d, &p.e, &p.l, &p.sign, &p.yield_normal, &p.yield_rhs})
    v->setZero(n_);
  p.saturated.setConstant(n_, false);
  p.worst = 0.0;
  p.converged = true;
  // The rounding of the largest slip, which the stress C P dgamma cannot resolve below.
  p.slip_resolution = 4.0 * kEps * dgamma.cwiseAbs().maxCoeff();
  if (batched_) {
    batch_flow_points(dgamma, tau, latent_drive);
    return slip_rows<true>(dgamma, tau, fn, latent_drive, p);
  }
  return slip_rows<false>(dgamma, tau, fn, latent_drive, p);
}

template <int N>
template <bool Batched>
inline typename StressSolver<N>::RoleChange StressSolver<N>::slip_rows(const VecN& dgamma,
                                                                       const VecN& tau,
                                                                       const VecN& fn,
                                                                       const VecN& latent_drive,
                                                                       SlipPoint& p) const {
  RoleChange change;
  for (int a = 0; a < n_; ++a) {
    const auto i = static_cast<size_t>(a);
    if (!(fn(a) > 0.0)) return {RoleChange::inadmissible, a};
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
                : flow_point(a, std::abs(tau(a)), fn(a), latent_drive(a), slips_against(a, tau), z);
    if (!std::isfinite(f.g)) return {RoleChange::inadmissible, a};
    if constexpr (!Batched) {
      if (is_saturated(a, f, fn(a))) {
        saturated_row(a, f, z, dgamma, tau, fn, p);
        continue;
      }
    }
    const bool finite_slope = f.g_s < 0.0 && std::isfinite(f.g_s);
    // An idle system whose excess a slip below that rounding would remove is at its root.
    if (dgamma(a) == 0.0 && finite_slope && f.g <= -f.g_s * p.slip_resolution) continue;
    if (!finite_slope) {
      // No finite slope: at zero slip where r_s (from r_s0 = 0) or the power overstress grows
      // like a root of the slip, or a flow rule that no longer depends on the slip.
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
                        within_floor(Batched ? batched_flow_point(a, z) : f, z, a, dgamma, fn(a)));
    const double s = sign_of(tau(a));
    p.sign(a) = s;
    if constexpr (Batched) {
      p.w(a) = s * batch_out_.newton_w[i];
      p.d(a) = batch_out_.newton_d[i];
      p.l(a) = s * batch_out_.newton_l[i];
    } else {
      const double inverse_slope = 1.0 / (-f.g_s);
      p.w(a) = s * f.g * inverse_slope;
      p.d(a) = f.g_dr / (f.mu * fn(a)) * inverse_slope;
      p.e(a) = ph_.pressure_sensitive ? s * f.g_dr * (-f.r / fn(a)) * inverse_slope : 0.0;
      p.l(a) = s * f.g_dr * (-f.r / f.mu) * f.dmu_de * inverse_slope;
    }
  }
  return change;
}

template <int N>
inline void StressSolver<N>::saturated_row(int a, const FlowPoint& f, double z, const VecN& dgamma,
                                           const VecN& tau, const VecN& fn, SlipPoint& p) const {
  p.saturated(a) = true;
  p.sign(a) = dgamma(a) != 0.0 ? sign_of(dgamma(a)) : sign_of(tau(a));
  p.mu(a) = f.mu, p.r_s(a) = f.r_s;
  p.worst = std::max(p.worst, std::abs(f.g));
  p.converged = p.converged && within_floor(f, z, a, dgamma, fn(a));
  // dG = g_dr (dr/d|tau| s P_a:ds - r/f_n df_n), df_n = -M_a:ds; scaled by mu f_n/g_dr.
  p.yield_normal(a) = ph_.pressure_sensitive ? f.r * f.mu : 0.0;
  p.yield_rhs(a) = -f.g * f.mu * fn(a) / f.g_dr;
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
inline Vec6 StressSolver<N>::k_times(const SlipPoint& p, const Condensed& c, const VecN& x) const {
  return c.symmetric ? Vec6(ph_.schmid * p.d.cwiseProduct(x)) : Vec6(c.k * x);
}

template <int N>
inline typename StressSolver<N>::VecN StressSolver<N>::k_transpose_times(const SlipPoint& p,
                                                                         const Condensed& c,
                                                                         const Vec6& y) const {
  return c.symmetric ? VecN(p.d.cwiseProduct(ph_.schmid.transpose() * y))
                     : VecN(c.k.transpose() * y);
}

template <int N>
inline typename StressSolver<N>::Condensed StressSolver<N>::condense(const SlipPoint& p) const {
  Condensed c;
  Mat6 s = ph_.compliance;
  if (ph_.pressure_sensitive) {
    c.k.noalias() = ph_.schmid * p.d.asDiagonal();
    c.k.noalias() -= ph_.plane_normal_dyad * p.e.asDiagonal();
    c.symmetric = false;
    s.noalias() += ph_.schmid.lazyProduct(c.k.transpose());
    c.lu.compute(s);
  } else {
    // Symmetric: its lower triangle (which the L D L^T factorisation reads) as one product
    // of the phase's 21 x n dyads with d.
    Eigen::Matrix<double, 21, 1> lower = Eigen::Matrix<double, 21, 1>::Zero();
    for (int a = 0; a < n_; ++a) lower += p.d(a) * ph_.schmid_dyads.col(a);
    for (int j = 0, k = 0; j < 6; ++j)
      for (int i = j; i < 6; ++i) s(i, j) += lower(k++);
    c.ldlt.compute(s);
  }
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
      c.gk.row(j) = k_times(p, c, VecN(c.g.row(j).transpose())).transpose();
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
inline typename StressSolver<N>::MatDQ StressSolver<N>::saturated_solve(const SlipPoint& p,
                                                                        const Condensed& c,
                                                                        const MatDQ& rhs) const {
  const int k = latent_rank_;
  const int m = static_cast<int>(p.saturated.count());
  const int dim = 6 + k + m;
  const double scale = latent_scale_;
  MatD a = MatD::Zero(dim, dim);
  a.topLeftCorner(6, 6) = scale * ph_.compliance;
  if (c.symmetric)
    a.topLeftCorner(6, 6).noalias() +=
        scale * ph_.schmid * p.d.asDiagonal() * ph_.schmid.transpose();
  else
    a.topLeftCorner(6, 6).noalias() += scale * ph_.schmid * c.k.transpose();
  if (k > 0) {
    a.block(0, 6, 6, k).noalias() = scale * ph_.schmid * c.lf;
    a.block(6, 0, k, 6) = -c.gk;
    a.block(6, 6, k, k).setIdentity();
    a.block(6, 6, k, k).noalias() -= c.g * c.lf;
  }
  for (int a_idx = 0, j = 6 + k; a_idx < n_; ++a_idx) {
    if (!p.saturated(a_idx)) continue;
    a.block(0, j, 6, 1) = ph_.schmid.col(a_idx);
    if (k > 0) a.block(6, j, k, 1) = -c.g.col(a_idx) / scale;
    a.block(j, 0, 1, 6) = p.sign(a_idx) * ph_.schmid.col(a_idx).transpose();
    if (ph_.pressure_sensitive)
      a.block(j, 0, 1, 6) += p.yield_normal(a_idx) * ph_.plane_normal_dyad.col(a_idx).transpose();
    ++j;
  }
  return Eigen::CompleteOrthogonalDecomposition<MatD>(a).solve(rhs);
}

template <int N>
inline typename StressSolver<N>::VecN StressSolver<N>::saturated_slips(const SlipPoint& p,
                                                                       const Condensed& c,
                                                                       const MatDQ& x, int col,
                                                                       const VecN& w) const {
  const int k = latent_rank_;
  VecN delta = w + k_transpose_times(p, c, Vec6(x.block(0, col, 6, 1)));
  if (k > 0) delta.noalias() += c.lf * x.block(6, col, k, 1);
  for (int a = 0, j = 6 + k; a < n_; ++a)
    if (p.saturated(a)) delta(a) = x(j++, col) / latent_scale_;
  return delta;
}

template <int N>
inline bool StressSolver<N>::slip_step(const SlipPoint& p, VecN& delta) const {
  const Condensed c = condense(p);
  if (p.saturated.any()) {
    const int k = latent_rank_;
    const int m = static_cast<int>(p.saturated.count());
    MatDQ rhs = MatDQ::Zero(6 + k + m, 1);
    rhs.topRows(6) = -latent_scale_ * (ph_.schmid * p.w);
    if (k > 0) rhs.block(6, 0, k, 1) = c.g * p.w;
    for (int a = 0, j = 6 + k; a < n_; ++a)
      if (p.saturated(a)) rhs(j++, 0) = p.yield_rhs(a);
    delta = saturated_slips(p, c, saturated_solve(p, c, rhs), 0, p.w);
    return delta.allFinite();
  }
  const Vec6 a = c.solve_s(ph_.schmid * p.w);
  Vec6 d_sigma = -a;
  VecK eta;
  if (latent_rank_ > 0) {
    const VecK rhs = c.g.lazyProduct(p.w) - c.gk.lazyProduct(a);
    eta = c.solve_m(rhs);
    d_sigma.noalias() -= c.z.lazyProduct(eta);
  }
  delta = p.w + k_transpose_times(p, c, d_sigma);
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
inline FlowPoint StressSolver<N>::flow_point(int a, double abs_tau, double fn, double latent,
                                             bool against, double z) const {
  const auto& law = ph_.laws[static_cast<size_t>(a)];
  const double p = exponent_[static_cast<size_t>(a)];
  const double slip = p == 2.0 ? z * z : std::pow(z, p);
  const double dslip_dz = p == 2.0 ? 2.0 * z : p * std::pow(z, p - 1.0);
  const double q = ph_.has_latent ? ph_.latent_self : 1.0;
  const double effective = q * slip + latent;
  const auto mu = law.friction_coefficient_after(s0_.mu(a), effective, dt_);
  const auto& start = starts_[static_cast<size_t>(a)][against ? 1 : 0];
  const auto rs = law.subloading_ratio_after(start, slip);
  const double r = abs_tau / (mu.value * fn);
  const auto g = law.flow_residual(r, rs.value, slip, dt_);
  if (!g.admissible || !(mu.value > 0.0)) return {kInf, 0.0, 0.0, 0.0, r, 0.0, mu.value, rs.value};
  const double dr_dslip = -r / mu.value * mu.d_slip * q;
  const double g_slip = g.d_r * dr_dslip + g.d_rs * rs.d_slip + g.d_slip;
  return {g.value, slip > 0.0 ? g_slip * dslip_dz : 0.0, g_slip, g.d_r, r, mu.d_slip, mu.value,
          rs.value};
}

template <int N>
inline SystemResponse StressSolver<N>::respond(int a, double abs_tau, double fn, double latent,
                                               bool against, double guess) const {
  const auto& law = ph_.laws[static_cast<size_t>(a)];
  const auto& start = starts_[static_cast<size_t>(a)][against ? 1 : 0];
  SystemResponse out;
  // No slip where r <= r_s0 (G(0) = r - r_s0 for every form); r as the state reports it.
  const auto mu_idle = law.friction_coefficient_after(s0_.mu(a), latent, dt_);
  if (abs_tau / (mu_idle.value * fn) <= start.r0) {
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
    f = flow_point(a, abs_tau, fn, latent, against, z);
    // Rate-independent: r_s <= 1 (it reaches 1 only in rounding, after large slip), so the
    // root at a held shear does not exist where r > 1: outside the flow rule's domain.
    if (law.is_rate_independent() && f.r > 1.0) f.g = kInf;
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
      f = flow_point(a, abs_tau, fn, latent, against, z);
      converged = std::isfinite(f.g) && !(law.is_rate_independent() && f.r > 1.0);
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
  out.d_normal = scale * f.g_dr * (-f.r / fn);
  out.d_latent = scale * f.g_dr * (-f.r / f.mu) * f.dmu_de;
  out.uncertainty = std::max(flow_tolerance_, 4.0 * std::abs(f.g_z) * kEps * z) * std::abs(scale);
  return out;
}

}  // namespace subslip::crystal::implicit_detail
