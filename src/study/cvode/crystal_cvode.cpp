// A Taylor aggregate as one ODE system for CVODE (see cvode_peer.hpp).
//
// Layout of the state: grain after grain, each [lattice stress (6, Mandel), orientation g (9,
// row-major), z (N), mu (N), signed slip (N)], then F (9, row-major) and the integral of sym(L)
// (9). The rates come from crystal::slip_rates / crystal::grain_rates, the same functions
// forward Euler steps.
//
// Linear algebra: up to CvodeOptions::dense_limit unknowns a dense Newton matrix with CVODE's
// difference-quotient Jacobian; beyond, matrix-free GMRES (CVODE's difference-quotient
// Jacobian-vector products) preconditioned by the block diagonal I - gamma J_g of the grains
// (J_g by differences of one grain's rates at fixed L; the coupling through the free components
// of L is left to GMRES). Grains run under OpenMP; every reduction is serial in grain order.
#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>

#include "cvode_solver.hpp"
#include "subslip/crystal/elasticity.hpp"
#include "subslip/crystal/free_components.hpp"

namespace subslip::cvode {

namespace {

using crystal::free_components;
using crystal::FreeComponent;
using crystal::Mat3;
using crystal::Vec3;
using crystal::Vec6;
using RowMat3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;
constexpr int kMaxFree = 9;
// Grains from which the per-grain loops of a right-hand side run in parallel: each evaluation
// opens a few parallel regions, which cost more than a handful of grains' work (measured with 3
// grains on a loaded 2-core machine: 2 s on one thread, 45 s on two).
constexpr long kParallelGrains = 64;
using FreeMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxFree, kMaxFree>;
using FreeVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxFree, 1>;

Mat3 cross_matrix(const Vec3& w) {
  Mat3 k;
  k << 0.0, -w.z(), w.y(), w.z(), 0.0, -w.x(), -w.y(), w.x(), 0.0;
  return k;
}

Mat3 log_strain(const Mat3& f) {
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(f * f.transpose());
  const Eigen::Vector3d log_values = eig.eigenvalues().array().log() * 0.5;
  return eig.eigenvectors() * log_values.asDiagonal() * eig.eigenvectors().transpose();
}

// Why a grain's state is not admissible (a recoverable right-hand-side failure).
struct GrainFailure {
  const char* why = nullptr;
  int system = -1;
};

template <int N>
class TaylorOde final : private crystal::GrainFields {
 public:
  using T = crystal::SlipTypes<N>;
  using VecN = typename T::VecN;
  using State = crystal::GrainState<N>;

  TaylorOde(crystal::BuiltPhase<N> built, const std::vector<crystal::Orientation>& grains)
      : phase_(std::move(built.phase)),
        initial_mu_(built.initial_mu),
        n_(phase_.slip_count),
        grain_size_(15 + 3 * n_),
        grains_(static_cast<int>(grains.size())) {
    for (const auto& law : phase_.laws) {
      if (law.is_rate_independent())
        throw std::invalid_argument(
            "CVODE peer: not applicable to the rate_independent overstress form (its slip rate "
            "is set by the consistency condition and has no ODE form); use the implicit "
            "integrator");
      z_.emplace_back(law);
    }
    if (grains.empty()) throw std::invalid_argument("CVODE peer: no grains");
    double total = 0.0;
    for (const auto& g : grains) {
      orientations_.push_back(g.g);
      weights_.push_back(g.weight);
      total += g.weight;
    }
    for (double& w : weights_) w /= total;
    states_.resize(static_cast<size_t>(grains_));
    slips_.resize(static_cast<size_t>(grains_));
    failures_.resize(static_cast<size_t>(grains_));
    parts_.resize(static_cast<size_t>(grains_));
    zero_.rate = VecN::Zero(n_);
  }

  int size() const { return grains_ * grain_size_ + 18; }
  int grain_count() const override { return grains_; }
  int slip_count() const override { return n_; }

  // Offsets within a grain's block.
  int z_at(int a) const { return 15 + a; }
  int mu_at(int a) const { return 15 + n_ + a; }
  int slip_at(int a) const { return 15 + 2 * n_ + a; }
  int global_at() const { return grains_ * grain_size_; }

  void initial_state(double* y) const {
    std::fill(y, y + size(), 0.0);
    for (int g = 0; g < grains_; ++g) {
      double* yg = y + g * grain_size_;
      Eigen::Map<RowMat3>(yg + 6) = orientations_[static_cast<size_t>(g)];
      for (int a = 0; a < n_; ++a) yg[mu_at(a)] = initial_mu_(a);
    }
    Eigen::Map<RowMat3>(y + global_at()) = Mat3::Identity();
  }

  std::vector<double> absolute_tolerances(double atol_scale) const {
    double stress = 0.0, mu = 0.0, stiffness = std::numeric_limits<double>::infinity();
    for (int a = 0; a < n_; ++a) {
      const auto& f = phase_.laws[static_cast<size_t>(a)].parameters().friction;
      mu = std::max({mu, f.mu_s, f.mu_k, initial_mu_(a)});
      stress = std::max(stress, phase_.tau0(a) * std::max({f.mu_s, f.mu_k, initial_mu_(a)}));
      stiffness = std::min(stiffness, phase_.interaction(a, a));
    }
    std::vector<double> atol(static_cast<size_t>(size()), atol_scale);  // g, z, F, E: scale 1
    for (int g = 0; g < grains_; ++g) {
      double* t = atol.data() + g * grain_size_;
      for (int k = 0; k < 6; ++k) t[k] = atol_scale * stress;
      for (int a = 0; a < n_; ++a) {
        t[mu_at(a)] = atol_scale * mu;
        t[slip_at(a)] = atol_scale * stress / stiffness;  // elastic shear at the yield scale
      }
    }
    return atol;
  }

  void set_segment(const crystal::LoadSegment& seg, const double* y) {
    if (seg.rate_control != crystal::RateControl::velocity_gradient ||
        seg.stress_measure != crystal::StressMeasure::cauchy)
      throw std::invalid_argument("CVODE peer: loading by L and Cauchy stress only (no dot_F, P)");
    free_ = free_components(seg.free);
    if (free_.size() > static_cast<size_t>(kMaxFree))
      throw std::invalid_argument("CVODE peer: more than 9 free components of L");
    prescribed_ = seg.velocity_gradient;
    for (const auto& c : free_) {
      prescribed_(c.i, c.j) = 0.0;
      if (c.symmetric_pair) prescribed_(c.j, c.i) = 0.0;
    }
    const Mat3 start = macro_stress(y);
    const int k = static_cast<int>(free_.size());
    target_rate_.resize(k);
    for (int b = 0; b < k; ++b) {
      const auto& c = free_[static_cast<size_t>(b)];
      target_rate_(b) =
          seg.duration > 0.0 ? (seg.stress_target(c.i, c.j) - start(c.i, c.j)) / seg.duration : 0.0;
    }
  }

  // The right-hand side; > 0 when some grain is outside the admissible set.
  int rhs(double t, const double* y, double* ydot) {
    if (!prepare(y)) return record_failure(t);
    if (!solve_free_components()) {
      failure_ = "mixed control: the free components of L have a singular stress-rate system";
      return 1;
    }
    const long grains = grains_;
#pragma omp parallel for schedule(static) if (grains >= kParallelGrains)
    for (long g = 0; g < grains; ++g) {
      const auto gi = static_cast<size_t>(g);
      grain_derivative(states_[gi], slips_[gi], y + g * grain_size_, l_, ydot + g * grain_size_);
    }
    const double* f = y + global_at();
    double* df = ydot + global_at();
    Eigen::Map<RowMat3>{df} = l_ * Eigen::Map<const RowMat3>(f);
    Eigen::Map<RowMat3>(df + 9) = 0.5 * (l_ + l_.transpose());
    return 0;
  }

  // Preconditioner set-up: the per-grain blocks I - gamma J_g (J_g recomputed unless jok) at
  // the L of the state y (the coupling through L is left to GMRES).
  int preconditioner_setup(double t, const double* y, bool jok, bool& recomputed, double gamma,
                           const std::vector<double>& weights) {
    recomputed = false;
    if (!jok) {
      scratch_.resize(static_cast<size_t>(size()));
      if (rhs(t, y, scratch_.data()) != 0) return 1;  // L and the base rates at y
      blocks_.resize(static_cast<size_t>(grains_));
      lu_.resize(static_cast<size_t>(grains_));
      bool ok = true;
      const long grains = grains_;
#pragma omp parallel for schedule(static) if (grains >= kParallelGrains) reduction(&& : ok)
      for (long g = 0; g < grains; ++g) ok = grain_jacobian(static_cast<int>(g), y, weights) && ok;
      if (!ok) return 1;
      ++jacobians_;
      recomputed = true;
    }
    const long grains = grains_;
#pragma omp parallel for schedule(static) if (grains >= kParallelGrains)
    for (long g = 0; g < grains; ++g) {
      const auto gi = static_cast<size_t>(g);
      Eigen::MatrixXd p = -gamma * blocks_[gi];
      p.diagonal().array() += 1.0;
      lu_[gi].compute(p);
    }
    return 0;
  }

  void preconditioner_solve(const double* r, double* z) const {
    const long grains = grains_;
#pragma omp parallel for schedule(static) if (grains >= kParallelGrains)
    for (long g = 0; g < grains; ++g) {
      const Eigen::Map<const Eigen::VectorXd> rg(r + g * grain_size_, grain_size_);
      Eigen::Map<Eigen::VectorXd>(z + g * grain_size_, grain_size_) =
          lu_[static_cast<size_t>(g)].solve(rg);
    }
    std::copy(r + global_at(), r + size(), z + global_at());
  }

  // Evaluates everything the observer sees at state y (time t) and calls it.
  bool observe(double t, int segment, const double* y, const crystal::MacroObserver& observer,
               bool initial) {
    scratch_.resize(static_cast<size_t>(size()));
    if (rhs(t, y, scratch_.data()) != 0) return false;
    view_ = y;
    crystal::MacroState m;
    m.time = t;
    m.segment = segment;
    m.velocity_gradient = initial ? Mat3::Zero() : l_;  // as Aggregate::run reports it
    m.deformation_gradient = Eigen::Map<const RowMat3>(y + global_at());
    m.strain = phase_.kinematics == crystal::Kinematics::small_strain
                   ? Mat3(Eigen::Map<const RowMat3>(y + global_at() + 9))
                   : log_strain(m.deformation_gradient);
    m.stress = macro_stress(y);
    observer(m, *this);
    return true;
  }

  const std::string& failure() const {
    return failure_;
  }
  long rejected() const {
    return rejected_;
  }
  long jacobians() const {
    return jacobians_;
  }

 private:
  // Unpacks every grain and computes its slip rates and the pieces of the mixed-control system
  // (the sample-frame stress rate at the prescribed L and per unit free component).
  bool prepare(const double* y) {
    const long grains = grains_;
    const int k = static_cast<int>(free_.size());
#pragma omp parallel for schedule(static) if (grains >= kParallelGrains)
    for (long g = 0; g < grains; ++g) {
      const auto gi = static_cast<size_t>(g);
      State& s = states_[gi];
      unpack(y + g * grain_size_, s);
      failures_[gi] = slip_rates_checked(s, slips_[gi]);
      if (failures_[gi].why) continue;
      auto& part = parts_[gi];
      part.resize(k, k + 1);
      if (k == 0) continue;
      const Mat3 base = sample_stress_rate(s, slips_[gi], prescribed_);
      for (int b = 0; b < k; ++b) {
        const Mat3 unit =
            sample_stress_rate(s, zero_slip(), free_[static_cast<size_t>(b)].direction());
        for (int a = 0; a < k; ++a) part(a, b) = unit(free_[a].i, free_[a].j);
      }
      for (int a = 0; a < k; ++a) part(a, k) = base(free_[a].i, free_[a].j);
    }
    for (int g = 0; g < grains_; ++g)
      if (failures_[static_cast<size_t>(g)].why) {
        failed_grain_ = g;
        return false;
      }
    return true;
  }

  // Free components u with sum_g w_g (M_g u + c_g) = target rate; l_ = prescribed + u.
  bool solve_free_components() {
    l_ = prescribed_;
    const int k = static_cast<int>(free_.size());
    if (k == 0) return true;
    FreeMatrix m = FreeMatrix::Zero(k, k);
    FreeVector c = FreeVector::Zero(k);
    for (int g = 0; g < grains_; ++g) {  // serial: independent of the thread count
      const auto& part = parts_[static_cast<size_t>(g)];
      m += weights_[static_cast<size_t>(g)] * part.leftCols(k);
      c += weights_[static_cast<size_t>(g)] * part.col(k);
    }
    const FreeVector u = m.partialPivLu().solve(FreeVector(target_rate_ - c));
    if (!u.allFinite()) return false;
    for (int b = 0; b < k; ++b) l_ += u(b) * free_[static_cast<size_t>(b)].direction();
    return true;
  }

  void unpack(const double* yg, State& s) const {
    s.stress = Eigen::Map<const Vec6>(yg);
    s.orientation = Eigen::Map<const RowMat3>(yg + 6);
    s.mu.resize(n_), s.r_s.resize(n_), s.slip.resize(n_), s.rate.resize(n_);
    for (int a = 0; a < n_; ++a) {
      s.r_s(a) = z_[static_cast<size_t>(a)].ratio_of(yg[z_at(a)]);
      s.mu(a) = yg[mu_at(a)];
      s.slip(a) = yg[slip_at(a)];
    }
    s.rate.setZero();
  }

  GrainFailure slip_rates_checked(const State& s, crystal::SlipRates<N>& sr) const {
    if (!s.stress.allFinite() || !s.orientation.allFinite())
      return {"non-finite stress or orientation", -1};
    for (int a = 0; a < n_; ++a)
      if (!std::isfinite(s.mu(a)) || !std::isfinite(s.slip(a)) || !(s.mu(a) > 0.0))
        return {"mu <= 0 or non-finite slip-system state", a};
    crystal::slip_rates(phase_, s, sr);
    for (int a = 0; a < n_; ++a) {
      if (!(sr.fn(a) > 0.0)) return {"slip plane not in compression (f_n <= 0)", a};
      if (!std::isfinite(sr.rate(a))) return {"r >= r_hat", a};
    }
    return {};
  }

  // No slip: what multiplies a free component of L in the stress rate.
  const crystal::SlipRates<N>& zero_slip() const {
    return zero_;
  }

  // d/dt of g^T sigma g for the state's rates under L: g^T (sigma' + Omega sigma - sigma Omega) g.
  Mat3 sample_stress_rate(const State& s, const crystal::SlipRates<N>& sr, const Mat3& l) const {
    crystal::GrainRates<N> rates;
    crystal::grain_rates(phase_, s, sr, l, rates);
    const Mat3 sigma = crystal::symmetric_from_mandel(s.stress);
    const Mat3 omega = cross_matrix(rates.lattice_spin);
    const Mat3 rate =
        crystal::symmetric_from_mandel(rates.stress_rate) + omega * sigma - sigma * omega;
    return s.orientation.transpose() * rate * s.orientation;
  }

  // One grain's block of the right-hand side under L.
  void grain_derivative(const State& s, const crystal::SlipRates<N>& sr, const double* yg,
                        const Mat3& l, double* out) const {
    crystal::GrainRates<N> rates;
    crystal::grain_rates(phase_, s, sr, l, rates);
    Eigen::Map<Vec6>{out} = rates.stress_rate;
    Eigen::Map<RowMat3>(out + 6) = -cross_matrix(rates.lattice_spin) * s.orientation;
    const VecN tau_rate = phase_.schmid.transpose() * rates.stress_rate;
    VecN fn_rate = VecN::Zero(n_);
    if (phase_.pressure_sensitive)
      fn_rate = -phase_.plane_normal_dyad.transpose() * rates.stress_rate;
    for (int a = 0; a < n_; ++a) {
      const auto& zv = z_[static_cast<size_t>(a)];
      const double r = sr.r(a), rs = s.r_s(a), mu = s.mu(a);
      double dz = 0.0;
      if (r > rs) {
        dz = zv.sliding_rate(yg[z_at(a)], std::abs(sr.rate(a)));
      } else {
        // (3.12): no viscoplastic slip, r_s follows r down.
        const double shear_rate =
            sr.tau(a) != 0.0 ? std::copysign(1.0, sr.tau(a)) * tau_rate(a) : std::abs(tau_rate(a));
        const double r_rate =
            shear_rate / (mu * sr.fn(a)) - r * (rates.mu_rate(a) / mu + fn_rate(a) / sr.fn(a));
        if (r_rate < 0.0) dz = zv.slope(rs) * r_rate;
      }
      out[z_at(a)] = dz;
      out[mu_at(a)] = rates.mu_rate(a);
      out[slip_at(a)] = sr.rate(a);
    }
  }

  // J_g by forward differences of one grain's rates at fixed L (step from the error weights).
  bool grain_jacobian(int g, const double* y, const std::vector<double>& weights) {
    const int m = grain_size_;
    auto& j = blocks_[static_cast<size_t>(g)];
    j.resize(m, m);
    const double* yg = y + g * grain_size_;
    const double* f0 = scratch_.data() + g * grain_size_;
    constexpr int kMax = 15 + 3 * crystal::kMaxSlipSystems;
    std::array<double, kMax> yp, fp;
    std::copy(yg, yg + m, yp.begin());
    State s;
    crystal::SlipRates<N> sr;
    const double root_eps = std::sqrt(std::numeric_limits<double>::epsilon());
    for (int c = 0; c < m; ++c) {
      const double w = weights[static_cast<size_t>(g * grain_size_ + c)];
      double h = root_eps * std::max(std::abs(yg[c]), w > 0.0 ? 1.0 / w : 1.0);
      bool ok = false;
      for (double sign : {1.0, -1.0}) {  // the backward difference where forward is inadmissible
        yp[static_cast<size_t>(c)] = yg[c] + sign * h;
        unpack(yp.data(), s);
        if (slip_rates_checked(s, sr).why) continue;
        grain_derivative(s, sr, yp.data(), l_, fp.data());
        for (int r = 0; r < m; ++r) j(r, c) = (fp[static_cast<size_t>(r)] - f0[r]) / (sign * h);
        ok = true;
        break;
      }
      yp[static_cast<size_t>(c)] = yg[c];
      if (!ok) return false;
    }
    return true;
  }

  int record_failure(double t) {
    ++rejected_;
    const int g = failed_grain_;
    const auto& f = failures_[static_cast<size_t>(g)];
    std::ostringstream msg;
    msg << "grain " << g << ", slip system " << f.system << ": " << f.why << " at time " << t;
    if (f.system >= 0) {
      const State& s = states_[static_cast<size_t>(g)];
      const auto& sr = slips_[static_cast<size_t>(g)];
      msg << " (mu = " << s.mu(f.system) << ", r = " << sr.r(f.system)
          << ", r_s = " << s.r_s(f.system) << ", slip = " << s.slip(f.system) << ")";
    }
    failure_ = msg.str();
    return 1;
  }

  Mat3 macro_stress(const double* y) const {
    Vec6 sum = Vec6::Zero();
    for (int g = 0; g < grains_; ++g) {
      const double* yg = y + g * grain_size_;
      const Mat3 gm = Eigen::Map<const RowMat3>(yg + 6);
      const Mat3 sample =
          gm.transpose() * crystal::symmetric_from_mandel(Eigen::Map<const Vec6>(yg)) * gm;
      sum += weights_[static_cast<size_t>(g)] * crystal::mandel_from_symmetric(sample);
    }
    return crystal::symmetric_from_mandel(sum);
  }

  // GrainFields over the state view_ (the slip rates are those of the last rhs, at view_).
  void values(crystal::GrainField f, double* out) const override {
    switch (f) {
      case crystal::GrainField::stress:
        return stress(out);
      case crystal::GrainField::orientation:
        return orientation(out);
      case crystal::GrainField::slip:
        return slip(out);
      case crystal::GrainField::slip_rate:
        return slip_rate(out);
      case crystal::GrainField::crss:
        return crss(out);
      case crystal::GrainField::strength:
        return strength(out);
      case crystal::GrainField::r:
        return ratio(out);
      case crystal::GrainField::r_s:
        return subloading_ratio(out);
      case crystal::GrainField::tau:
        return resolved_shear(out);
    }
  }
  template <class F>
  void per_system(double* out, F&& f) const {
    for (int g = 0; g < grains_; ++g)
      for (int a = 0; a < n_; ++a) out[g * n_ + a] = f(g, a);
  }
  void stress(double* out) const {
    for (int g = 0; g < grains_; ++g) {
      const double* yg = view_ + g * grain_size_;
      const Mat3 gm = Eigen::Map<const RowMat3>(yg + 6);
      const Mat3 t =
          gm.transpose() * crystal::symmetric_from_mandel(Eigen::Map<const Vec6>(yg)) * gm;
      const double v[6] = {t(0, 0), t(1, 1), t(2, 2), t(1, 2), t(0, 2), t(0, 1)};
      std::copy(v, v + 6, out + 6 * g);
    }
  }
  void orientation(double* out) const {
    for (int g = 0; g < grains_; ++g)
      std::copy(view_ + g * grain_size_ + 6, view_ + g * grain_size_ + 15, out + 9 * g);
  }
  void slip(double* out) const {
    per_system(out, [&](int g, int a) { return view_[g * grain_size_ + slip_at(a)]; });
  }
  void slip_rate(double* out) const {
    per_system(out, [&](int g, int a) { return slips_[static_cast<size_t>(g)].rate(a); });
  }
  void crss(double* out) const {
    per_system(out,
               [&](int g, int a) { return view_[g * grain_size_ + mu_at(a)] * phase_.tau0(a); });
  }
  void strength(double* out) const {  // mu f_n, f_n = tau0 - M : sigma (lattice frame)
    for (int g = 0; g < grains_; ++g) {
      const double* yg = view_ + g * grain_size_;
      VecN fn = phase_.tau0;
      if (phase_.pressure_sensitive)
        fn -= phase_.plane_normal_dyad.transpose() * Eigen::Map<const Vec6>(yg);
      for (int a = 0; a < n_; ++a) out[g * n_ + a] = yg[mu_at(a)] * fn(a);
    }
  }
  void ratio(double* out) const {
    per_system(out, [&](int g, int a) { return slips_[static_cast<size_t>(g)].r(a); });
  }
  void resolved_shear(double* out) const {  // stress in the lattice frame (Mandel, first 6)
    for (int g = 0; g < grains_; ++g) {
      const VecN tau = phase_.schmid.transpose() * Eigen::Map<const Vec6>(view_ + g * grain_size_);
      for (int a = 0; a < n_; ++a) out[g * n_ + a] = tau(a);
    }
  }
  void subloading_ratio(double* out) const {
    per_system(out, [&](int g, int a) {
      return std::min(states_[static_cast<size_t>(g)].r_s(a), slips_[static_cast<size_t>(g)].r(a));
    });
  }

  crystal::Phase<N> phase_;
  VecN initial_mu_;
  int n_, grain_size_, grains_;
  std::vector<detail::SubloadingVariable> z_;  // per slip system
  std::vector<Mat3> orientations_;
  std::vector<double> weights_;
  // Segment.
  std::vector<FreeComponent> free_;
  Mat3 prescribed_ = Mat3::Zero();
  FreeVector target_rate_;
  // Per-grain scratch of the last right-hand side.
  std::vector<State> states_;
  std::vector<crystal::SlipRates<N>> slips_;
  std::vector<GrainFailure> failures_;
  std::vector<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxFree, kMaxFree + 1>>
      parts_;
  crystal::SlipRates<N> zero_;
  Mat3 l_ = Mat3::Zero();
  int failed_grain_ = -1;
  std::string failure_;
  long rejected_ = 0, jacobians_ = 0;
  // Preconditioner.
  std::vector<Eigen::MatrixXd> blocks_;
  std::vector<Eigen::PartialPivLU<Eigen::MatrixXd>> lu_;
  std::vector<double> scratch_;
  const double* view_ = nullptr;
};

// What the solver calls (plain arrays; detail::Solver adapts CVODE's vectors).
template <int N>
struct Callbacks {
  explicit Callbacks(TaylorOde<N>& o) : ode(&o) {}
  TaylorOde<N>* ode;
  detail::Solver* solver = nullptr;

  static int rhs(double t, const double* y, double* ydot, void* self) {
    return static_cast<Callbacks*>(self)->ode->rhs(t, y, ydot);
  }
  static int setup(double t, const double* y, bool jok, bool& recomputed, double gamma,
                   void* self) {
    auto& c = *static_cast<Callbacks*>(self);
    return c.ode->preconditioner_setup(t, y, jok, recomputed, gamma, c.solver->error_weights());
  }
  static void solve(const double* r, double* z, void* self) {
    static_cast<Callbacks*>(self)->ode->preconditioner_solve(r, z);
  }
};

template <int N>
crystal::AggregateStats run(crystal::BuiltPhase<N> built,
                            const std::vector<crystal::Orientation>& grains,
                            const std::vector<crystal::LoadSegment>& segments,
                            const CvodeOptions& options, const crystal::MacroObserver& observe,
                            CvodeStats& cv) {
  TaylorOde<N> ode(std::move(built), grains);
  Callbacks<N> callbacks(ode);
  const bool krylov = options.linear_solver == LinearSolver::krylov ||
                      (options.linear_solver == LinearSolver::automatic && ode.grain_count() > 1);
  detail::Solver solver(ode.size(), &Callbacks<N>::rhs, &callbacks, options,
                        ode.absolute_tolerances(options.atol_scale), krylov,
                        {&Callbacks<N>::setup, &Callbacks<N>::solve});
  callbacks.solver = &solver;
  double* y = solver.state();
  ode.initial_state(y);

  auto fail = [&](const std::string& where) {
    std::ostringstream msg;
    msg << "CVODE failed " << where << ": " << solver.message();
    if (!ode.failure().empty()) msg << " (last rejected state: " << ode.failure() << ")";
    throw CvodeFailure(msg.str());
  };
  crystal::AggregateStats stats;
  double t = 0.0;
  for (size_t k = 0; k < segments.size(); ++k) {
    const auto& seg = segments[k];
    ode.set_segment(seg, y);
    if (k == 0 && !ode.observe(t, -1, y, observe, true)) fail("at the initial state");
    const double t_end = t + seg.duration;
    std::vector<double> outputs = detail::output_times(
        t, crystal::increment_lengths(seg.duration, seg.increments, seg.growth), seg.output_every);
    outputs.back() = t_end;
    stats.increments += seg.increments;
    if (seg.duration > 0.0) solver.restart(t, t_end);
    const int index = static_cast<int>(k);
    std::vector<double> step_state;
    std::function<void(double, const double*)> on_step;
    if (options.report_every_step) {
      on_step = [&](double ts, const double* state) {
        step_state.assign(state, state + ode.size());  // observe() evaluates at this state
        if (!ode.observe(ts, index, step_state.data(), observe, false))
          fail("evaluating a step in segment " + std::to_string(k));
      };
    }
    for (double t_out : outputs) {
      if (seg.duration > 0.0 && !solver.integrate_to(t_out, on_step))
        fail("in segment " + std::to_string(k) + " before time " + std::to_string(t_out));
      if (!ode.observe(t_out, index, y, observe, false))
        fail("at an output of segment " + std::to_string(k));
    }
    solver.add_counters(cv);
    t = t_end;
  }
  if (segments.empty() && !ode.observe(t, -1, y, observe, true)) fail("at the initial state");
  cv.recoverable_rhs_failures = ode.rejected();
  if (krylov) cv.jacobian_evaluations = ode.jacobians();
  const long g = ode.grain_count();
  stats.substeps = cv.steps;
  stats.grain_steps = cv.steps * g;
  stats.grain_solves = cv.rhs_evaluations * g;
  stats.newton_iterations = cv.nonlinear_iterations;
  stats.cutbacks = cv.error_test_failures + cv.nonlinear_convergence_failures;
  return stats;
}

}  // namespace

crystal::AggregateStats run_taylor_aggregate(const crystal::PhaseDescription& phase,
                                             const std::vector<crystal::Orientation>& grains,
                                             const std::vector<crystal::LoadSegment>& segments,
                                             const CvodeOptions& options,
                                             const crystal::MacroObserver& observe,
                                             CvodeStats* cvode_stats) {
  const auto start = std::chrono::steady_clock::now();
  CvodeStats cv;
  crystal::AggregateStats stats = crystal::visit_phase(phase, [&](auto built) {
    return run(std::move(built), grains, segments, options, observe, cv);
  });
  cv.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  stats.wall_seconds = cv.wall_seconds;
  if (cvode_stats) *cvode_stats = cv;
  return stats;
}

}  // namespace subslip::cvode
