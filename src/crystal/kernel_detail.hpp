// Pieces of the crystal kernel shared by its explicit step (crystal_kernel.cpp) and its implicit
// step (implicit_grain_step.hpp, semismooth_grain_step.cpp). Internal to src/crystal/.
#pragma once

#include <cmath>
#include <limits>

#include "subslip/crystal/crystal_kernel.hpp"
#include "subslip/crystal/rotation.hpp"

namespace subslip::crystal::detail {

inline Vec3 axial(const Mat3& w) {
  return Vec3(w(2, 1), w(0, 2), w(1, 0));
}

inline double sign_of(double v) {
  return v >= 0.0 ? 1.0 : -1.0;
}

// S = L D L^T of a symmetric positive definite 6 x 6 (its lower triangle is read), L unit lower
// triangular: the implicit step's condensed Newton matrix, factored once or twice per grain
// step. Written out because at this size the factorisation is a chain of dependent operations:
// Eigen's LLT<Mat6> takes six square roots and six divisions on that chain (about 4 % of a
// grain step's time, measured), this one six divisions and no root. No pivoting: a positive
// definite matrix needs none (its pivots are the positive D).
class SymmetricFactor6 {
 public:
  void compute(const Mat6& s) {
    for (int j = 0; j < 6; ++j) {
      double ld[6];  // L(j, k) D(k)
      double pivot = s(j, j);
      for (int k = 0; k < j; ++k) {
        ld[k] = l_(j, k) * d_(k);
        pivot -= l_(j, k) * ld[k];
      }
      // A pivot that is not positive: every solve is NaN (as Eigen's LLT, whose root of it is),
      // which the callers' finiteness checks reject.
      const bool positive = pivot > 0.0 && std::isfinite(pivot);
      d_(j) = pivot;
      inverse_d_(j) = positive ? 1.0 / pivot : std::numeric_limits<double>::quiet_NaN();
      for (int i = j + 1; i < 6; ++i) {
        double v = s(i, j);
        for (int k = 0; k < j; ++k) v -= l_(i, k) * ld[k];
        l_(i, j) = v * inverse_d_(j);
      }
    }
  }
  Vec6 solve(const Vec6& b) const {
    Vec6 x = b;
    for (int i = 1; i < 6; ++i)
      for (int k = 0; k < i; ++k) x(i) -= l_(i, k) * x(k);
    x = x.cwiseProduct(inverse_d_);
    for (int i = 4; i >= 0; --i)
      for (int k = i + 1; k < 6; ++k) x(i) -= l_(k, i) * x(k);
    return x;
  }

 private:
  Mat6 l_;
  Vec6 d_, inverse_d_;
};

// Velocity gradient split and expressed in the lattice frame of orientation g.
struct LatticeKinematics {
  Vec6 strain_rate;  // D_lat (Mandel)
  Vec3 spin;         // axial vector of W_lat
};

// The axial vector of W in the lattice frame of orientation g.
inline Vec3 lattice_spin(const Mat3& g, const Mat3& L) {
  const Mat3 w = 0.5 * (L - L.transpose());
  return axial(g * w * g.transpose());
}

inline LatticeKinematics lattice_kinematics(const Mat3& g, const Mat3& L) {
  const Mat3 d = 0.5 * (L + L.transpose());
  return {mandel_from_symmetric(g * d * g.transpose()), lattice_spin(g, L)};
}

// The kinematics of a step. The lattice turns with the total spin W and back with the plastic
// spin; the strain increment is resolved at the orientation halfway through the total spin's
// turn, g_mid = exp(-[w] dt/2) g0 (w: lattice components of W), which is exact to second order
// for a superposed rigid rotation: a rotation of the whole body changes only the orientation,
// not the lattice stress.
struct StepKinematics {
  Vec6 strain_increment;  // D_lat dt at the mid-step orientation (Mandel)
  Vec3 lattice_spin;      // w, axial vector of W_lat
  Mat3 mid_orientation;   // where D was resolved (the tangent needs it)
  Mat3 spun_orientation;  // exp(-[w] dt) g0: the end orientation before the plastic spin
};

inline StepKinematics step_kinematics(const Mat3& g0, const Mat3& L, double dt,
                                      Kinematics kinematics) {
  if (kinematics == Kinematics::small_strain) {
    const LatticeKinematics k = lattice_kinematics(g0, L);
    return {k.strain_rate * dt, k.spin, g0, g0};
  }
  const Vec3 w = lattice_spin(g0, L);
  const Mat3 g_mid = rotation_exp(-0.5 * dt * w) * g0;
  // D alone at g_mid (lattice_kinematics would resolve the spin there too, which the step does
  // not use). The whole turn is its own exponential, not the half turn squared: the same value
  // in exact arithmetic, but the orientations' rounding, and with it the iteration counts the
  // instruction sets are tested to agree on (tests/test_grain_step_isa.cpp), would change.
  const Mat3 d = 0.5 * (L + L.transpose());
  return {mandel_from_symmetric(g_mid * d * g_mid.transpose()) * dt, w, g_mid,
          rotation_exp(-dt * w) * g0};
}

// The end orientation: after the total spin, the lattice turns back by the plastic spin
// W_p = sum_a dgamma_a W_a (lattice components), g1 = exp(+[W_p]) g_spun.
template <int N>
Mat3 orientation_after_plastic_spin(const Phase<N>& ph, const Mat3& g_spun,
                                    const typename SlipTypes<N>::VecN& dgamma) {
  if (ph.kinematics == Kinematics::small_strain) return g_spun;
  return rotation_exp(ph.slip_spin * dgamma) * g_spun;
}

// Normal traction on each slip plane: tau0 alone, or tau0 plus the compressive normal stress.
template <int N>
typename SlipTypes<N>::VecN normal_traction(const Phase<N>& ph, const Vec6& stress) {
  if (!ph.pressure_sensitive) return ph.tau0;
  return ph.tau0 - ph.plane_normal_dyad.transpose() * stress;
}

// r_a = |tau_a| / (mu_a f_n,a); 0 on an open plane (f_n <= 0: no contact, no ratio).
template <int N>
typename SlipTypes<N>::VecN loading_ratio_of(const Phase<N>& ph, const Vec6& stress,
                                             const typename SlipTypes<N>::VecN& mu,
                                             const typename SlipTypes<N>::VecN& fn) {
  const typename SlipTypes<N>::VecN tau = ph.schmid.transpose() * stress;
  typename SlipTypes<N>::VecN r = tau.cwiseAbs().cwiseQuotient(mu.cwiseProduct(fn));
  for (int a = 0; a < ph.slip_count; ++a)
    if (fn(a) <= 0.0) r(a) = 0.0;
  return r;
}

// Open slip planes (f_n <= 0, r = 0) are admissible where the step resolved them (implicit).
enum class OpenPlanes { refused, resolved };

// Whether every test of admissible_state passes, on whole vectors at once (most states are
// admissible; the per-system loop then only has to name the first failing system). Conservative:
// a rate-independent system's r in (1, 1 + flow tolerance] fails here and passes there.
template <int N>
bool plainly_admissible(const Phase<N>& ph, const GrainState<N>& s,
                        const typename SlipTypes<N>::VecN& r, const typename SlipTypes<N>::VecN& fn,
                        OpenPlanes open) {
  // The comparisons are false for NaN, and r < ratio_limit (finite) rejects an infinite r and,
  // through r_s <= r, an infinite r_s.
  return s.mu.allFinite() && s.slip.allFinite() && (s.mu.array() > 0.0).all() &&
         (open == OpenPlanes::resolved || (fn.array() > 0.0).all()) &&
         (s.r_s.array() >= 0.0).all() && (s.r_s.array() <= r.array()).all() &&
         (r.array() < ph.ratio_limit.array()).all();
}

template <int N>
bool admissible_state(const Phase<N>& ph, const GrainState<N>& s,
                      const typename SlipTypes<N>::VecN& r, const typename SlipTypes<N>::VecN& fn,
                      GrainStepReport& rep, OpenPlanes open = OpenPlanes::refused,
                      double flow_tolerance = 0.0) {
  if (!s.stress.allFinite() || !s.orientation.allFinite()) {
    rep.why = "non-finite stress or orientation";
    return false;
  }
  if (plainly_admissible(ph, s, r, fn, open)) return true;
  for (int a = 0; a < ph.slip_count; ++a) {
    const auto& o = ph.laws[static_cast<size_t>(a)].parameters().overstress;
    const bool ri = o.form == law::OverstressForm::rate_independent;
    if (!std::isfinite(s.mu(a)) || !std::isfinite(s.r_s(a)) || !std::isfinite(s.slip(a)) ||
        !std::isfinite(r(a))) {
      rep.why = "non-finite slip-system state", rep.system = a;
      return false;
    }
    if (!(s.mu(a) > 0.0) || (open == OpenPlanes::refused && !(fn(a) > 0.0))) {
      rep.why = "mu <= 0 or slip plane not in compression", rep.system = a;
      return false;
    }
    // The rate-independent form's limit is r = 1: r_s < 1 at any finite slip, reaching 1
    // only in rounding; a saturated system (r_s = 1) carries r = 1 to the flow rule's tolerance.
    if (ri ? r(a) > 1.0 + flow_tolerance : r(a) >= o.r_hat) {
      rep.why = ri ? "r > 1 (rate-independent)" : "r >= r_hat", rep.system = a;
      return false;
    }
    if (s.r_s(a) < 0.0 || s.r_s(a) > r(a)) {
      rep.why = "r_s outside [0, r]", rep.system = a;
      return false;
    }
  }
  return true;
}

// The lattice strain increments of sample strain directions E (Mandel columns), resolved at
// the orientation g the step resolves its strain increment at: g E g^T, column by column.
inline StrainDirections lattice_directions(const StrainDirections& e, const Mat3& g) {
  StrainDirections out(6, e.cols());
  for (int k = 0; k < e.cols(); ++k)
    out.col(k) = mandel_from_symmetric(g * symmetric_from_mandel(e.col(k)) * g.transpose());
  return out;
}

// The consistent tangent d sigma_sample / d(D_sample dt) E of an implicit step's end state s1,
// from the lattice stress and slips' changes along the lattice directions of E
// (lattice_directions at the step's mid orientation). The end orientation depends on the slip
// through the plastic spin: g1 = exp([W_p]) g_spun, dg1 = [dW_p] g1 to first order, and
// sigma_sample = g1^T sigma_lattice g1 changes by dg1^T sigma g1 + g1^T sigma dg1.
template <int N>
Tangent sample_tangent(const Phase<N>& ph, const GrainState<N>& s1, const Tangent& d_sigma_lattice,
                       const SlipTangent<N>& d_dgamma) {
  const Mat3& g1 = s1.orientation;
  const bool spins = ph.kinematics == Kinematics::finite_rotation;
  const Mat3 sigma = spins ? symmetric_from_mandel(s1.stress) : Mat3::Zero();  // read if spins
  Tangent t(6, d_sigma_lattice.cols());
  for (int k = 0; k < t.cols(); ++k) {
    Mat3 change = symmetric_from_mandel(d_sigma_lattice.col(k));
    if (spins) {
      // With dg1 = [dw] g1: d sigma_sample = g1^T (d sigma + sigma [dw] - [dw] sigma) g1, dw =
      // W_p d dgamma the plastic spin's change; for the skew [dw], sigma [dw] - [dw] sigma is
      // sigma [dw] plus its transpose. One turn to the sample frame per column.
      const Vec3 dw = ph.slip_spin * d_dgamma.col(k);
      Mat3 skew;
      skew << 0.0, -dw.z(), dw.y(), dw.z(), 0.0, -dw.x(), -dw.y(), dw.x(), 0.0;
      const Mat3 turn = sigma * skew;
      change += turn + turn.transpose();
    }
    t.col(k) = mandel_from_symmetric(g1.transpose() * change * g1);
  }
  return t;
}

// The tangents along the lattice directions `e_lattice` from a step's full lattice slip
// sensitivity d dgamma / d(lattice strain increment) (N x 6): the stress follows the slips
// through sigma = C (de - P dgamma).
template <int N>
void tangents_from_slip_sensitivity(const Phase<N>& ph, const GrainState<N>& s1,
                                    const typename SlipTypes<N>::MatN6& dgamma_de,
                                    const StrainDirections& e_lattice, Tangent* tangent,
                                    SlipTangent<N>* slip_tangent) {
  const SlipTangent<N> d_dgamma = dgamma_de * e_lattice;
  Tangent d_sigma = ph.stiffness * e_lattice;
  d_sigma.noalias() -= ph.c_schmid * d_dgamma;
  *tangent = sample_tangent(ph, s1, d_sigma, d_dgamma);
  if (slip_tangent) *slip_tangent = d_dgamma;
}

}  // namespace subslip::crystal::detail
