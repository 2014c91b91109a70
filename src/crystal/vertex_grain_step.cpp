// The rate-independent grain step on the yield polytope (see vertex_grain_step.hpp).
#include "vertex_grain_step.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "kernel_detail.hpp"

namespace subslip::crystal::detail {

namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();
constexpr double kInf = std::numeric_limits<double>::infinity();

// The active faces of a quadratic subproblem: at most one per held system (the side of its start
// shear). With hardening (h > 0) more faces than the six stress components can be
// active: the slips are then fixed by the hardening, not by the stress alone. One capacity for
// every slip count: the algorithms below are compiled once, not once per size of grain step (at
// seven sizes they were the longest compilation of the project).
constexpr int kMaxFaces = kMaxSlipSystems;
using Mat6F = Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, kMaxFaces>;
using MatFF = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxFaces, kMaxFaces>;
using VecF = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxFaces, 1>;

// The solution of one quadratic subproblem: the step x and the active faces with their
// multipliers (the slip magnitudes of their systems).
struct QpSolution {
  Vec6 x;
  std::array<int, kMaxFaces> face{};
  std::array<double, kMaxFaces> multiplier{};
  int count = 0;
};

// A face whose normal makes an angle below ~1e-7 rad with the span of the active normals (the
// squared sine of the angle, in the metric of G^-1, below 64 eps) lies in that span to the
// rounding of the projection: it cannot enter the active set without a face leaving it.
constexpr double kDependentNormal = 64.0 * kEps;

// min 1/2 x^T G x + g^T x over x and multipliers u >= 0 subject to n_f^T x - h_f u_f <= b_f
// (f < faces; h_f >= 0 the face's hardening: its limit rises with its own multiplier), by the
// dual active-set method of Goldfarb and Idnani (Math. Programming 27:1-33, 1983), extended by
// the diagonal h. From the unconstrained minimum it adds the most violated face, moving x and the
// multipliers together so that the stationarity G x + g + sum_f u_f n_f = 0 and the active faces'
// equalities hold throughout and u stays >= 0 (an active face whose multiplier would turn
// negative leaves first). Each added face raises the dual objective, so no active set repeats
// and the method ends after finitely many changes; a face whose normal lies in the span of the
// active ones (a vertex with more yielding systems than independent Schmid tensors) enters only
// after a face left. Violations up to `slack(f)` count as met. Returns false where rounding made
// it exceed its bound on changes, or where the faces admit no point (which the stress zero rules
// out, but rounding could fake).
bool solve_qp(const Mat6& g_inverse, const Vec6& g, const Mat6F& normals, const VecF& b,
              const VecF& h, const VecF& slack, QpSolution& out) {
  const int faces = static_cast<int>(normals.cols());
  out.x = -g_inverse * g;
  out.count = 0;
  const int max_changes = 8 * faces + 8;
  int changes = 0;
  auto is_active = [&](int f) {
    return std::find(out.face.begin(), out.face.begin() + out.count, f) !=
           out.face.begin() + out.count;
  };
  for (;;) {
    int p = -1;
    double worst = 0.0;
    for (int f = 0; f < faces; ++f) {
      const double violation = normals.col(f).dot(out.x) - b(f);
      if (violation > slack(f) && violation > worst && !is_active(f)) worst = violation, p = f;
    }
    if (p < 0) return true;
    const Vec6 np = normals.col(p);
    double up = 0.0;
    for (;;) {
      if (++changes > max_changes) return false;
      const int q = out.count;
      const Vec6 w = g_inverse * np;
      Vec6 hn = w;  // H n_p: n_p's part outside the span of the active normals (metric G^-1)
      VecF r(q);    // how the active multipliers change per unit of u_p
      if (q > 0) {
        Mat6F active(6, q);
        MatFF gram(q, q);
        for (int j = 0; j < q; ++j) active.col(j) = normals.col(out.face[static_cast<size_t>(j)]);
        const Mat6F g_active = g_inverse * active;
        gram.noalias() = active.transpose() * g_active;
        for (int j = 0; j < q; ++j) gram(j, j) += h(out.face[static_cast<size_t>(j)]);
        r = gram.ldlt().solve(active.transpose() * w);
        hn.noalias() -= g_active * r;
      }
      const double denom = np.dot(hn) + h(p);
      const bool dependent = q == kMaxFaces || !(denom > kDependentNormal * (np.dot(w) + h(p)));
      // The step that meets face p; a violation that earlier steps turned negative in rounding
      // is met where p stands (a step back would undo them and cycle).
      const double full =
          dependent ? kInf : std::max(0.0, (np.dot(out.x) - h(p) * up - b(p)) / denom);
      double partial = kInf;
      int leaving = -1;
      for (int j = 0; j < q; ++j) {
        const double uj = out.multiplier[static_cast<size_t>(j)];
        if (r(j) > 0.0 && uj / r(j) < partial) partial = uj / r(j), leaving = j;
      }
      if (full == kInf && partial == kInf) return false;
      const double t = std::min(full, partial);
      out.x.noalias() -= t * hn;
      for (int j = 0; j < q; ++j) out.multiplier[static_cast<size_t>(j)] -= t * r(j);
      up += t;
      if (full <= partial) {
        out.face[static_cast<size_t>(q)] = p;
        out.multiplier[static_cast<size_t>(q)] = up;
        ++out.count;
        break;
      }
      for (int j = leaving; j + 1 < q; ++j) {
        out.face[static_cast<size_t>(j)] = out.face[static_cast<size_t>(j + 1)];
        out.multiplier[static_cast<size_t>(j)] = out.multiplier[static_cast<size_t>(j + 1)];
      }
      --out.count;
    }
  }
}

// The pseudo-inverse of the Gram matrix N N^T of face normals (6 x 6, positive semidefinite):
// its eigenvalues below kDependentNormal times the largest count as zero (the squared sine of a
// normal's angle with the span of the others, the rule of solve_qp). N^T (N N^T)^+ t is the
// least-norm solution of N v = t.
template <class Normals>
Mat6 gram_pseudo_inverse(const Normals& normals) {
  const Eigen::SelfAdjointEigenSolver<Mat6> eigen(normals * normals.transpose());
  const Vec6& value = eigen.eigenvalues();  // ascending
  Vec6 inverse = Vec6::Zero();
  for (int i = 0; i < 6; ++i)
    if (value(i) > kDependentNormal * value(5)) inverse(i) = 1.0 / value(i);
  return eigen.eigenvectors() * inverse.asDiagonal() * eigen.eigenvectors().transpose();
}

// The column j of c, outside `in_set` and not `barred`, with the largest gain c_j . y, where
// that exceeds the angle rule (the sine of the angle between c_j and the plane normal to y above
// sqrt(kDependentNormal), the dependence rule of solve_qp, so that a gain of rounding does not
// enter); -1 where none does.
template <class Columns, class Vector, size_t Max>
int largest_gain(const Columns& c, const Vector& y, const std::array<bool, Max>& in_set,
                 const std::array<bool, Max>& barred) {
  int largest = -1;
  double best = 0.0;
  for (int j = 0; j < static_cast<int>(c.cols()); ++j) {
    if (in_set[static_cast<size_t>(j)] || barred[static_cast<size_t>(j)]) continue;
    const double gain = c.col(j).dot(y);
    if (gain > std::sqrt(kDependentNormal) * c.col(j).norm() * y.norm() && gain > best)
      best = gain, largest = j;
  }
  return largest;
}

// min |E u - f| over u >= 0 (E: rows x n): Lawson and Hanson's NNLS (Solving Least Squares
// Problems, 1974, ch. 23). Columns enter the passive set P by the largest w_j = e_j . (f - E u)
// (the angle rule of the active-set method below); on P the unconstrained least-squares point z
// is approached as far as u stays >= 0, and a column reaching 0 leaves P. Each step of positive
// length lowers |E u - f|, and a column that enters with w_j > 0 gets z_j > 0 in exact arithmetic
// (their Lemma 23.17): where rounding says otherwise it stays out until u moves (their remedy).
// Returns false where `max_changes` is exhausted (rounding).
template <int MaxRows, int MaxCols>
bool nonnegative_least_squares(
    const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, MaxRows, MaxCols>& e,
    const Eigen::Matrix<double, Eigen::Dynamic, 1, 0, MaxRows, 1>& f,
    Eigen::Matrix<double, Eigen::Dynamic, 1, 0, MaxCols, 1>& u) {
  using MatE = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, MaxRows, MaxCols>;
  using VecR = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, MaxRows, 1>;
  using VecC = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, MaxCols, 1>;
  const int n = static_cast<int>(e.cols());
  u.setZero(n);
  std::array<bool, MaxCols> passive{}, barred{};
  const int max_changes = 3 * n + 3;
  for (int changes = 0; changes < max_changes;) {
    const int entering = largest_gain(e, VecR(f - e * u), passive, barred);
    if (entering < 0) return true;
    passive[static_cast<size_t>(entering)] = true;
    for (bool first = true;; first = false) {
      if (++changes >= max_changes) return false;
      std::array<int, MaxCols> index{};
      int k = 0;
      for (int j = 0; j < n; ++j)
        if (passive[static_cast<size_t>(j)]) index[static_cast<size_t>(k++)] = j;
      MatE columns(e.rows(), k);
      for (int i = 0; i < k; ++i) columns.col(i) = e.col(index[static_cast<size_t>(i)]);
      const VecC z = Eigen::ColPivHouseholderQR<MatE>(columns).solve(f);
      double alpha = 1.0;
      int blocking = -1;
      bool rejected = false;  // the entering column without a positive z_j
      for (int i = 0; i < k; ++i) {
        const int j = index[static_cast<size_t>(i)];
        rejected = rejected || (first && j == entering && !(z(i) > 0.0));
        if (z(i) <= 0.0 && u(j) / (u(j) - z(i)) < alpha) alpha = u(j) / (u(j) - z(i)), blocking = i;
      }
      if (rejected) {
        passive[static_cast<size_t>(entering)] = false,
        barred[static_cast<size_t>(entering)] = true;
        break;
      }
      for (int i = 0; i < k; ++i) {
        const int j = index[static_cast<size_t>(i)];
        u(j) = blocking < 0 ? z(i) : u(j) + alpha * (z(i) - u(j));
      }
      barred.fill(false);
      if (blocking < 0) break;
      for (int i = 0; i < k; ++i) {
        const int j = index[static_cast<size_t>(i)];
        if (i == blocking || !(u(j) > 0.0)) u(j) = 0.0, passive[static_cast<size_t>(j)] = false;
      }
    }
  }
  return false;
}

// The least-norm nonnegative solution of N v = t as a least-distance program (Lawson and Hanson,
// ch. 23): min |v| subject to G v >= h, G = [N; -N; I], h = [t; -t; 0] (t scaled to unit
// length), through NNLS on E = [G^T; h^T] and f = e_(m+1): with r = E u - f, v = -r_(1..m) /
// r_(m+1). Unlike the primal active-set method below it needs no multiplier of N v = t, which is
// not unique where the free faces span less than all of them. Returns false where NNLS does.
bool least_distance_split(const Mat6F& normals, const Vec6& t, VecF& v) {
  constexpr int kRows = kMaxFaces + 1, kCols = kMaxFaces + 12;
  using MatE = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kRows, kCols>;
  using VecR = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kRows, 1>;
  using VecC = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kCols, 1>;
  const int m = static_cast<int>(normals.cols());
  const double length = t.norm();
  if (!(length > 0.0)) {
    v.setZero(m);
    return true;
  }
  const Vec6 unit = t / length;
  MatE e = MatE::Zero(m + 1, m + 12);
  e.topLeftCorner(m, 6) = normals.transpose();
  e.block(0, 6, m, 6) = -normals.transpose();
  e.block(0, 12, m, m).setIdentity();
  e.block(m, 0, 1, 6) = unit.transpose();
  e.block(m, 6, 1, 6) = -unit.transpose();
  VecR f = VecR::Zero(m + 1);
  f(m) = 1.0;
  VecC u;
  if (!nonnegative_least_squares<kRows, kCols>(e, f, u)) return false;
  const VecR r = e * u - f;
  if (!(r(m) < 0.0)) return false;  // no feasible v (which the feasible start rules out)
  // v_j = r_j / abs(r_(m+1)). A face that does not slip at the optimum gets r_j = 0 up to the
  // rounding of its sum (Higham's bound gamma_n sum |E_ji u_i|); below that it is 0 exactly, so
  // that the slipping set (which the split's sensitivities use) holds the slipping faces alone.
  const double gamma = (m + 13) * kEps / (1.0 - (m + 13) * kEps);
  for (int j = 0; j < m; ++j) {
    const double rounding = gamma * e.row(j).cwiseAbs().dot(u.cwiseAbs());
    v(j) = r(j) > rounding ? -r(j) / r(m) * length : 0.0;
  }
  return true;
}

// The least-norm nonnegative solution of N v = t (N: 6 x m, the normals of the faces whose slips
// the flow rules leave undetermined), from a feasible v (N v = t, v >= 0): the primal active-set
// method for the strictly convex program min 1/2 |v|^2 subject to N v = t, v >= 0 (Nocedal and
// Wright, Numerical Optimization, 2nd ed., 16.5). On the free faces F (v_f > 0) the least |v_F|
// with N_F v_F = t is x = N_F^T lambda, lambda = (N_F N_F^T)^+ t (t lies in the range of N_F
// because v does); v moves towards x as far as it stays >= 0, and a face reaching 0 leaves F.
// Where x is reached, a face f outside F with n_f . lambda > 0 would lower |v| by slipping, if its
// normal lies in the span of N_F: the largest such enters. Where no face has n_f . lambda > 0,
// lambda is a multiplier of the optimality conditions and v is the solution (unique: strictly
// convex objective; a Lipschitz function of t, the projection of the origin on the polyhedron
// {v >= 0, N v = t}). A face whose normal lies outside that span gets no slip by entering (its
// entry is blocked before v moves: it is barred until v moves, the remedy of Lawson and Hanson's
// NNLS): there lambda is one of many multipliers, faces may lower |v| only together, and the
// least-distance program decides (least_distance_split), as it does if `max_changes` runs out.
// Returns false only where that fails too (v is then a feasible point, not the least-norm one).
bool least_norm_nonnegative(const Mat6F& normals, const Vec6& t, VecF& v) {
  const int m = static_cast<int>(normals.cols());
  std::array<bool, kMaxFaces> free{};
  for (int f = 0; f < m; ++f) free[static_cast<size_t>(f)] = v(f) > 0.0;
  // Faces whose entry did not move v (below): kept out until v moves.
  std::array<bool, kMaxFaces> barred{};
  int entered = -1;
  const int max_changes = 4 * m + 4;
  for (int changes = 0; changes < max_changes; ++changes) {
    std::array<int, kMaxFaces> index{};
    int k = 0;
    for (int f = 0; f < m; ++f)
      if (free[static_cast<size_t>(f)]) index[static_cast<size_t>(k++)] = f;
    Mat6F free_normals(6, k);
    for (int i = 0; i < k; ++i) free_normals.col(i) = normals.col(index[static_cast<size_t>(i)]);
    // lambda: the multiplier of N v = t, with x = N_F^T lambda.
    const Vec6 lambda = k > 0 ? Vec6(gram_pseudo_inverse(free_normals) * t) : Vec6::Zero();
    const VecF x = free_normals.transpose() * lambda;
    // The step towards x, as far as every free slip stays >= 0.
    double alpha = 1.0;
    int blocking = -1;
    for (int i = 0; i < k; ++i) {
      const double vi = v(index[static_cast<size_t>(i)]);
      if (x(i) < 0.0 && vi / (vi - x(i)) < alpha) alpha = vi / (vi - x(i)), blocking = i;
    }
    bool moved = false;
    for (int i = 0; i < k; ++i) {
      double& vi = v(index[static_cast<size_t>(i)]);
      const double next = blocking < 0 ? x(i) : vi + alpha * (x(i) - vi);
      moved = moved || next != vi;
      vi = next;
    }
    // A face whose entry is blocked before v moves: its normal lies outside the span of N_F (in
    // exact arithmetic a face inside it enters with positive slip; one outside cannot slip alone,
    // its x_f is 0 and rounding makes it negative), so its gain says nothing about lowering |v|.
    // Entering it again from the same v and lambda would repeat the same two changes, so it stays
    // out until v moves (the remedy of Lawson and Hanson's NNLS), the next face by gain is tried,
    // and the end test below hands a remaining barred face to the least-distance program.
    if (moved) barred.fill(false);
    if (blocking >= 0) {
      const int f = index[static_cast<size_t>(blocking)];
      v(f) = 0.0, free[static_cast<size_t>(f)] = false;
      if (!moved && f == entered) barred[static_cast<size_t>(f)] = true;
      entered = -1;
      continue;
    }
    // x reached: the face outside F that would lower |v| most, if any.
    const int entering = largest_gain(normals, lambda, free, barred);
    // No face lowers |v| by itself. Where none is barred, lambda certifies v (n_f . lambda <= 0
    // outside F); a barred face's normal lies outside the span of N_F, where lambda is one of
    // many multipliers and faces may lower |v| only together: the least-distance program decides.
    if (entering < 0)
      return std::none_of(barred.begin(), barred.begin() + m, [](bool b) { return b; }) ||
             least_distance_split(normals, t, v);
    free[static_cast<size_t>(entering)] = true;
    entered = entering;
  }
  return least_distance_split(normals, t, v);
}

// The step's stress as the minimiser of
//   Phi(sigma) = 1/2 (sigma - sigma_trial) : C^-1 : (sigma - sigma_trial) + sum_a Psi_a(tau_a)
// over the faces s_a P_a : sigma <= mu_a tau0_a r_s,a(ds_a) of the held systems (s_a: the sign of
// the system's shear at the step's start), with Psi_a' = the slip of a resolved branch at its
// resolved shear (the rate-independent flow rule r = r_s(ds) solved for ds: ds = H(r) - H(start)
// above the branch's start, H the law's slip integral, 0 below). Its stationarity is the step's
// stress equation sigma = sigma_trial - C sum_a P_a dgamma_a with every flow rule met; the
// multipliers of the active faces are the held systems' slips. Held are the systems whose
// hardening mu tau0 U(r_s0) is below their elastic coupling A_aa (near saturation, r_s -> 1, it
// vanishes in double precision), on the side of their start shear; the others, and a held
// system's other side (its r_s restarts from 0 there, (3.12)), are resolved, and their slip's
// rounding through 1/U moves the stress equation by less than eps. A held face's limit is
// linearised in its slip (solve_qp's h) and relinearised at each solve's slips: Newton on the
// held limits. docs/grain_step.md has the argument and its assumptions.
template <int N>
class VertexSolver {
 public:
  using T = SlipTypes<N>;
  using VecN = typename T::VecN;
  using Qp = QpSolution;

  VertexSolver(const Phase<N>& ph, const GrainState<N>& s0, const Vec6& trial, double dt,
               double tolerance)
      : ph_(ph), s0_(s0), trial_(trial), tolerance_(tolerance), n_(ph.slip_count) {
    mu_.resize(n_), crss_.resize(n_), slip_integral0_.resize(n_), start_sign_.resize(n_);
    const VecN tau0 = ph.schmid.transpose() * s0.stress;
    limit_.resize(n_), hardening_.resize(n_), linearised_at_.resize(n_);
    for (int a = 0; a < n_; ++a) {
      const auto& law = ph.laws[static_cast<size_t>(a)];
      mu_(a) = law.friction_coefficient_after(s0.mu(a), 0.0, dt).value;
      start_sign_(a) = sign_of(tau0(a));
      crss_(a) = mu_(a) * ph.tau0(a);
      slip_integral0_(a) = law.subloading_slip_integral(s0.r_s(a));
      limit_(a) = s0.r_s(a) * crss_(a);
      hardening_(a) = law.subloading_rate(s0.r_s(a)) * crss_(a);
      linearised_at_(a) = 0.0;
      held_[static_cast<size_t>(a)] = hardening_(a) < ph.interaction(a, a);
      if (held_[static_cast<size_t>(a)]) held_system_[static_cast<size_t>(held_count_++)] = a;
    }
    face_normals_.resize(6, held_count_);
    for (int f = 0; f < held_count_; ++f)
      face_normals_.col(f) = sign_of_face(f) * ph.schmid.col(system_of(f));
  }

  int held_count() const { return held_count_; }
  // The subloading ratio a system's branch starts from for a shear of this sign: r_s0 along the
  // start shear, 0 against it ((3.12): r_s follows r down through zero).
  double branch_start(int a, double sign) const {
    return sign == start_sign_(a) ? s0_.r_s(a) : 0.0;
  }
  const VecN& mu() const { return mu_; }

  // The minimiser and the final quadratic subproblem's active faces; false where the solve did
  // not converge within max_iterations quadratic subproblems.
  bool solve(Vec6& sigma, Qp& qp, int& iterations, int max_iterations) {
    sigma = s0_.stress;
    for (;;) {
      if (!minimise(sigma, qp, iterations, max_iterations)) return false;
      if (relinearise(qp) <= 0.25 * tolerance_) {
        split_saturated(sigma, qp);
        return true;
      }
    }
  }

  // The slip increments (signed) at a converged stress and active set.
  VecN slips(const Vec6& sigma, const Qp& qp) const {
    VecN dgamma = VecN::Zero(n_);
    const VecN tau = ph_.schmid.transpose() * sigma;
    for (int a = 0; a < n_; ++a) {
      const ResolvedBranch b = resolved_branch(a, tau(a));
      if (b.slips) dgamma(a) = b.sign * resolved_slip(a, b.r, b.sign);
    }
    for (int j = 0; j < qp.count; ++j) {
      const int f = qp.face[static_cast<size_t>(j)];
      dgamma(system_of(f)) = sign_of_face(f) * qp.multiplier[static_cast<size_t>(j)];
    }
    if (split_count_ > 0) {
      for (int j = 0; j < qp.count; ++j) {
        const int f = qp.face[static_cast<size_t>(j)];
        if (saturated_[static_cast<size_t>(f)]) dgamma(system_of(f)) = 0.0;
      }
      for (int i = 0; i < split_count_; ++i) {
        const int f = split_face_[static_cast<size_t>(i)];
        dgamma(system_of(f)) = sign_of_face(f) * split_slip_[static_cast<size_t>(i)];
      }
    }
    return dgamma;
  }

  // d dgamma / d(lattice strain increment) at the solution: the stationarity G dsigma +
  // N du = d eps and the active faces N^T dsigma = h du (h: the held systems' hardening, mu
  // tau0 U at the end) give du = (N^T G^-1 N + h)^-1 N^T G^-1 d eps and dsigma = G^-1 (d eps -
  // N du); a resolved system's slip follows its shear with slope 1/(U crss).
  typename T::MatN6 slip_sensitivities(const Vec6& sigma, const Qp& qp) const {
    Mat6 hessian;
    Vec6 gradient;
    evaluate(sigma, gradient, &hessian);
    const Mat6 g_inverse = hessian.llt().solve(Mat6::Identity());
    Mat6 dsigma = g_inverse;
    MatFF du;
    if (qp.count > 0) {
      Mat6F active(6, qp.count);
      MatFF gram(qp.count, qp.count);
      for (int j = 0; j < qp.count; ++j)
        active.col(j) = face_normal(qp.face[static_cast<size_t>(j)]);
      const Mat6F g_active = g_inverse * active;
      gram.noalias() = active.transpose() * g_active;
      // The held faces' hardening at the end: solve() returns after relinearise() at the
      // final slips.
      for (int j = 0; j < qp.count; ++j)
        gram(j, j) += hardening_(system_of(qp.face[static_cast<size_t>(j)]));
      du = gram.ldlt().solve(g_active.transpose());  // q x 6
      dsigma.noalias() -= g_active * du;
    }
    typename T::MatN6 out = T::MatN6::Zero(n_, 6);
    const VecN tau = ph_.schmid.transpose() * sigma;
    for (int a = 0; a < n_; ++a) {
      const ResolvedBranch b = resolved_branch(a, tau(a));
      if (!b.slips) continue;
      const double slope = 1.0 / (ph_.laws[static_cast<size_t>(a)].subloading_rate(b.r) * crss_(a));
      out.row(a) = slope * (ph_.schmid.col(a).transpose() * dsigma);
    }
    for (int j = 0; j < qp.count; ++j) {
      const int f = qp.face[static_cast<size_t>(j)];
      out.row(system_of(f)) = sign_of_face(f) * du.row(j);
    }
    if constexpr (T::MaxN > 1)
      if (split_count_ > 0) split_sensitivities(qp, du, out);
    return out;
  }

 private:
  // Face k: held system k along its start shear. Against it a held system is resolved: its
  // subloading ratio restarts from 0 there (3.12), where the hardening is large.
  int system_of(int face) const { return held_system_[static_cast<size_t>(face)]; }
  double sign_of_face(int face) const { return start_sign_(system_of(face)); }
  Vec6 face_normal(int face) const { return face_normals_.col(face); }
  bool resolves(int a, double sign) const {
    return sign != start_sign_(a) || !held_[static_cast<size_t>(a)];
  }

  // Where system a's shear tau puts it on a resolved branch above that branch's start (so that
  // it slips by its own flow rule): the branch's sign and loading ratio.
  struct ResolvedBranch {
    bool slips;
    double sign, r;
  };
  ResolvedBranch resolved_branch(int a, double tau) const {
    const double sign = sign_of(tau), r = std::abs(tau) / crss_(a);
    return {resolves(a, sign) && r > branch_start(a, sign), sign, r};
  }

  // A resolved system's slip at loading ratio r (< 1) and shear of this sign: the root of its
  // flow rule on that branch.
  double resolved_slip(int a, double r, double sign) const {
    if (!(r > branch_start(a, sign))) return 0.0;
    const double start_integral = sign == start_sign_(a) ? slip_integral0_(a) : 0.0;
    return std::max(0.0,
                    ph_.laws[static_cast<size_t>(a)].subloading_slip_integral(r) - start_integral);
  }

  // Phi's gradient (and Hessian) at sigma; false outside the domain (r >= 1 on a resolved
  // system, where its slip is unbounded).
  bool evaluate(const Vec6& sigma, Vec6& gradient, Mat6* hessian) const {
    gradient.noalias() = ph_.compliance * (sigma - trial_);
    if (hessian) *hessian = ph_.compliance;
    const VecN tau = ph_.schmid.transpose() * sigma;
    for (int a = 0; a < n_; ++a) {
      const ResolvedBranch b = resolved_branch(a, tau(a));
      if (!b.slips) continue;
      if (!(b.r < 1.0)) return false;
      gradient.noalias() += (b.sign * resolved_slip(a, b.r, b.sign)) * ph_.schmid.col(a);
      if (hessian) {
        const double slope =
            1.0 / (ph_.laws[static_cast<size_t>(a)].subloading_rate(b.r) * crss_(a));
        hessian->noalias() += slope * ph_.schmid.col(a) * ph_.schmid.col(a).transpose();
      }
    }
    return true;
  }

  // Sequential quadratic programming at fixed linearisations of the held limits: each
  // iterate's quadratic model of Phi minimised over the faces (solve_qp), then a line search
  // along the step. Converged when the step changes no shear by more than a quarter of the
  // tolerance (traction-ratio units); the full step is then taken.
  bool minimise(Vec6& sigma, Qp& qp, int& iterations, int max_iterations) const {
    const int faces = held_count_;
    VecF b(faces), h(faces), slack(faces);
    double last_step = kInf;
    for (;;) {
      if (++iterations > max_iterations) return false;
      Vec6 gradient;
      Mat6 hessian;
      if (!evaluate(sigma, gradient, &hessian)) return false;
      const Mat6 g_inverse = hessian.llt().solve(Mat6::Identity());
      for (int f = 0; f < faces; ++f) {
        const int a = system_of(f);
        h(f) = hardening_(a);
        b(f) = limit_(a) - hardening_(a) * linearised_at_(a) - face_normal(f).dot(sigma);
        slack(f) = 0.25 * tolerance_ * crss_(a);
      }
      if (!solve_qp(g_inverse, gradient, face_normals_, b, h, slack, qp)) return false;
      const VecN step_shear = ph_.schmid.transpose() * qp.x;
      const double step = step_shear.cwiseAbs().cwiseQuotient(crss_).maxCoeff();
      // Newton's steps shrink quadratically until they reach the rounding of the stationarity
      // (a resolved system's slip through 1/U, the faces' multipliers); a step within the
      // tolerance that did not halve is that rounding.
      if (step <= 0.25 * tolerance_ || (step <= tolerance_ && step > 0.5 * last_step)) {
        sigma += qp.x;
        return true;
      }
      last_step = step;
      if (!line_search(sigma, qp.x, gradient.dot(qp.x))) return false;
    }
  }

  // sigma + alpha x. From a stress that meets the faces the step descends (slope0 < 0): alpha = 1
  // where Phi's slope there is at most half its magnitude at alpha = 0 (a Newton step near the
  // solution), else halved until the slope is not positive (the line minimum is not passed, so
  // Phi fell). From one that does not (the start, or after a relinearisation) the step restores
  // the faces and is taken whole, halved only into the domain. False where halving no longer
  // moves sigma.
  bool line_search(Vec6& sigma, const Vec6& x, double slope0) const {
    Vec6 gradient;
    for (double alpha = 1.0;; alpha *= 0.5) {
      const Vec6 trial = sigma + alpha * x;
      if (trial == sigma) return false;
      if (!evaluate(trial, gradient, nullptr)) continue;
      const double slope = gradient.dot(x);
      if (!(slope0 < 0.0) || slope <= 0.0 || (alpha == 1.0 && slope <= -0.5 * slope0)) {
        sigma = trial;
        return true;
      }
    }
  }

  // The split of slip among saturated faces. A held face is saturated where its hardening times
  // the step's held slip (|u|, a bound on how far any split moves one face's slip) is below half
  // the flow tolerance: no split of that slip changes its flow rule by as much as the tolerance
  // leaves after convergence, so the flow rules do not determine it (at r_s -> 1 the hardening
  // vanishes in double precision; at a vertex of more saturated faces than independent normals
  // the dual active-set method returns one basis of them, chosen by the order of its steps, which
  // jumps between neighbouring loadings). The stress determines their joint share of the
  // stationarity, t = sum over the saturated active faces u_f n_f; it is redistributed as the
  // least-norm nonnegative slips over every saturated face at its limit within half the
  // tolerance (least_norm_nonnegative): unique, and continuous in the loading. The end state's
  // check of every flow rule verifies the bound.
  void split_saturated(const Vec6& sigma, const Qp& qp) {
    split_count_ = 0;
    if (n_ == 1) return;  // one face: the stress determines its slip
    double held_slip = 0.0;
    for (int j = 0; j < qp.count; ++j)
      held_slip += qp.multiplier[static_cast<size_t>(j)] * qp.multiplier[static_cast<size_t>(j)];
    held_slip = std::sqrt(held_slip);
    for (int f = 0; f < held_count_; ++f) {
      const int a = system_of(f);
      saturated_[static_cast<size_t>(f)] = hardening_(a) * held_slip <= 0.5 * tolerance_ * crss_(a);
    }
    Mat6F normals(6, held_count_);
    VecF v(held_count_);
    Vec6 t = Vec6::Zero();
    int m = 0;
    for (int j = 0; j < qp.count; ++j) {
      const int f = qp.face[static_cast<size_t>(j)];
      if (!saturated_[static_cast<size_t>(f)]) continue;
      split_face_[static_cast<size_t>(m)] = f;
      normals.col(m) = face_normal(f);
      v(m++) = qp.multiplier[static_cast<size_t>(j)];
      t += qp.multiplier[static_cast<size_t>(j)] * face_normal(f);
    }
    if (m == 0) return;
    for (int f = 0; f < held_count_; ++f) {
      const int a = system_of(f);
      const bool listed =
          std::find(split_face_.begin(), split_face_.begin() + m, f) != split_face_.begin() + m;
      if (listed || !saturated_[static_cast<size_t>(f)] ||
          face_normal(f).dot(sigma) - limit_(a) < -0.5 * tolerance_ * crss_(a))
        continue;
      split_face_[static_cast<size_t>(m)] = f;
      normals.col(m) = face_normal(f);
      v(m++) = 0.0;
    }
    normals.conservativeResize(6, m);
    v.conservativeResize(m);
    if (!least_norm_nonnegative(normals, t, v)) return;  // the dual method's split stands
    for (int i = 0; i < m; ++i) split_slip_[static_cast<size_t>(i)] = v(i);
    split_count_ = m;
  }

  // The split's slip sensitivities: where the set of saturated faces that slip (P) does not
  // change, their slips are N_P^T (N_P N_P^T)^+ t, and t's sensitivity is the saturated active
  // faces' share of N du (the stress and the other faces' slips determine it, whatever the basis).
  void split_sensitivities(const Qp& qp, const MatFF& du, typename T::MatN6& out) const {
    Mat6 dt = Mat6::Zero();
    for (int j = 0; j < qp.count; ++j) {
      const int f = qp.face[static_cast<size_t>(j)];
      if (!saturated_[static_cast<size_t>(f)]) continue;
      dt.noalias() += face_normal(f) * du.row(j);
      out.row(system_of(f)).setZero();
    }
    Mat6F slipping(6, split_count_);
    std::array<int, T::MaxN> face{};
    int k = 0;
    for (int i = 0; i < split_count_; ++i) {
      if (!(split_slip_[static_cast<size_t>(i)] > 0.0)) continue;
      face[static_cast<size_t>(k)] = split_face_[static_cast<size_t>(i)];
      slipping.col(k++) = face_normal(split_face_[static_cast<size_t>(i)]);
    }
    if (k == 0) return;
    slipping.conservativeResize(6, k);
    const Mat6 dlambda = gram_pseudo_inverse(slipping) * dt;
    for (int i = 0; i < k; ++i) {
      const int f = face[static_cast<size_t>(i)];
      out.row(system_of(f)) = sign_of_face(f) * (slipping.col(i).transpose() * dlambda);
    }
  }

  // Each held system's limit and hardening at the slip the last solve gave it; returns the
  // largest error of the linearisation there (traction-ratio units).
  double relinearise(const Qp& qp) {
    double error = 0.0;
    for (int k = 0; k < held_count_; ++k) {
      const int a = held_system_[static_cast<size_t>(k)];
      double slip = 0.0;
      for (int j = 0; j < qp.count; ++j)
        if (system_of(qp.face[static_cast<size_t>(j)]) == a)
          slip = qp.multiplier[static_cast<size_t>(j)];
      const auto after = ph_.laws[static_cast<size_t>(a)].subloading_ratio_after(s0_.r_s(a), slip);
      const double linear = limit_(a) + hardening_(a) * (slip - linearised_at_(a));
      limit_(a) = after.value * crss_(a);
      hardening_(a) = after.d_slip * crss_(a);
      linearised_at_(a) = slip;
      error = std::max(error, std::abs(limit_(a) - linear) / crss_(a));
    }
    return error;
  }

  const Phase<N>& ph_;
  const GrainState<N>& s0_;
  Vec6 trial_;
  double tolerance_;
  int n_;
  VecN mu_, crss_, slip_integral0_, start_sign_;
  VecN limit_, hardening_, linearised_at_;  // the held faces' linearisations (stress units)
  std::array<bool, T::MaxN> held_{};        // per system
  std::array<int, T::MaxN> held_system_{};  // the held systems, in order: face k is the k-th
  int held_count_ = 0;
  Mat6F face_normals_;  // face k's column: sign_of_face(k) P_a (a = system_of(k))
  // The saturated faces' split (split_saturated): per face whether it is saturated; the faces
  // of the split and their least-norm slips.
  std::array<bool, T::MaxN> saturated_{};
  std::array<int, T::MaxN> split_face_{};
  std::array<double, T::MaxN> split_slip_{};
  int split_count_ = 0;
};

}  // namespace

template <int N>
bool vertex_step_applies(const Phase<N>& ph) {
  if (ph.pressure_sensitive) return false;
  for (const auto& law : ph.laws)
    if (!law.is_rate_independent() || law.parameters().friction.kappa != 0.0) return false;
  return true;
}

template <int N>
GrainStepReport vertex_grain_step(const Phase<N>& ph, const GrainState<N>& s0, const Mat3& L,
                                  double dt, const GrainStepOptions& opt, GrainState<N>& s1,
                                  Tangent* tangent, SlipTangent<N>* slip_tangent) {
  using VecN = typename SlipTypes<N>::VecN;
  GrainStepReport rep;
  const int n = ph.slip_count;
  const StepKinematics kin = step_kinematics(s0.orientation, L, dt, ph.kinematics);
  const Vec6 trial = s0.stress + ph.stiffness * kin.strain_increment;
  const double tolerance = admitted_flow_residual(opt);
  VertexSolver<N> solver(ph, s0, trial, dt, tolerance);
  Vec6 sigma;
  typename VertexSolver<N>::Qp qp;
  rep.iterations = 0;
  if (!solver.solve(sigma, qp, rep.iterations, opt.max_iterations)) {
    rep.why = "rate-independent vertex step did not converge";
    return rep;
  }

  // The end state from the slips: the stress equation holds by construction, the flow rules
  // are checked.
  const VecN dgamma = solver.slips(sigma, qp);
  s1.stress = trial - ph.c_schmid * dgamma;
  s1.mu = solver.mu();
  s1.slip = s0.slip + dgamma;
  s1.rate = dgamma / dt;
  const VecN fn1 = normal_traction(ph, s1.stress);
  const VecN r1 = loading_ratio_of(ph, s1.stress, s1.mu, fn1);
  VecN r_s = VecN::Zero(n);
  for (int a = 0; a < n; ++a) {
    const auto& law = ph.laws[static_cast<size_t>(a)];
    // The flow rule on the branch of the end shear: r = r_s(ds) where the system slips, r <= the
    // branch's start where it does not.
    const double tau1 = ph.schmid.col(a).dot(s1.stress);
    const double start =
        solver.branch_start(a, dgamma(a) != 0.0 ? sign_of(dgamma(a)) : sign_of(tau1));
    r_s(a) = law.subloading_ratio_after(start, std::abs(dgamma(a))).value;
    const double residual = r1(a) - r_s(a);
    if (dgamma(a) != 0.0 ? std::abs(residual) > tolerance : residual > tolerance) {
      rep.why = "rate-independent vertex step: flow rule not met", rep.system = a;
      return rep;
    }
  }
  s1.r_s = r_s.cwiseMin(r1);  // (3.12): r_s follows r down where no slip occurs
  s1.orientation = orientation_after_plastic_spin(ph, kin.spun_orientation, dgamma);
  if (!admissible_state(ph, s1, r1, fn1, rep, OpenPlanes::refused, tolerance)) return rep;

  if (tangent) {
    tangents_from_slip_sensitivity(ph, s1, solver.slip_sensitivities(sigma, qp),
                                   lattice_directions(opt.tangent_directions, kin.mid_orientation),
                                   tangent, slip_tangent);
  }
  rep.ok = true;
  return rep;
}

#define SUBSLIP_INSTANTIATE_VERTEX(N)                                                         \
  template bool vertex_step_applies<N>(const Phase<N>&);                                      \
  template GrainStepReport vertex_grain_step<N>(const Phase<N>&, const GrainState<N>&,        \
                                                const Mat3&, double, const GrainStepOptions&, \
                                                GrainState<N>&, Tangent*, SlipTangent<N>*);
SUBSLIP_FOR_EACH_SLIP_COUNT(SUBSLIP_INSTANTIATE_VERTEX)

}  // namespace subslip::crystal::detail
