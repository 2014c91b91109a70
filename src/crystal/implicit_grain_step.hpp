// The implicit grain step: backward Euler of one grain over a step, solved in stress space.
//
// Unknowns: the lattice stress sigma (6 numbers), plus, only where the phase needs them, one
// number per slip system (latent hardening: the slip the other systems contribute to its
// hardening; an open slip plane: its slip). For a given stress every slip system's slip
// increment is the root of its own scalar flow rule at its resolved shear tau_a = P_a : sigma
// (and normal traction f_n,a), so the outer residual
//   R(sigma) = sigma - sigma_trial + sum_a C P_a dgamma_a(sigma)
// has a Jacobian I + sum_a C P_a (d dgamma_a / d sigma) whose size does not grow with the slip
// count and which stays regular where the slips themselves are not determined (the Taylor
// ambiguity of FCC and BCC). docs/grain_step.md gives the argument for convergence, its
// assumptions and what happens outside them. It is used where those assumptions hold
// (implicit_grain_step, below); other laws, and steps it does not resolve, go to the semismooth
// step (semismooth_grain_step.cpp). Phases with a latent matrix start with Newton on the slips
// (StressSolver::slip_newton), which carries the latent coupling in its condensed system, and
// go to the semismooth step where that does not converge; only a step that starts from no slip
// at all (the virgin step) goes to the stress-space solve with its latent drives instead.
// Newton on the slips takes over from the stress-space solve at its first iterate from which it
// converges. The stress-space solve's branches for open planes and saturated rate-independent
// systems are kept from its development but are not reached through that choice
// (docs/grain_step.md).
//
// Internal to src/crystal/: the template is instantiated once per slip count, each in its own
// translation unit (implicit_grain_step_<N>.cpp), so that a rebuild compiles them in parallel;
// a portable build compiles those of 12, 24 and 48 systems for AVX2 and AVX-512 too
// (grain_step_isa.hpp).
#pragma once

#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>

#include "grain_step_isa.hpp"
#include "kernel_detail.hpp"
#include "semismooth_grain_step.hpp"
#include "subslip/crystal/flow_point_batch.hpp"
#include "vertex_grain_step.hpp"

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

// The response of one slip system to a resolved shear |tau|, a normal traction f_n and a latent
// slip h (the others' slips that harden it), on one branch: the slip increment ds >= 0 that
// solves its flow rule G(r(ds), r_s(ds), ds) = 0, and its derivatives.
struct SystemResponse {
  double slip = 0.0;         // ds
  double z = 0.0;            // ds^(1/p): the unknown of the scalar root (warm start of the next)
  double mu = 0.0;           // friction coefficient after the step
  double r_s = 0.0;          // subloading ratio after the step
  double d_tau = 0.0;        // d ds / d|tau|
  double d_normal = 0.0;     // d ds / d f_n
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
};

template <int N>
class StressSolver {
 public:
  using T = SlipTypes<N>;
  using VecN = typename T::VecN;
  static constexpr int MaxY = 6 + 2 * T::MaxN;  // sigma, latent drive, open-plane slips
  using VecY = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 2 * T::MaxN, 1>;
  using Flags = Eigen::Matrix<bool, N, 1, 0, T::MaxN, 1>;
  using MatJ = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, MaxY, MaxY>;
  using MatJ6 = Eigen::Matrix<double, Eigen::Dynamic, 6, 0, MaxY, 6>;

  // One point of the outer iteration and everything the Jacobian needs there.
  struct Iterate {
    Vec6 sigma;
    VecY y;  // per system: A_aa h_a (latent) or A_aa dgamma_a (open plane); empty without either
    VecN tau, fn, slip, z, dgamma, mu, r_s, d_tau, d_normal, d_latent, uncertainty;
    Flags against;  // slips against its start shear: r_s restarts from 0 (3.12)
    Vec6 r_sigma;
    VecY r_y;
    double merit = kInf;
    int bad_system = -1;  // the system that made the point inadmissible
    int opening = -1;     // a closed system whose plane is open at this point
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
    extras_ = latent_rank_ + (ph.pressure_sensitive ? n_ : 0);
    latent_scale_ = stiffness_.mean();
    open_.setConstant(n_, false);
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
  // no latent coupling and no plane pressure. The line search then works on Phi, which is C^1
  // where R has kinks (a system starting to slip), so the Newton direction is a descent
  // direction there too.
  bool has_potential() const { return extras_ == 0 && !ph_.pressure_sensitive; }
  // d Phi / d alpha along d_sigma at an iterate: (C^-1 R) . d_sigma.
  double potential_slope(const Iterate& it, const Vec6& d_sigma) const {
    return (ph_.compliance * it.r_sigma).dot(d_sigma);
  }
  double residual_tolerance() const { return residual_tolerance_; }
  double stress_scale() const { return stress_scale_; }
  const Flags& open() const { return open_; }

  // The extra unknowns y: first the latent drive c R^T |dgamma| (latent_rank numbers, R the
  // phase's latent_mix, c a mean elastic stiffness so that its rows are in stress units like
  // sigma's), then, with the pressure-sensitive reading, one per system: A_aa dgamma_a on an
  // open plane, 0 on a closed one.
  VecY extras_for(const VecN& dgamma) const {
    VecY y = VecY::Zero(extras_);
    if (latent_rank_ > 0)
      y.head(latent_rank_).noalias() =
          latent_scale_ * ph_.latent_mix.leftCols(latent_rank_).transpose() * dgamma.cwiseAbs();
    if (ph_.pressure_sensitive)
      for (int a = 0; a < n_; ++a)
        if (open_(a)) y(latent_rank_ + a) = stiffness_(a) * dgamma(a);
    return y;
  }

  // Decides which planes are open (f_n <= 0) at a stress, and the extra unknowns that go with
  // the slips `dgamma`.
  void set_open_planes(const Vec6& sigma, const VecN& dgamma, VecY& y) {
    if (ph_.pressure_sensitive) {
      const VecN fn = normal_traction(ph_, sigma);
      for (int a = 0; a < n_; ++a) open_(a) = !(fn(a) > 0.0);
    }
    y = extras_for(dgamma);
  }
  // Changes one system's role.
  void set_open(int a, bool open, const VecN& dgamma, VecY& y) {
    open_(a) = open;
    y(latent_rank_ + a) = open ? stiffness_(a) * dgamma(a) : 0.0;
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
    it.fn = normal_traction(ph_, sigma);
    for (VecN* v : {&it.slip, &it.z, &it.dgamma, &it.mu, &it.r_s, &it.d_tau, &it.d_normal,
                    &it.d_latent, &it.uncertainty})
      v->setZero(n_);
    it.against.setConstant(n_, false);
    it.merit = kInf;
    it.bad_system = -1;
    it.opening = -1;
    it.scalar_iterations = 0;
    for (int a = 0; a < n_; ++a) {
      if (open_(a)) {
        it.dgamma(a) = y(latent_rank_ + a) / stiffness_(a);
        it.slip(a) = std::abs(it.dgamma(a));
        continue;
      }
      if (!(it.fn(a) > 0.0)) {
        it.bad_system = it.opening = a;
        return;
      }
      const bool against = slips_against(a, it.tau);
      const double latent =
          latent_rank_ > 0 ? ph_.latent_factor.row(a).head(latent_rank_).dot(y.head(latent_rank_)) /
                                 latent_scale_
                           : 0.0;
      const double guess = warm_against_(a) == against ? warm_z_(a) : 0.0;
      const SystemResponse resp = respond(a, std::abs(it.tau(a)), it.fn(a), latent, against, guess);
      it.scalar_iterations += resp.iterations;
      if (!resp.admissible) {
        it.bad_system = a;
        return;
      }
      it.against(a) = against;
      it.slip(a) = resp.slip, it.z(a) = resp.z, it.mu(a) = resp.mu, it.r_s(a) = resp.r_s;
      it.d_tau(a) = resp.d_tau, it.d_normal(a) = resp.d_normal, it.d_latent(a) = resp.d_latent;
      it.uncertainty(a) = resp.uncertainty;
      it.dgamma(a) = sign_of(it.tau(a)) * resp.slip;
    }
    it.r_sigma = sigma - trial_;
    it.r_sigma.noalias() += ph_.c_schmid * it.dgamma;
    it.r_y = y - extras_for(it.dgamma);
    if (ph_.pressure_sensitive)
      for (int a = 0; a < n_; ++a)
        if (open_(a)) it.r_y(latent_rank_ + a) = it.tau(a);
    it.merit = 0.5 * (it.r_sigma.squaredNorm() + it.r_y.squaredNorm());
  }

  // d dgamma_a / d sigma of the closed systems (columns), zero for open ones.
  Eigen::Matrix<double, 6, N, 0, 6, T::MaxN> slip_gradient(const Iterate& it) const {
    Eigen::Matrix<double, 6, N, 0, 6, T::MaxN> w = ph_.schmid * it.d_tau.asDiagonal();
    if (ph_.pressure_sensitive) {
      // f_n = tau0 - M : sigma, and dgamma = sign(tau) ds.
      VecN signed_normal(n_);
      for (int a = 0; a < n_; ++a) signed_normal(a) = sign_of(it.tau(a)) * it.d_normal(a);
      w.noalias() -= ph_.plane_normal_dyad * signed_normal.asDiagonal();
      for (int a = 0; a < n_; ++a)
        if (open_(a)) w.col(a).setZero();
    }
    return w;
  }

  // d dgamma / d y (n x extras).
  using MatNY = Eigen::Matrix<double, N, Eigen::Dynamic, N == 1 ? Eigen::RowMajor : Eigen::ColMajor,
                              T::MaxN, MaxY>;
  MatNY slip_gradient_in_extras(const Iterate& it) const {
    MatNY g = MatNY::Zero(n_, extras_);
    for (int a = 0; a < n_; ++a) {
      if (open_(a)) {
        g(a, latent_rank_ + a) = 1.0 / stiffness_(a);
      } else if (latent_rank_ > 0) {
        g.row(a).head(latent_rank_) = sign_of(it.tau(a)) * it.d_latent(a) / latent_scale_ *
                                      ph_.latent_factor.row(a).head(latent_rank_);
      }
    }
    return g;
  }

  // The 6 x 6 Jacobian (no extra unknowns).
  Mat6 stress_jacobian(const Iterate& it) const {
    Mat6 j = Mat6::Identity();
    j.noalias() += ph_.c_schmid.lazyProduct(slip_gradient(it).transpose());
    return j;
  }

  // The full Jacobian with the extra unknowns: rows R_sigma, then R_y = y - extras_for(dgamma)
  // (an open plane's row: its shear).
  MatJ full_jacobian(const Iterate& it) const {
    const int m = 6 + extras_;
    MatJ j = MatJ::Zero(m, m);
    const auto w = slip_gradient(it);
    const auto g = slip_gradient_in_extras(it);
    j.topLeftCorner(6, 6) = stress_jacobian(it);
    j.topRightCorner(6, extras_).noalias() = ph_.c_schmid * g;
    j.bottomRightCorner(extras_, extras_).setIdentity();
    if (latent_rank_ > 0) {
      // d(c R^T |dgamma|) = c R^T S (W^T d sigma + G d y), S = sign(tau) (0 on open planes,
      // whose |dgamma| changes with y only).
      VecN sign(n_);
      for (int a = 0; a < n_; ++a) sign(a) = open_(a) ? sign_of(it.dgamma(a)) : sign_of(it.tau(a));
      const Eigen::Matrix<double, Eigen::Dynamic, N, 0, MaxY, T::MaxN> rs =
          latent_scale_ * ph_.latent_mix.leftCols(latent_rank_).transpose() * sign.asDiagonal();
      j.block(6, 0, latent_rank_, 6).noalias() -= rs * w.transpose();
      j.block(6, 6, latent_rank_, extras_).noalias() -= rs * g;
    }
    for (int a = 0; a < n_; ++a) {
      if (!open_(a)) continue;
      const int row = 6 + latent_rank_ + a;
      j.row(row).setZero();
      j.block(row, 0, 1, 6) = ph_.schmid.col(a).transpose();
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
  // of role changes). An open plane or a stress outside the flow rule's domain ends it too.
  struct SlipPoint {
    Vec6 sigma;
    VecN dgamma, mu, r_s;
    // The Newton linearization: the change of dgamma_a for a stress change ds and latent-drive
    // change eta = R^T S d|dgamma| is w_a + d_a P_a:ds - e_a M_a:ds + l_a F_a.eta.
    VecN w, d, e, l, sign;
    // Saturated systems (see is_saturated): their flow rule is a yield condition on the stress,
    // linearised as sign_a P_a:ds + yield_normal_a M_a:ds = yield_rhs_a; their slip change is
    // an unknown of its own.
    Flags saturated;
    VecN yield_normal, yield_rhs;
    double worst = kInf;           // largest |G_a| (an idle system: r - r_s0 where positive)
    double slip_resolution = 0.0;  // the rounding of the largest slip
    bool converged = false;
  };

  bool can_refine() const { return !open_.any(); }

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
    if (p.saturated.any()) {
      const int m = static_cast<int>(p.saturated.count());
      MatDQ rhs = MatDQ::Zero(6 + latent_rank_ + m, cols);
      rhs.topRows(6) = latent_scale_ * e;
      const MatDQ x = saturated_solve(p, c, rhs);
      d_sigma = x.topRows(6);
      d_dgamma.resize(n_, cols);
      for (int col = 0; col < cols; ++col)
        d_dgamma.col(col) = saturated_slips(p, c, x, col, VecN::Zero(n_));
      return;
    }
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
      d_dgamma.col(col) = k_transpose_times(p, c, Vec6(d_sigma.col(col)));
    if (latent_rank_ > 0) d_dgamma.noalias() += c.lf * eta;
  }

 private:
  using MatK = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, T::MaxN, T::MaxN>;
  using MatK6 =
      Eigen::Matrix<double, Eigen::Dynamic, 6, T::MaxN == 1 ? Eigen::RowMajor : 0, T::MaxN, 6>;
  using MatKC = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic,
                              T::MaxN == 1 ? Eigen::RowMajor : 0, T::MaxN, 6>;
  using MatNK = Eigen::Matrix<double, N, Eigen::Dynamic, 0, T::MaxN, T::MaxN>;
  using VecK = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, T::MaxN, 1>;

  double tau_of(const Vec6& sigma, int a) const { return ph_.schmid.col(a).dot(sigma); }

  // The slip an activated system starts from: the root of its own flow rule at the stress of
  // `p` (the stress the Newton coupling then corrects).
  double activation_slip(int a, const SlipPoint& p) const {
    const double tau = tau_of(p.sigma, a);
    const VecN fn = normal_traction(ph_, p.sigma);
    const bool against = tau * tau_start_(a) < 0.0;
    const SystemResponse resp =
        respond(a, std::abs(tau), fn(a), latent_drives(p.dgamma)(a), against, 0.0);
    return resp.admissible ? resp.slip : 0.0;
  }

  // F R^T |dgamma|: for each system the slip of the others that hardens it.
  // F times the mixed slips column by column: fixed-size columns, not the general
  // matrix-vector kernel over a dynamic column count (rank 1, the usual latent matrix, is
  // then one scaled column).
  VecN latent_drives(const VecN& dgamma) const {
    if (latent_rank_ == 0) return VecN::Zero(n_);
    const VecK mixed = ph_.latent_mix.leftCols(latent_rank_).transpose() * dgamma.cwiseAbs();
    VecN drive = VecN::Zero(n_);
    for (int j = 0; j < latent_rank_; ++j) drive += ph_.latent_factor.col(j) * mixed(j);
    return drive;
  }

  // G's own rounding (its terms are O(1) ratios) and a few ulp of the slip.
  // Whether system a's flow rule is within its tolerance or its rounding: G's own terms, a few
  // ulp of the slip, and the rounding the written shear carries, of |tau_trial,a| +
  // sum_b |A_ab dgamma_b| (computed only when the tolerance is not met).
  bool within_floor(const FlowPoint& f, double z, int a, const VecN& dgamma, double fn) const {
    if (std::abs(f.g) <= tolerance_) return true;
    const double shear_size = std::abs(tau_trial_(a)) +
                              ph_.interaction.row(a).cwiseAbs().dot(dgamma.cwiseAbs().transpose());
    return std::abs(f.g) <=
           4.0 * kEps *
               (1.0 + f.r + std::abs(f.g_z) * z + std::abs(f.g_dr) * shear_size / (f.mu * fn));
  }

  // A rate-independent system whose flow rule no longer depends on its own slip to the
  // resolution of the elastic coupling: its slip response to its shear, d = g_dr / (mu f_n
  // |dG/ds|), exceeds the elastic compliance of its own slip, 1/A_aa, by 1/eps (r_s = 1 to
  // round-off, with mu at its limit or held). Its slip is then fixed by the others and the
  // elastic coupling alone, as in rate-independent perfect plasticity, and its flow rule
  // G = r - r_s = 0 is a yield condition on the stress.
  bool is_saturated(int a, const FlowPoint& f, double fn) const {
    if (!ph_.laws[static_cast<size_t>(a)].is_rate_independent() || !std::isfinite(f.g_s) ||
        f.g_s > 0.0)
      return false;
    return -f.g_s * f.mu * fn <= kEps * f.g_dr * stiffness_(a);
  }

  // What an evaluation found that changes the active set (the first such system).
  struct RoleChange {
    enum Kind { none, wants_to_slip, turned_against, inadmissible } kind = none;
    int system = -1;
  };

  // Evaluates the flow rules at the slips `dgamma`, or reports an idle system the written
  // stress loads past r_s0 (it wants to slip), an active one whose shear turned against its
  // slip, or a point outside the flow rules' domain (an open plane, r >= r_hat).
  RoleChange evaluate_slips(const VecN& dgamma, SlipPoint& p) const {
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

  // evaluate_slips' rows, one system at a time, from the flow points of one SIMD batch
  // (`Batched`, batch_flow_points: one exponential law of the cot function on every system and
  // no plane pressure, so no saturated system) or of each system's own law (flow_point). The
  // tests that set a system's role are the same for both sources.
  template <bool Batched>
  RoleChange slip_rows(const VecN& dgamma, const VecN& tau, const VecN& fn,
                       const VecN& latent_drive, SlipPoint& p) const {
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
      const FlowPoint f = Batched ? FlowPoint{.g = batch_out_.g[i],
                                              .g_s = batch_out_.g_slip[i],
                                              .mu = batch_out_.mu[i],
                                              .r_s = batch_out_.r_s[i]}
                                  : flow_point(a, std::abs(tau(a)), fn(a), latent_drive(a),
                                               slips_against(a, tau), z);
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
      p.converged = p.converged &&
                    (std::abs(f.g) <= tolerance_ ||
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

  // The row of a saturated system (is_saturated): slipping, or loaded past r = r_s0 = 1 at zero
  // slip (the slip is then ready to grow), with a flow rule that no longer depends on its own
  // slip: a yield condition on the stress.
  void saturated_row(int a, const FlowPoint& f, double z, const VecN& dgamma, const VecN& tau,
                     const VecN& fn, SlipPoint& p) const {
    p.saturated(a) = true;
    p.sign(a) = dgamma(a) != 0.0 ? sign_of(dgamma(a)) : sign_of(tau(a));
    p.mu(a) = f.mu, p.r_s(a) = f.r_s;
    p.worst = std::max(p.worst, std::abs(f.g));
    p.converged = p.converged && within_floor(f, z, a, dgamma, fn(a));
    // dG = g_dr (dr/d|tau| s P_a:ds - r/f_n df_n), df_n = -M_a:ds; scaled by mu f_n/g_dr.
    p.yield_normal(a) = ph_.pressure_sensitive ? f.r * f.mu : 0.0;
    p.yield_rhs(a) = -f.g * f.mu * fn(a) / f.g_dr;
  }

  // Whether system a's shear is against its shear at the start of the step: its subloading
  // ratio then restarts from 0 (3.12).
  bool slips_against(int a, const VecN& tau) const { return tau(a) * tau_start_(a) < 0.0; }
  // A system's friction coefficient at zero slip of its own (the latent drive only).
  double idle_friction(int a, double latent) const {
    return ph_.laws[static_cast<size_t>(a)]
        .friction_coefficient_after(s0_.mu(a), latent, dt_)
        .value;
  }
  // z = |ds|^(1/p): the unknown in which a system's flow rule keeps a finite slope at zero slip.
  double slip_root(int a, double dgamma) const {
    const double p_exp = exponent_[static_cast<size_t>(a)];
    const double slip = std::abs(dgamma);
    return p_exp == 2.0 ? std::sqrt(slip) : std::pow(slip, 1.0 / p_exp);
  }

  // The Newton system of a slip point, condensed to 6 x 6. With K = P diag(d) - M diag(e)
  // (M only with the pressure-sensitive reading), g = R^T S and lf = diag(l) F, the step
  // delta = w + K^T ds + lf eta solves ds = -C P delta and eta = g delta, that is
  //   S ds = -P (w + lf eta),  (I - g lf) eta - g K^T ds = g w,   S = C^-1 + P K^T.
  // Without plane pressure S = C^-1 + P diag(d) P^T is symmetric positive definite (d > 0:
  // each flow rule's slip grows with its shear), so it is factored as L D L^T; the latent
  // unknowns eta (latent_rank of them) are eliminated through
  //   Z = S^-1 P lf,  M = I - g lf + g K^T Z,  eta = M^-1 g (w - K^T S^-1 P w).
  struct Condensed {
    // K, formed only with plane pressure: without it K = P diag(d) is applied as such (k_times,
    // k_transpose_times), which saves forming a 6 x n matrix per Newton step.
    Eigen::Matrix<double, 6, N, 0, 6, T::MaxN> k;
    SymmetricFactor6 ldlt;
    Eigen::PartialPivLU<Mat6> lu;
    bool symmetric = true;
    // Latent coupling only:
    MatNK lf;
    MatK g;
    Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, T::MaxN> z;
    MatK6 gk;  // g K^T
    Eigen::PartialPivLU<MatK> m;
    double m_scalar = 1.0;  // M when latent_rank == 1

    Vec6 solve_s(const Vec6& rhs) const {
      return symmetric ? ldlt.solve(rhs) : Vec6(lu.solve(rhs));
    }
    template <typename Rhs>
    auto solve_m(const Rhs& rhs) const {
      constexpr int cols = Rhs::ColsAtCompileTime;
      using Result = Eigen::Matrix<double, Eigen::Dynamic, cols,
                                   (T::MaxN == 1 && cols != 1) ? Eigen::RowMajor : Eigen::ColMajor,
                                   T::MaxN, Rhs::MaxColsAtCompileTime>;
      return rhs.rows() == 1 ? Result(rhs / m_scalar) : Result(m.solve(rhs));
    }
  };
  // K x and K^T y: without plane pressure K = P diag(d), applied without forming it.
  Vec6 k_times(const SlipPoint& p, const Condensed& c, const VecN& x) const {
    return c.symmetric ? Vec6(ph_.schmid * p.d.cwiseProduct(x)) : Vec6(c.k * x);
  }
  VecN k_transpose_times(const SlipPoint& p, const Condensed& c, const Vec6& y) const {
    return c.symmetric ? VecN(p.d.cwiseProduct(ph_.schmid.transpose() * y))
                       : VecN(c.k.transpose() * y);
  }

  Condensed condense(const SlipPoint& p) const {
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

  // The Newton system of a slip point with saturated systems, whose slip changes x_S are
  // unknowns and whose rows are their linearised yield conditions, for the right-hand sides
  // `rhs` (rows: c (de - P w), g w, yield_rhs_S; c a mean stiffness so the unknowns
  // (ds, eta, c x_S) and the rows are of one scale). Where the saturated systems' yield
  // normals are linearly dependent (more than five of them, as in rate-independent Taylor
  // plasticity) their slips are not determined: the complete orthogonal decomposition gives the
  // solution of least norm, whose stress is the unique one.
  using MatD = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, MaxY, MaxY>;
  using MatDQ = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, MaxY, 6>;
  MatDQ saturated_solve(const SlipPoint& p, const Condensed& c, const MatDQ& rhs) const {
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

  // The change of every slip from a solution of saturated_solve (one column).
  VecN saturated_slips(const SlipPoint& p, const Condensed& c, const MatDQ& x, int col,
                       const VecN& w) const {
    const int k = latent_rank_;
    VecN delta = w + k_transpose_times(p, c, Vec6(x.block(0, col, 6, 1)));
    if (k > 0) delta.noalias() += c.lf * x.block(6, col, k, 1);
    for (int a = 0, j = 6 + k; a < n_; ++a)
      if (p.saturated(a)) delta(a) = x(j++, col) / latent_scale_;
    return delta;
  }

  bool slip_step(const SlipPoint& p, VecN& delta) const {
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

 private:
  // Every system's subloading starts, the batched flow points' law's (cot) in SIMD batches: at
  // its r_s from the start of the step and, for a slip against its start shear, at 0. And the
  // batch's inputs that a solve holds fixed: mu at the start of the step and f_n (tau0: a batch
  // has no plane pressure).
  void set_batched_starts() {
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

  // Every system's flow point at the slips `dgamma` in SIMD batches (one law of closed-form
  // updates, see flow_point_batch.hpp): what flow_point gives system by system, with each
  // system's slip at z = |ds|^(1/2) (the exponent of the exponential form) as evaluate_slips
  // takes it.
  void batch_flow_points(const VecN& dgamma, const VecN& tau, const VecN& latent_drive) const {
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
  FlowPoint batched_flow_point(int a, double z) const {
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

  FlowPoint flow_point(int a, double abs_tau, double fn, double latent, bool against,
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
    const double r = abs_tau / (mu.value * fn);
    const auto g = law.flow_residual(r, rs.value, slip, dt_);
    if (!g.admissible || !(mu.value > 0.0))
      return {kInf, 0.0, 0.0, 0.0, r, 0.0, mu.value, rs.value};
    const double dr_dslip = -r / mu.value * mu.d_slip * q;
    const double g_slip = g.d_r * dr_dslip + g.d_rs * rs.d_slip + g.d_slip;
    return {g.value, slip > 0.0 ? g_slip * dslip_dz : 0.0, g_slip, g.d_r, r, mu.d_slip, mu.value,
            rs.value};
  }

  // The scalar flow rule of system a: G decreases from G(0) = r - r_s0 > 0 as the system slips
  // (its shear is held: slip only lowers r - r_s through r_s, hardening and the overstress), so
  // a bracketed Newton iteration in z = ds^(1/p) finds its root; p >= 2 keeps the slope finite
  // where r_s grows like sqrt(ds) from r_s = 0 and where the power overstress has
  // G ~ -ds^(1/n).
  SystemResponse respond(int a, double abs_tau, double fn, double latent, bool against,
                         double guess) const {
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

  const Phase<N>& ph_;
  const GrainState<N>& s0_;
  double dt_;
  int n_;
  Vec6 trial_;
  VecN tau_start_, tau_trial_, stiffness_, warm_z_;
  Flags open_, warm_against_;
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

using namespace implicit_detail;

// The stress-space solve (see the file comment and docs/grain_step.md): Newton on sigma (and
// the extra unknowns) with each system's slip from its own flow rule, globalised by a line
// search on the convex potential. Returns whether it converged; `it` is its last iterate.
// `local(it)` is offered every iterate the line search accepts: where it returns true (it has
// solved the step from there, see solve_grain_step), the solve ends there, successfully.
template <int N, class Local>
bool stress_space_solve(StressSolver<N>& solver, const Phase<N>& ph, const GrainState<N>& s0,
                        const Vec6& trial, const typename SlipTypes<N>::VecN& previous_slip,
                        const GrainStepOptions& opt, typename StressSolver<N>::Iterate& it,
                        GrainStepReport& rep, Local&& local) {
  using VecY = typename StressSolver<N>::VecY;
  const int n = ph.slip_count;
  Vec6 predicted = trial;
  predicted.noalias() -= ph.c_schmid * previous_slip;
  typename StressSolver<N>::Iterate trial_point;
  // Starts: the last step's slip rate continued, the elastic trial and the start stress; the
  // iteration begins from the one with the smallest residual (a nearly rate-independent law can
  // put the trial just inside the domain with slips of 1e8, and the start stress is always
  // inside it).
  VecY y = solver.extras_for(previous_slip);
  solver.set_open_planes(predicted, previous_slip, y);
  solver.evaluate(predicted, y, it);
  if (!(std::sqrt(2.0 * it.merit) <= solver.residual_tolerance())) {
    for (const Vec6* start : {&trial, &s0.stress}) {
      if (*start == predicted) continue;  // (no slip in the last step: the trial itself)
      VecY y_start = y;
      solver.set_open_planes(*start, previous_slip, y_start);
      solver.evaluate(*start, y_start, trial_point);
      if (trial_point.merit < it.merit) std::swap(it, trial_point);
    }
  }
  // The plane roles of the chosen start, with the extra unknowns consistent with its slips
  // (without plane pressure or a latent matrix there are none, and the start stands as
  // evaluated).
  if (solver.extras() > 0) {
    solver.set_open_planes(it.sigma, it.dgamma, it.y);
    solver.evaluate(it.sigma, it.y, it);
  }
  if (!std::isfinite(it.merit)) {
    rep.why = "no admissible start (r >= r_hat or slip plane open)";
    rep.system = it.bad_system;
    return false;
  }
  solver.remember(it);

  // Newton on sigma (and the extras) with a backtracking line search on 1/2 |R|^2. Open planes
  // are an active set: a closed plane that the iteration wants to open, or an open plane closed
  // at the solution, changes role and the iteration goes on (at most once per system and way).
  bool converged = false;
  bool at_floor = false;  // the line search found no decrease within the residual's floor
  int role_changes = 0;
  for (int iterations = 0; iterations < opt.max_iterations;) {
    const double residual = std::max(it.r_sigma.cwiseAbs().maxCoeff(),
                                     it.r_y.size() ? it.r_y.cwiseAbs().maxCoeff() : 0.0);
    Vec6 d_sigma;
    VecY d_y;
    const bool have_step = solver.newton_correction(it, d_sigma, d_y);
    // Converged when the residual is within tolerance, or when the correction no longer changes
    // the stress in floating point (the scalar roots' rounding sets the residual's floor).
    const bool stagnant =
        have_step && d_sigma.cwiseAbs().maxCoeff() <= 4.0 * kEps * solver.stress_scale() &&
        (d_y.size() == 0 || d_y.cwiseAbs().maxCoeff() <= 4.0 * kEps * solver.stress_scale());
    // Where slip_newton() resolves the slips afterwards, R at its floor is as good as it gets.
    const bool floor_reached =
        at_floor || (solver.can_refine() && residual <= solver.residual_floor(it));
    if (residual <= solver.residual_tolerance() || stagnant || floor_reached) {
      // An open plane closed at the solution is solved again as closed.
      int closes = -1;
      for (int a = 0; a < n && closes < 0; ++a)
        if (solver.open()(a) && it.fn(a) > 0.0) closes = a;
      if (closes < 0 || role_changes > 2 * n) {
        converged = closes < 0;
        break;
      }
      ++role_changes;
      solver.set_open(closes, false, it.dgamma, it.y);
      at_floor = false;
      solver.evaluate(it.sigma, it.y, it);
      if (!std::isfinite(it.merit)) break;
      continue;
    }
    if (!have_step) break;
    ++iterations;
    ++rep.iterations;
    double alpha = 1.0;
    bool accepted = false;
    // Sufficient decrease (Armijo, c = 1e-4): of Phi where R has a potential, judged from its
    // slopes by the trapezoidal rule, Phi(alpha) - Phi(0) ~ alpha (s(0) + s(alpha)) / 2, exact for
    // a quadratic Phi, so a full Newton step is taken near the solution; of 1/2 |R|^2 otherwise.
    const bool on_potential = solver.has_potential();
    const double slope0 = on_potential ? solver.potential_slope(it, d_sigma) : 0.0;
    int opening = -1;
    const double step_size = d_sigma.cwiseAbs().maxCoeff();
    const double stress_size = it.sigma.cwiseAbs().maxCoeff();
    // Halving until the step no longer moves the stress in floating point.
    for (; !accepted && alpha * step_size > kEps * stress_size; alpha *= 0.5) {
      solver.evaluate(it.sigma + alpha * d_sigma, it.y + alpha * d_y, trial_point);
      if (opening < 0) opening = trial_point.opening;
      accepted = on_potential
                     ? std::isfinite(trial_point.merit) &&
                           solver.potential_slope(trial_point, d_sigma) <= -(1.0 - 2e-4) * slope0
                     : trial_point.merit <= (1.0 - 2e-4 * alpha) * it.merit;
      if (accepted) break;
    }
    if (!accepted && opening < 0 && residual <= solver.residual_floor(it)) {
      // R is at the resolution of the scalar roots: no stress does better (slip_newton() below
      // resolves the slips).
      at_floor = true;
      continue;
    }
    if (!accepted) {
      // A plane the Newton step opens becomes an open plane (its slip an unknown).
      if (opening < 0 || role_changes > 2 * n) break;
      ++role_changes;
      solver.set_open(opening, true, it.dgamma, it.y);
      solver.evaluate(it.sigma, it.y, it);
      if (!std::isfinite(it.merit)) break;
      continue;
    }
    std::swap(it, trial_point);
    solver.remember(it);
    if (local(it)) return true;
  }
  if (!converged) {
    rep.why = "stress iteration did not converge";
    rep.system = it.bad_system;
    if (rep.system < 0 && n > 0) it.slip.maxCoeff(&rep.system);
    return false;
  }
  return true;
}

// Whether every system's resistance grows with slip under an overstress form, from s0: kappa > 0
// with mu_s <= mu_k and mu < mu_k (slip drives mu towards mu_k, recovery towards mu_s); the
// rate-independent form's slip response is unbounded at r_s = 1. Newton on the slips needs this
// (its slopes are then bounded away from zero), and so does the stress-space solve.
template <int N>
bool resistance_grows_with_slip(const Phase<N>& ph, const GrainState<N>& s0) {
  for (int a = 0; a < ph.slip_count; ++a) {
    const auto& law = ph.laws[static_cast<size_t>(a)];
    const auto& f = law.parameters().friction;
    if (law.is_rate_independent() || !(f.kappa > 0.0) || f.mu_s > f.mu_k || !(s0.mu(a) < f.mu_k))
      return false;
  }
  return true;
}

// The grain step (implicit_grain_step, below), compiled for the instruction set of the
// translation unit that instantiates it.
template <int N>
GrainStepReport solve_grain_step(const Phase<N>& ph, const GrainState<N>& s0, const Mat3& L,
                                 double dt, const GrainStepOptions& opt, GrainState<N>& s1,
                                 Tangent* tangent, const typename SlipTypes<N>::VecN* start_rate,
                                 SlipTangent<N>* slip_tangent) {
  using Solver = StressSolver<N>;
  using VecN = typename SlipTypes<N>::VecN;
  using Iterate = typename Solver::Iterate;
  // The rate-independent form without hardening of mu: the step on the yield polytope
  // (vertex_grain_step.hpp), the semismooth step where that does not converge.
  if (vertex_step_applies(ph)) {
    GrainStepReport r = vertex_grain_step(ph, s0, L, dt, opt, s1, tangent, slip_tangent);
    if (r.ok) return r;
    const int spent = r.iterations;
    r = semismooth_grain_step(ph, s0, L, dt, opt, s1, tangent, start_rate, slip_tangent);
    r.iterations += spent;
    return r;
  }
  // Newton on the slips from the last rates needs a growing resistance and no plane pressure; a
  // latent matrix only adds its rank to the condensed system. The stress-space solve after it
  // needs, besides those two, no latent matrix: its argument (docs/grain_step.md) is that
  // R(sigma) = C grad Phi with Phi strictly convex, and a latent coupling leaves R no potential.
  if (ph.pressure_sensitive || !resistance_grows_with_slip(ph, s0))
    return semismooth_grain_step(ph, s0, L, dt, opt, s1, tangent, start_rate, slip_tangent);
  const int n = ph.slip_count;
  const VecN previous_slip = (start_rate != nullptr ? *start_rate : s0.rate) * dt;
  // With a latent matrix the stress-space solve (with its latent-drive unknowns, Newton on
  // 1/2 |R|^2) takes the steps that start from no slip at all (the virgin step, an elastic
  // unloading), where Newton on the slips cannot start (dr_s/d slip is infinite at r_s = 0)
  // and the semismooth step would start from a Jacobi sweep of scalar roots.
  const bool stress_space = !ph.has_latent || (previous_slip.array() == 0.0).all();
  GrainStepReport rep;
  const StepKinematics kin = step_kinematics(s0.orientation, L, dt, ph.kinematics);
  const Vec6 trial = s0.stress + ph.stiffness * kin.strain_increment;
  Solver solver(ph, s0, trial, dt, opt);

  // The semismooth step takes over a step this one does not end on resolved slips (its
  // iterations count in the report).
  auto semismooth = [&] {
    const int spent = rep.iterations;
    GrainStepReport r =
        semismooth_grain_step(ph, s0, L, dt, opt, s1, tangent, start_rate, slip_tangent);
    r.iterations += spent;
    return r;
  };

  // Most steps of a loading path: Newton on the slips from the last step's slip rate continued
  // converges from there. Where it does not (the first step, a change of the active set, a
  // large step), the stress-space solve, then Newton on the slips from its result.
  typename Solver::SlipPoint point;
  rep.iterations = 0;
  if (!(solver.slip_newton(previous_slip, VecN::Zero(n), point, rep.iterations, false) &&
        point.converged)) {
    Iterate it;
    // Newton on the slips takes over from the stress iteration at the first iterate from which
    // it converges (its own test: every full step halves the largest flow-rule residual, else
    // it stops at once): each of its evaluations is one batch of flow points, where each of the
    // stress iteration's is a scalar root per system.
    bool handed_over = false;
    auto hand_over = [&](const Iterate& at) {
      handed_over = solver.can_refine() &&
                    solver.slip_newton(solver.corrected_slips(at), VecN::Zero(n), point,
                                       rep.iterations, false) &&
                    point.converged;
      return handed_over;
    };
    // Near ideal plasticity (r -> r_hat with the hardening spent) the slip response to the
    // stress is unbounded in double precision and the stress iteration can stall; the
    // semismooth iteration on the slips, which is well posed there, takes the step.
    if (!stress_space ||
        !stress_space_solve(solver, ph, s0, trial, previous_slip, opt, it, rep, hand_over))
      return semismooth();
    // The stress iterate fixes each slip only to |dG/d ds|^-1 times G's rounding, coarse where
    // the law is nearly rate-independent; a step ending there would make the grain's response
    // jump between neighbouring loadings. So the slips are resolved from it, or the semismooth
    // iteration resolves them.
    if (!handed_over && !(solver.can_refine() &&
                          solver.slip_newton(solver.corrected_slips(it), VecN::Zero(n), point,
                                             rep.iterations, true) &&
                          point.converged))
      return semismooth();
  }

  // The end state: the converged slip point (see StressSolver::slip_newton).
  const VecN& dgamma = point.dgamma;
  s1.stress = point.sigma;
  s1.slip = s0.slip + dgamma;
  s1.rate = dgamma / dt;
  s1.mu = point.mu;
  const VecN fn1 = normal_traction(ph, s1.stress);  // tau0 exactly: no plane pressure here
  // r through the kernel's own definition (crystal_kernel.cpp), not inline: whatever instruction
  // set this step is compiled for (grain_step_isa.hpp), every later reading of the state then
  // finds r_s <= r to the bit.
  const VecN r1 = loading_ratio(ph, s1);
  // (3.12): r_s follows r down where no slip occurs.
  s1.r_s = point.r_s.cwiseMin(r1);
  s1.orientation = orientation_after_plastic_spin(ph, kin.spun_orientation, dgamma);
  // A flow rule converged to its tolerance, or to its rounding (StressSolver::within_floor).
  const double flow_tolerance =
      std::max(opt.tolerance, 16.0 * std::numeric_limits<double>::epsilon());
  if (!admissible_state(ph, s1, r1, fn1, rep, OpenPlanes::resolved, flow_tolerance)) return rep;

  if (tangent) {
    Tangent d_sigma;
    SlipTangent<N> d_dgamma;
    solver.slip_sensitivities(
        point, lattice_directions(opt.tangent_directions, kin.mid_orientation), d_sigma, d_dgamma);
    *tangent = sample_tangent(ph, s1, d_sigma, d_dgamma);
    if (slip_tangent) *slip_tangent = d_dgamma;
  }
  rep.ok = true;
  return rep;
}

#ifdef SUBSLIP_GRAIN_STEP_ISA
// This translation unit compiled for AVX2 or AVX-512 (grain_step_isa.hpp): the step under its
// own name, isa_avx2:: or isa_avx512::implicit_grain_step<N>.
namespace SUBSLIP_GRAIN_STEP_ISA {
template <int N>
GrainStepReport implicit_grain_step(const Phase<N>& ph, const GrainState<N>& s0, const Mat3& L,
                                    double dt, const GrainStepOptions& opt, GrainState<N>& s1,
                                    Tangent* tangent, const typename SlipTypes<N>::VecN* start_rate,
                                    SlipTangent<N>* slip_tangent) {
  return solve_grain_step(ph, s0, L, dt, opt, s1, tangent, start_rate, slip_tangent);
}
}  // namespace SUBSLIP_GRAIN_STEP_ISA
#else
// The step of the build's own instruction set; for the slip counts compiled for wider ones too,
// the one wide step of a host build, or the widest the machine runs and the run allows (the flow
// batches' level: one choice for both, which MPI ranks agree on) where the portable step is
// compiled beside them (grain_step_isa.hpp).
template <int N>
GrainStepReport implicit_grain_step(const Phase<N>& ph, const GrainState<N>& s0, const Mat3& L,
                                    double dt, const GrainStepOptions& opt, GrainState<N>& s1,
                                    Tangent* tangent, const typename SlipTypes<N>::VecN* start_rate,
                                    SlipTangent<N>* slip_tangent) {
#if SUBSLIP_GRAIN_STEP_ISAS  // (the wide steps are declared only in builds that have them)
  if constexpr (has_isa_grain_steps(N)) {
#if !SUBSLIP_GRAIN_STEP_PORTABLE && SUBSLIP_GRAIN_STEP_AVX512
    return isa_avx512::implicit_grain_step(ph, s0, L, dt, opt, s1, tangent, start_rate,
                                           slip_tangent);
#elif !SUBSLIP_GRAIN_STEP_PORTABLE
    return isa_avx2::implicit_grain_step(ph, s0, L, dt, opt, s1, tangent, start_rate,
                                         slip_tangent);
#else
    switch (detail::flow_batch_level()) {
      case 2:
        return isa_avx512::implicit_grain_step(ph, s0, L, dt, opt, s1, tangent, start_rate,
                                               slip_tangent);
      case 1:
        return isa_avx2::implicit_grain_step(ph, s0, L, dt, opt, s1, tangent, start_rate,
                                             slip_tangent);
      default:
        return solve_grain_step(ph, s0, L, dt, opt, s1, tangent, start_rate, slip_tangent);
    }
#endif
  } else {
    return solve_grain_step(ph, s0, L, dt, opt, s1, tangent, start_rate, slip_tangent);
  }
#else
  return solve_grain_step(ph, s0, L, dt, opt, s1, tangent, start_rate, slip_tangent);
#endif
}
#endif

}  // namespace subslip::crystal
