// The implicit grain step's solver (src/crystal/implicit_grain_step.hpp): the stress-space
// residual, its Jacobian and sensitivities (StressSolver), and the slip-space Newton iteration
// that takes over from it (StressSolver::slip_newton), with each slip system's scalar flow rule.
// Its domain is the one solve_grain_step gives it: no plane pressure (f_n = tau0 on every
// system) and on every system an overstress form whose resistance grows with slip
// (resistance_grows_with_slip); other phases go to the semismooth step or the step on the
// yield polytope, and no branch here handles them.
// The members of the slip rows, their condensed system and the flow points are defined in
// stress_solver_slips.hpp, which includes this header (include that one). Internal to
// src/crystal/ (see implicit_grain_step.hpp).
#pragma once

#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>

#include "grain_step_isa.hpp"
#include "kernel_detail.hpp"
#include "subslip/crystal/flow_point_batch.hpp"

namespace subslip::crystal {

namespace implicit_detail {

using namespace detail;

constexpr double kEps = std::numeric_limits<double>::epsilon();
constexpr double kInf = std::numeric_limits<double>::infinity();

// Slip of one system in one step above which a stress is taken to lie outside the domain of the
// flow rule (r -> r_hat for an overstress form, r -> 1 without one): no physical step slips a
// thousand in shear, and the merit there is infinite, so the line search steps back.
constexpr double kSlipBound = 1e3;
// Growth of a scalar root's unknown per try while no upper bracket is known.
constexpr double kBracketGrowth = 4.0;

// The response of one slip system to a resolved shear |tau| and a latent slip h (the others'
// slips that harden it), on one branch: the slip increment ds >= 0 that solves its flow rule
// G(r(ds), r_s(ds), ds) = 0, and its derivatives.
struct SystemResponse {
  double slip = 0.0;         // ds
  double z = 0.0;            // ds^(1/p): the unknown of the scalar root (warm start of the next)
  double mu = 0.0;           // friction coefficient after the step
  double r_s = 0.0;          // subloading ratio after the step
  double d_tau = 0.0;        // d ds / d|tau|
  double d_latent = 0.0;     // d ds / d h
  double uncertainty = 0.0;  // of ds: the scalar root's tolerance on G over |dG/d ds|
  bool admissible = true;
  int iterations = 0;
};

// The flow rule of one system, one value of its unknown z.
struct FlowPoint {
  double g = 0.0;    // G, ratio units; +inf where r >= r_hat
  double g_z = 0.0;  // dG/dz
  double g_s = 0.0;  // dG/d ds (-inf at ds = 0 where r_s or the overstress grows like a root of ds)
  double g_dr = 0.0;  // dG/dr
  double r = 0.0;
  double dmu_de = 0.0;  // d mu / d(effective slip)
  double mu = 0.0, r_s = 0.0;
  double per_traction = 0.0;  // 1/(mu f_n) = dr/d|tau| (its system-by-system evaluation only)
};

template <int N>
class StressSolver {
 public:
  using T = SlipTypes<N>;
  using VecN = typename T::VecN;
  // The latent drives: at most one per system (at least room for two, one SSE packet, so that no
  // vectorised access to a one-element buffer is compiled for a single system).
  static constexpr int MaxExtras = T::MaxN < 2 ? 2 : T::MaxN;
  static constexpr int MaxY = 6 + MaxExtras;  // sigma, latent drive
  using VecY = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, MaxExtras, 1>;
  using Flags = Eigen::Matrix<bool, N, 1, 0, T::MaxN, 1>;
  using MatJ = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, MaxY, MaxY>;
  using MatJ6 = Eigen::Matrix<double, Eigen::Dynamic, 6, 0, MaxY, 6>;

  // One point of the outer iteration and everything the Jacobian needs there.
  struct Iterate {
    Vec6 sigma;
    VecY y;  // the latent drive (see extras_for); empty without a latent matrix
    VecN tau, slip, z, dgamma, mu, r_s, d_tau, d_latent, uncertainty;
    Flags against;  // slips against its start shear: r_s restarts from 0 (3.12)
    Vec6 r_sigma;
    VecY r_y;
    double merit = kInf;
    int bad_system = -1;  // the system that made the point inadmissible
    int scalar_iterations = 0;
  };

  StressSolver(const Phase<N>& ph, const GrainState<N>& s0, const Vec6& trial, double dt,
               const GrainStepOptions& opt)
      : ph_(ph),
        s0_(s0),
        dt_(dt),
        n_(ph.slip_count),
        trial_(trial),
        batched_(ph.batched_flow_points) {
    tau_start_ = ph.schmid.transpose() * s0.stress;
    tau_trial_ = ph.schmid.transpose() * trial;
    stiffness_ = ph.interaction.diagonal();
    latent_rank_ = ph.has_latent ? ph.latent_rank : 0;
    extras_ = latent_rank_;
    latent_scale_ = stiffness_.mean();
    warm_z_.setZero(n_);
    warm_against_.setConstant(n_, false);
    if (batched_) {
      clear_batch_padding(batch_in_, n_);
      set_batched_starts();
    }
    double crss = 0.0;
    for (int a = 0; a < n_; ++a) {
      const auto& law = ph.laws[static_cast<size_t>(a)];
      if (!batched_)
        starts_[static_cast<size_t>(a)] = {law.subloading_start(s0.r_s(a)),
                                           law.subloading_start(0.0)};
      exponent_[static_cast<size_t>(a)] = std::max(law.slip_exponent(), 2.0);
      crss = std::max(crss, s0.mu(a) * ph.tau0(a));
    }
    stress_scale_ = std::max(trial.cwiseAbs().maxCoeff(), crss);
    residual_tolerance_ = opt.tolerance * stress_scale_;
    // The scalar roots an order tighter than the outer residual asks (ratio units).
    flow_tolerance_ = 1e-2 * opt.tolerance;
    tolerance_ = opt.tolerance;
    max_iterations_ = opt.max_iterations;
  }

  // How far R can be from zero at an exact solution, from the rounding of the scalar roots'
  // slips: |C P| times their uncertainty (the residual cannot be resolved below it).
  double residual_floor(const Iterate& it) const {
    return (ph_.c_schmid.cwiseAbs() * it.uncertainty).maxCoeff();
  }

  int extras() const { return extras_; }

  // Whether R is C times the gradient of the convex potential Phi (see docs/grain_step.md):
  // no latent coupling. The line search then works on Phi, which is C^1 where R has kinks (a
  // system starting to slip), so the Newton direction is a descent direction there too.
  bool has_potential() const { return extras_ == 0; }
  // d Phi / d alpha along d_sigma at an iterate: (C^-1 R) . d_sigma.
  double potential_slope(const Iterate& it, const Vec6& d_sigma) const {
    return (ph_.compliance * it.r_sigma).dot(d_sigma);
  }
  double residual_tolerance() const { return residual_tolerance_; }
  double stress_scale() const { return stress_scale_; }

  // The extra unknowns y: the latent drive c R^T |dgamma| (latent_rank numbers, R the phase's
  // latent_mix, c a mean elastic stiffness so that its rows are in stress units like sigma's).
  VecY extras_for(const VecN& dgamma) const {
    VecY y = VecY::Zero(extras_);
    if (latent_rank_ > 0)
      y.head(latent_rank_).noalias() =
          latent_scale_ * ph_.latent_mix.leftCols(latent_rank_).transpose() * dgamma.cwiseAbs();
    return y;
  }

  // Uses the slips of an iterate as the starting guesses of the next scalar roots.
  void remember(const Iterate& it) {
    warm_z_ = it.z;
    warm_against_ = it.against;
  }

  void evaluate(const Vec6& sigma, const VecY& y, Iterate& it) const {
    it.sigma = sigma;
    it.y = y;
    it.tau.noalias() = ph_.schmid.transpose() * sigma;
    for (VecN* v :
         {&it.slip, &it.z, &it.dgamma, &it.mu, &it.r_s, &it.d_tau, &it.d_latent, &it.uncertainty})
      v->setZero(n_);
    it.against.setConstant(n_, false);
    it.merit = kInf;
    it.bad_system = -1;
    it.scalar_iterations = 0;
    for (int a = 0; a < n_; ++a) {
      const bool against = slips_against(a, it.tau);
      const double latent =
          latent_rank_ > 0 ? ph_.latent_factor.row(a).head(latent_rank_).dot(y.head(latent_rank_)) /
                                 latent_scale_
                           : 0.0;
      const double guess = warm_against_(a) == against ? warm_z_(a) : 0.0;
      const SystemResponse resp = respond(a, std::abs(it.tau(a)), latent, against, guess);
      it.scalar_iterations += resp.iterations;
      if (!resp.admissible) {
        it.bad_system = a;
        return;
      }
      it.against(a) = against;
      it.slip(a) = resp.slip, it.z(a) = resp.z, it.mu(a) = resp.mu, it.r_s(a) = resp.r_s;
      it.d_tau(a) = resp.d_tau, it.d_latent(a) = resp.d_latent;
      it.uncertainty(a) = resp.uncertainty;
      it.dgamma(a) = sign_of(it.tau(a)) * resp.slip;
    }
    it.r_sigma = sigma - trial_;
    it.r_sigma.noalias() += ph_.c_schmid * it.dgamma;
    it.r_y = y - extras_for(it.dgamma);
    it.merit = 0.5 * (it.r_sigma.squaredNorm() + it.r_y.squaredNorm());
  }

  // d dgamma_a / d sigma (columns).
  Eigen::Matrix<double, 6, N, 0, 6, T::MaxN> slip_gradient(const Iterate& it) const {
    Eigen::Matrix<double, 6, N, 0, 6, T::MaxN> w = ph_.schmid * it.d_tau.asDiagonal();
    return w;
  }

  // d dgamma / d y (n x extras).
  using MatNY = Eigen::Matrix<double, N, Eigen::Dynamic, 0, T::MaxN, MaxY>;
  MatNY slip_gradient_in_extras(const Iterate& it) const {
    MatNY g = MatNY::Zero(n_, extras_);
    for (int a = 0; a < n_ && latent_rank_ > 0; ++a)
      g.row(a).head(latent_rank_) = sign_of(it.tau(a)) * it.d_latent(a) / latent_scale_ *
                                    ph_.latent_factor.row(a).head(latent_rank_);
    return g;
  }

  // The 6 x 6 Jacobian (no extra unknowns).
  Mat6 stress_jacobian(const Iterate& it) const {
    Mat6 j = Mat6::Identity();
    j.noalias() += ph_.c_schmid.lazyProduct(slip_gradient(it).transpose());
    return j;
  }

  // The full Jacobian with the extra unknowns: rows R_sigma, then R_y = y - extras_for(dgamma).
  MatJ full_jacobian(const Iterate& it) const {
    const int m = 6 + extras_;
    MatJ j = MatJ::Zero(m, m);
    const auto w = slip_gradient(it);
    const auto g = slip_gradient_in_extras(it);
    j.topLeftCorner(6, 6) = stress_jacobian(it);
    j.topRightCorner(6, extras_).noalias() = ph_.c_schmid * g;
    j.bottomRightCorner(extras_, extras_).setIdentity();
    if (latent_rank_ > 0) {
      // d(c R^T |dgamma|) = c R^T S (W^T d sigma + G d y), S = sign(tau).
      VecN sign(n_);
      for (int a = 0; a < n_; ++a) sign(a) = sign_of(it.tau(a));
      const Eigen::Matrix<double, Eigen::Dynamic, N, 0, MaxY, T::MaxN> rs =
          latent_scale_ * ph_.latent_mix.leftCols(latent_rank_).transpose() * sign.asDiagonal();
      j.block(6, 0, latent_rank_, 6).noalias() -= rs * w.transpose();
      j.block(6, 6, latent_rank_, extras_).noalias() -= rs * g;
    }
    return j;
  }

  // The Newton correction of an iterate: (d sigma, d y).
  bool newton_correction(const Iterate& it, Vec6& d_sigma, VecY& d_y) const {
    if (extras_ == 0) {
      d_sigma = -Eigen::PartialPivLU<Mat6>(stress_jacobian(it)).solve(it.r_sigma);
      d_y.resize(0);
    } else {
      const int m = 6 + extras_;
      Eigen::Matrix<double, Eigen::Dynamic, 1, 0, MaxY, 1> rhs(m);
      rhs << it.r_sigma, it.r_y;
      const Eigen::Matrix<double, Eigen::Dynamic, 1, 0, MaxY, 1> d =
          -Eigen::PartialPivLU<MatJ>(full_jacobian(it)).solve(rhs);
      d_sigma = d.head(6);
      d_y = d.tail(extras_);
    }
    return d_sigma.allFinite() && d_y.allFinite();
  }

  // d sigma / d(strain increment) (lattice) and d dgamma / d(strain increment) at a solution.
  void sensitivities(const Iterate& it, Mat6& d_sigma, typename T::MatN6& d_dgamma) const {
    const auto w = slip_gradient(it);
    if (extras_ == 0) {
      d_sigma = Eigen::PartialPivLU<Mat6>(stress_jacobian(it)).solve(ph_.stiffness);
      d_dgamma.noalias() = w.transpose() * d_sigma;
      return;
    }
    const int m = 6 + extras_;
    MatJ6 rhs = MatJ6::Zero(m, 6);
    rhs.topRows(6) = ph_.stiffness;
    const MatJ6 x = Eigen::PartialPivLU<MatJ>(full_jacobian(it)).solve(rhs);
    d_sigma = x.topRows(6);
    d_dgamma.noalias() = w.transpose() * d_sigma;
    d_dgamma.noalias() += slip_gradient_in_extras(it) * x.bottomRows(extras_);
  }

  // Newton on the slips themselves, with the stress written from them (sigma = sigma_trial -
  // C P dgamma, exact) and every flow rule G_a as a residual. Its Jacobian is diagonal (each
  // system's own slope) plus the elastic coupling through P^T C P (rank 6) plus the latent
  // coupling F R^T (rank latent_rank), so each step is solved through a (6 + latent_rank)
  // system condensed to 6 x 6, whatever the slip count, and costs one flow-rule evaluation per
  // system. It converges quadratically where it starts close; it is used
  //  - first, from the last step's slip rate continued (most steps of a loading path: the
  //    predictor is within the region of quadratic convergence), and
  //  - after the stress-space solve (see the file comment), from its slips, to resolve each slip
  //    to round-off: the stress iterate fixes each slip only to |dG/d ds|^-1 times G's
  //    rounding, coarse where the law is nearly rate-independent.
  // A step is kept while it at least halves the largest flow-rule residual (quadratic
  // convergence does much better). From the last step's rates (`damped` false) a full step that
  // does not is the sign of a start outside Newton's region of quadratic convergence, and the
  // iteration stops there (the stress-space solve takes over); as the polish (`damped` true) it
  // halves the step instead. A system idle at the start that the written stress loads past r_s0
  // becomes active, with its slip from its own scalar flow rule at that stress; a slip whose
  // shear the written stress turns against it is dropped. From the last step's rates, an active
  // set met again without a smaller residual than at its last visit ends the iteration (a cycle
  // of role changes). A stress outside the flow rule's domain ends it too.
  struct SlipPoint {
    Vec6 sigma;
    VecN dgamma, mu, r_s;
    // The Newton linearization: the change of dgamma_a for a stress change ds and latent-drive
    // change eta = R^T S d|dgamma| is w_a + d_a P_a:ds + l_a F_a.eta.
    VecN w, d, l, sign;
    double worst = kInf;           // largest |G_a| (an idle system: r - r_s0 where positive)
    double slip_resolution = 0.0;  // the rounding of the largest slip
    bool converged = false;
  };

  // The slips at which the stress iterate's Newton correction points, to first order (the
  // iterate's residual is mostly the scalar roots' rounding, which this takes back out).
  VecN corrected_slips(const Iterate& it) const {
    VecN dgamma = it.dgamma;
    Vec6 d_sigma;
    VecY d_y;
    if (newton_correction(it, d_sigma, d_y)) {
      dgamma.noalias() += slip_gradient(it).transpose() * d_sigma;
      if (extras_ > 0) dgamma.noalias() += slip_gradient_in_extras(it) * d_y;
    }
    // A slip that the correction turned against its own sign is at the resolution of zero.
    for (int a = 0; a < n_; ++a)
      if (dgamma(a) * it.dgamma(a) <= 0.0) dgamma(a) = 0.0;
    return dgamma;
  }

  // Returns whether any point was evaluated; `best` is the last kept point, `iterations` counts
  // the Newton steps taken. A Newton step that leaves the flow rules' domain (r >= r_hat, an
  // open plane) or does not reduce the largest residual by the fraction lambda/2 of its length
  // lambda is halved (where `damped`; see above); it ends when a halved step no longer changes
  // the slips. The first point tried is start + first_step, damped towards start like any
  // Newton step.
  bool slip_newton(const VecN& start, const VecN& first_step, SlipPoint& best, int& iterations,
                   bool damped) const {
    // Changes of the active set count like Newton iterations against the same cap (a cycle
    // between active sets ends there, and the stress-space solve takes over).
    int role_changes = 0, steps = 0;
    // The active sets (which systems slip, and which way) visited so far, each with the largest
    // residual it was left at: a set met again without a smaller residual is a cycle.
    struct Visit {
      std::uint64_t slipping, positive;
      double worst;
    };
    std::array<Visit, 64> visited;
    int visits = 0;
    auto visit = [&](const VecN& d, double worst) {
      std::uint64_t slipping = 0, positive = 0;
      for (int a = 0; a < n_; ++a) {
        if (d(a) != 0.0) slipping |= std::uint64_t{1} << a;
        if (d(a) > 0.0) positive |= std::uint64_t{1} << a;
      }
      for (int k = 0; k < visits; ++k) {
        Visit& v = visited[static_cast<size_t>(k)];
        if (v.slipping != slipping || v.positive != positive) continue;
        if (!(worst < v.worst)) return false;
        v.worst = worst;
        return true;
      }
      if (visits == static_cast<int>(visited.size())) return false;
      visited[static_cast<size_t>(visits++)] = {slipping, positive, worst};
      return true;
    };
    visit(start + first_step, kInf);
    best.worst = kInf;
    double reference = kInf;  // the residual of the point the pending step starts from
    VecN base = start, delta = first_step;
    double lambda = 1.0;  // the pending step's length (0: none)
    VecN dgamma = base + delta;
    SlipPoint current;
    for (;;) {
      const RoleChange change = evaluate_slips(dgamma, current);
      const bool rejected = change.kind == RoleChange::inadmissible ||
                            (change.kind == RoleChange::none && !current.converged &&
                             !(current.worst <= (1.0 - 0.5 * lambda) * reference));
      // A full step that does not halve the largest residual: the slips are not within Newton's
      // region of quadratic convergence, where this iteration is meant to work; the globally
      // convergent stress-space solve takes over.
      if (rejected && !damped && lambda == 1.0 && std::isfinite(reference))
        return std::isfinite(best.worst);
      if (rejected) {
        lambda *= 0.5;
        const double move = lambda * delta.cwiseAbs().maxCoeff();
        if (!(move > 4.0 * kEps * base.cwiseAbs().maxCoeff())) return std::isfinite(best.worst);
        dgamma = base + lambda * delta;
        continue;
      }
      if (change.kind != RoleChange::none) {
        const int a = change.system;
        // A slip set to zero without a change of the active set (no role change counted):
        // * below the rounding of the others: dropping it moves no stress (and cannot cycle);
        // * carried through zero by the step while its shear kept its sign: the linearised flow
        //   rules want it below zero, where a slip of that sign cannot go. It is projected onto
        //   zero (the projected Newton step of the complementarity "slip >= 0 on the shear's
        //   side, G <= 0, one of them zero"), not bisected towards zero: the root of such a
        //   system is mostly at zero (a system that stops slipping), which bisection reaches
        //   only after some forty halvings, each failing the step's contraction test. Where its
        //   flow rule still wants slip at zero, the evaluation there says so and it re-enters
        //   the active set with its activation slip below, a role change that is counted and
        //   checked for cycles like any other.
        if (change.kind == RoleChange::turned_against &&
            (std::abs(dgamma(a)) <= current.slip_resolution || base(a) * dgamma(a) < 0.0)) {
          dgamma(a) = 0.0;
          continue;
        }
        const double direction = sign_of(tau_of(current.sigma, a));
        if (++role_changes > max_iterations_) return std::isfinite(best.worst);
        if (change.kind == RoleChange::turned_against) {
          dgamma(a) = 0.0;
        } else {
          const double slip = activation_slip(a, current);
          if (!(slip > 0.0)) return std::isfinite(best.worst);
          dgamma(a) = direction * slip;
        }
        // An active set met before: the role changes cycle and will not settle; the stress-space
        // solve, in which each slip is a continuous function of the stress, takes over.
        if (!damped && !visit(dgamma, current.worst)) return std::isfinite(best.worst);
        reference = kInf;  // a new active set: its own contraction starts here
        lambda = 0.0;
        continue;
      }
      if (current.worst <= best.worst || current.converged) best = current;
      if (current.converged) return true;
      if (++steps > max_iterations_) return true;
      if (!slip_step(current, delta)) return true;
      reference = current.worst;
      base = dgamma;
      lambda = 1.0;
      dgamma = base + delta;
      ++iterations;
    }
  }

  // d sigma / d(strain increment) and d dgamma / d(strain increment) along the lattice strain
  // directions e (6 x k) at a converged slip point: the Newton system with e in place of the
  // residual, solved for its k columns.
  void slip_sensitivities(const SlipPoint& p, const StrainDirections& e, Tangent& d_sigma,
                          SlipTangent<N>& d_dgamma) const {
    // The Newton system with the strain increment in place of the residual:
    //   S ds = de - P lf eta,  M eta = g K^T S^-1 de.
    const Condensed c = condense(p);
    const int cols = static_cast<int>(e.cols());
    // Column by column: the triangular solves of a 6-vector, not Eigen's blocked kernels for
    // a matrix right-hand side, whose set-up costs more than the solve at this size.
    d_sigma.resize(6, cols);
    for (int col = 0; col < cols; ++col) d_sigma.col(col) = c.solve_s(Vec6(e.col(col)));
    MatKC eta;
    if (latent_rank_ > 0) {
      eta = c.solve_m(MatKC(c.gk * d_sigma));
      d_sigma.noalias() -= c.z * eta;
    }
    d_dgamma.resize(n_, cols);
    for (int col = 0; col < cols; ++col)
      d_dgamma.col(col) = k_transpose_times(p, Vec6(d_sigma.col(col)));
    if (latent_rank_ > 0) d_dgamma.noalias() += c.lf * eta;
  }

 private:
  using MatK = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, T::MaxN, T::MaxN>;
  using MatK6 = Eigen::Matrix<double, Eigen::Dynamic, 6, 0, T::MaxN, 6>;
  using MatKC = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, T::MaxN, 6>;
  using MatNK = Eigen::Matrix<double, N, Eigen::Dynamic, 0, T::MaxN, T::MaxN>;
  using VecK = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, T::MaxN, 1>;

  double tau_of(const Vec6& sigma, int a) const { return ph_.schmid.col(a).dot(sigma); }

  // The slip an activated system starts from: the root of its own flow rule at the stress of
  // `p` (the stress the Newton coupling then corrects).
  double activation_slip(int a, const SlipPoint& p) const;

  // F R^T |dgamma|: for each system the slip of the others that hardens it.
  // F times the mixed slips column by column: fixed-size columns, not the general
  // matrix-vector kernel over a dynamic column count (rank 1, the usual latent matrix, is
  // then one scaled column).
  VecN latent_drives(const VecN& dgamma) const;

  // Whether system a's flow rule is within its tolerance or its rounding: G's own terms, a few
  // ulp of the slip, and the rounding the written shear carries, of |tau_trial,a| +
  // sum_b |A_ab dgamma_b| (computed only when the tolerance is not met).
  bool within_floor(const FlowPoint& f, double z, int a, const VecN& dgamma) const;

  // What an evaluation found that changes the active set (the first such system).
  struct RoleChange {
    enum Kind { none, wants_to_slip, turned_against, inadmissible } kind = none;
    int system = -1;
  };

  // Evaluates the flow rules at the slips `dgamma`, or reports an idle system the written
  // stress loads past r_s0 (it wants to slip), an active one whose shear turned against its
  // slip, or a point outside the flow rules' domain (r >= r_hat).
  RoleChange evaluate_slips(const VecN& dgamma, SlipPoint& p) const;

  // evaluate_slips' rows, one system at a time, from the flow points of one SIMD batch
  // (`Batched`, batch_flow_points: one exponential law of the cot function on every system) or
  // of each system's own law (flow_point). The tests that set a system's role are the same for
  // both sources.
  template <bool Batched>
  RoleChange slip_rows(const VecN& dgamma, const VecN& tau, const VecN& latent_drive,
                       SlipPoint& p) const;

  // Whether system a's shear is against its shear at the start of the step: its subloading
  // ratio then restarts from 0 (3.12).
  bool slips_against(int a, const VecN& tau) const { return tau(a) * tau_start_(a) < 0.0; }
  // A system's friction coefficient at zero slip of its own (the latent drive only).
  double idle_friction(int a, double latent) const;
  // z = |ds|^(1/p): the unknown in which a system's flow rule keeps a finite slope at zero slip.
  double slip_root(int a, double dgamma) const;

  // The Newton system of a slip point, condensed to 6 x 6. With K = P diag(d), g = R^T S and
  // lf = diag(l) F, the step delta = w + K^T ds + lf eta solves ds = -C P delta and
  // eta = g delta, that is
  //   S ds = -P (w + lf eta),  (I - g lf) eta - g K^T ds = g w,   S = C^-1 + P K^T.
  // S = C^-1 + P diag(d) P^T is symmetric positive definite (d > 0: each flow rule's slip grows
  // with its shear), so it is factored as L D L^T; the latent unknowns eta (latent_rank of them)
  // are eliminated through
  //   Z = S^-1 P lf,  M = I - g lf + g K^T Z,  eta = M^-1 g (w - K^T S^-1 P w).
  struct Condensed {
    SymmetricFactor6 ldlt;
    // Latent coupling only:
    MatNK lf;
    MatK g;
    Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, T::MaxN> z;
    MatK6 gk;  // g K^T
    Eigen::PartialPivLU<MatK> m;
    double m_scalar = 1.0;  // M when latent_rank == 1

    Vec6 solve_s(const Vec6& rhs) const { return ldlt.solve(rhs); }
    template <typename Rhs>
    auto solve_m(const Rhs& rhs) const {
      constexpr int cols = Rhs::ColsAtCompileTime;
      using Result =
          Eigen::Matrix<double, Eigen::Dynamic, cols, 0, T::MaxN, Rhs::MaxColsAtCompileTime>;
      return rhs.rows() == 1 ? Result(rhs / m_scalar) : Result(m.solve(rhs));
    }
  };
  // K x and K^T y, K = P diag(d) applied without forming it (a 6 x n matrix per Newton step).
  Vec6 k_times(const SlipPoint& p, const VecN& x) const;
  VecN k_transpose_times(const SlipPoint& p, const Vec6& y) const;

  Condensed condense(const SlipPoint& p) const;

  bool slip_step(const SlipPoint& p, VecN& delta) const;

 private:
  // Every system's subloading starts, the batched flow points' law's (cot) in SIMD batches: at
  // its r_s from the start of the step and, for a slip against its start shear, at 0. And the
  // batch's inputs that a solve holds fixed: mu at the start of the step and f_n (tau0: a batch
  // has no plane pressure).
  void set_batched_starts();

  // Every system's flow point at the slips `dgamma` in SIMD batches (one law of closed-form
  // updates, see flow_point_batch.hpp): what flow_point gives system by system, with each
  // system's slip at z = |ds|^(1/2) (the exponent of the exponential form) as evaluate_slips
  // takes it.
  void batch_flow_points(const VecN& dgamma, const VecN& tau, const VecN& latent_drive) const;
  FlowPoint batched_flow_point(int a, double z) const;

  FlowPoint flow_point(int a, double abs_tau, double latent, bool against, double z) const;

  // The scalar flow rule of system a: G decreases from G(0) = r - r_s0 > 0 as the system slips
  // (its shear is held: slip only lowers r - r_s through r_s, hardening and the overstress), so
  // a bracketed Newton iteration in z = ds^(1/p) finds its root; p >= 2 keeps the slope finite
  // where r_s grows like sqrt(ds) from r_s = 0 and where the power overstress has
  // G ~ -ds^(1/n).
  SystemResponse respond(int a, double abs_tau, double latent, bool against, double guess) const;

  const Phase<N>& ph_;
  const GrainState<N>& s0_;
  double dt_;
  int n_;
  Vec6 trial_;
  VecN tau_start_, tau_trial_, stiffness_, warm_z_;
  Flags warm_against_;
  int latent_rank_ = 0, extras_ = 0, max_iterations_ = 0;
  double latent_scale_ = 1.0;
  double stress_scale_ = 0.0, residual_tolerance_ = 0.0, flow_tolerance_ = 0.0, tolerance_ = 0.0;
  std::array<std::array<law::SubloadingFrictionLaw::SubloadingStart, 2>, T::MaxN> starts_;
  std::array<double, T::MaxN> exponent_{};
  bool batched_;  // every system's flow point in SIMD batches (batch_flow_points)
  mutable FlowBatchInput batch_in_;
  mutable FlowBatchOutput batch_out_;
  mutable std::array<double, T::MaxN> batch_z_;  // each system's z = |ds|^(1/2) in the batch
};

}  // namespace implicit_detail

}  // namespace subslip::crystal
