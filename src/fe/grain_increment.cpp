#include "grain_increment.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "material_cache.hpp"
#include "subslip/crystal/elasticity.hpp"
#include "subslip/fe/umat_layout.h"

namespace subslip::fe {

namespace cr = subslip::crystal;

Kinematics small_strain_kinematics(const Eigen::Matrix3d& e, double dt) {
  if (!e.allFinite()) throw std::invalid_argument("the strain increment is not finite");
  Kinematics k;
  k.none = e.isZero(0.0);
  if (dt > 0.0) k.l = e / dt;
  return k;
}

// The relative deformation dF = F1 F0^-1 = R U (polar). The grains stretch by log(U) over the
// increment (in the configuration at its start) and then turn with R: a rotation superposed on
// the motion turns the lattice with it and leaves everything in the lattice frame as it was
// (incremental objectivity, exact for any size of rotation).
Kinematics finite_strain_kinematics(const Eigen::Matrix3d& f0, const Eigen::Matrix3d& f1,
                                    double dt) {
  if (!f0.allFinite() || !f1.allFinite())
    throw std::invalid_argument("a deformation gradient is not finite");
  if (!(f0.determinant() > 0.0) || !(f1.determinant() > 0.0))
    throw std::invalid_argument("a deformation gradient has a determinant <= 0");
  Kinematics k;
  k.finite = true;
  k.none = f0 == f1;
  if (k.none) return k;
  const Eigen::Matrix3d df = f1 * f0.inverse();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(df.transpose() * df);
  const Eigen::Vector3d stretch = eigen.eigenvalues().cwiseSqrt();
  const Eigen::Matrix3d& v = eigen.eigenvectors();
  const Eigen::Matrix3d log_u = v * stretch.array().log().matrix().asDiagonal() * v.transpose();
  k.rotation = df * v * stretch.cwiseInverse().asDiagonal() * v.transpose();
  k.stretch = stretch;
  k.stretch_axes = v;
  if (dt > 0.0) k.l = log_u / dt;
  return k;
}

std::shared_ptr<const UmatMaterial> umat_material(const double* props, int nprops) {
  static MaterialCache<UmatMaterial> cache;
  if (nprops < 1 || !props) throw std::invalid_argument("NPROPS < 1: no PROPS");
  return cache.get(props, nprops, make_umat_material);
}

namespace {

// (log a - log b) / (a - b), 1/a where a = b: accurate for close stretches (log1p).
double log_divided_difference(double a, double b) {
  if (a == b) return 1.0 / a;
  const double x = (a - b) / b;
  return std::log1p(x) / (x * b);
}

// The exact derivative of the finite-strain increment sigma1 = R sigma(log U) R^T under
// F1 -> (I + e) F1, e symmetric (docs/fe.md): the relative deformation becomes
// R (I + A) U, A = R^T e R, whose polar parts change by d(U^2) = 2 U A U and
// R^T dR = A - dU U^-1. In the principal axes of U (stretches l_a):
//   d(log U)_ab = A_ab 2 l_a l_b / (l_a + l_b) (log l_a - log l_b) / (l_a - l_b)  (A_aa at a = b)
//   (R^T dR)_ab = A_ab (l_b - l_a) / (l_a + l_b)
// and d sigma1 = R (T : d(log U) + Omega sigma - sigma Omega) R^T, Omega = R^T dR, with T the
// grain update's d sigma / d(D dt) and sigma its stress, both before the rotation R.
point::Matrix6 finite_increment_tangent(const Kinematics& k, const point::Mandel6& stress,
                                        const point::Matrix6& t) {
  const Eigen::Matrix3d& r = k.rotation;
  const Eigen::Matrix3d& v = k.stretch_axes;
  const Eigen::Vector3d& l = k.stretch;
  Eigen::Matrix3d log_factor, spin_factor;  // multiply A_ab in the principal axes
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) {
      log_factor(a, b) =
          a == b ? 1.0 : 2.0 * l(a) * l(b) / (l(a) + l(b)) * log_divided_difference(l(a), l(b));
      spin_factor(a, b) = (l(b) - l(a)) / (l(a) + l(b));
    }
  const Eigen::Matrix3d sigma = cr::symmetric_from_mandel(stress);
  point::Matrix6 out;
  for (int c = 0; c < 6; ++c) {
    const Eigen::Matrix3d e = cr::symmetric_from_mandel(point::Mandel6::Unit(c));
    const Eigen::Matrix3d a = v.transpose() * (r.transpose() * e * r) * v;
    const Eigen::Matrix3d d_log_u = v * a.cwiseProduct(log_factor) * v.transpose();
    const Eigen::Matrix3d omega = v * a.cwiseProduct(spin_factor) * v.transpose();
    const Eigen::Matrix3d d_sigma =
        cr::symmetric_from_mandel(t * cr::mandel_from_symmetric(d_log_u)) + omega * sigma -
        sigma * omega;
    out.col(c) = cr::mandel_from_symmetric(r * d_sigma * r.transpose());
  }
  return out;
}

// tau_a = P_a : sigma, and the part of it the static resistance carries, sign(tau) r_s mu tau0
// (all of it for the rate-independent form, which has no overstress).
struct SystemStress {
  double total, statical;
};

SystemStress system_stress(const UmatMaterial& m, const point::GrainState& s, int a) {
  const auto i = static_cast<std::size_t>(a);
  const double tau = m.schmid[i].dot(s.stress);
  if (!m.viscous[i]) return {tau, tau};
  const double sign = tau > 0.0 ? 1.0 : (tau < 0.0 ? -1.0 : 0.0);
  return {tau, sign * s.r_s(a) * s.mu(a) * m.tau0[i]};
}

// The grains' elastic energy at the end and the increment's dissipation: on each system the
// trapezoid of tau over the slip increment, so that with sigma1 = sigma0 + C (de - P dgamma)
// (the grain step's stress) the work 1/2 (sigma0 + sigma1) : de is the elastic energy's change
// plus the dissipation, to rounding.
IncrementEnergies increment_energies(const UmatMaterial& m,
                                     const std::vector<point::GrainState>& before,
                                     const std::vector<point::GrainState>& after) {
  IncrementEnergies e;
  for (std::size_t g = 0; g < after.size(); ++g) {
    const point::GrainState& s0 = before[g];
    const point::GrainState& s1 = after[g];
    double plastic = 0.0, viscous = 0.0;
    for (int a = 0; a < m.slip_count; ++a) {
      const double dgamma = s1.slip(a) - s0.slip(a);
      if (dgamma == 0.0) continue;
      const SystemStress t0 = system_stress(m, s0, a), t1 = system_stress(m, s1, a);
      plastic += 0.5 * (t0.statical + t1.statical) * dgamma;
      viscous += 0.5 * ((t0.total - t0.statical) + (t1.total - t1.statical)) * dgamma;
    }
    e.elastic += m.weights[g] * 0.5 * s1.stress.dot(m.lattice_compliance * s1.stress);
    e.plastic += m.weights[g] * plastic;
    e.viscous += m.weights[g] * viscous;
  }
  return e;
}

// The elastic stiffness of the grains (weighted), sample frame, Mandel: the response over an
// increment of no time.
point::Matrix6 elastic_tangent(const UmatMaterial& m,
                               const std::vector<point::GrainState>& grains) {
  point::Matrix6 c = point::Matrix6::Zero();
  for (std::size_t g = 0; g < grains.size(); ++g)
    c += m.weights[g] * cr::stiffness_in_sample_frame(m.lattice_stiffness, grains[g].orientation);
  return c;
}

std::vector<point::GrainState> read_grains(const UmatMaterial& m, const double* statev) {
  const double marker = statev[SUBSLIP_UMAT_MARKER - 1];
  std::vector<point::GrainState> grains;
  if (marker == 0.0) {
    for (const Eigen::Matrix3d& g : m.orientations)
      grains.push_back(m.grain_point().initial_state(g));
  } else if (marker == 1.0) {
    const auto block = static_cast<std::size_t>(grain_block(m.slip_count));
    for (std::size_t g = 0; g < m.orientations.size(); ++g)
      grains.push_back(unpack_grain(statev + 1 + g * block, m.slip_count));
  } else {
    throw std::invalid_argument("STATEV(1) (Initialised) = " + std::to_string(marker) +
                                ": 0 before the first increment, 1 after (docs/fe.md)");
  }
  return grains;
}

}  // namespace

GrainIncrement grain_increment(const UmatMaterial& m, double* statev, const Kinematics& k,
                               double dt) {
  if (!std::isfinite(dt) || dt < 0.0)
    throw std::invalid_argument("the time increment is " + std::to_string(dt));
  std::vector<point::GrainState> grains = read_grains(m, statev);
  const std::vector<point::GrainState> before = grains;
  GrainIncrement out;
  if (dt == 0.0) {
    if (!k.none)
      throw std::invalid_argument(
          "a deformation over no time (DTIME = 0): the law is rate "
          "dependent");
    out.tangent = elastic_tangent(m, grains);
    out.stress = point::Mandel6::Zero();
    for (std::size_t g = 0; g < grains.size(); ++g)
      out.stress += m.weights[g] * grains[g].sample_stress();
  } else {
    point::SolveReport report;
    if (m.taylor) {
      point::TaylorUpdate u = m.aggregate->update({grains}, k.l, dt);
      report = std::move(u.report);
      grains = std::move(u.state.grains);
      out.stress = u.stress;
      out.tangent = u.tangent;
    } else {
      point::GrainUpdate u = m.grain->update(grains[0], k.l, dt);
      report = std::move(u.report);
      grains[0] = std::move(u.state);
      out.stress = u.stress;
      out.tangent = u.tangent;
    }
    if (!report.ok)
      throw std::runtime_error(
          "the grain solver did not take the increment" +
          (report.grain >= 0 ? " (grain " + std::to_string(report.grain + 1) + ")" : "") + ": " +
          report.why);
    if (k.finite) {
      out.tangent = finite_increment_tangent(k, out.stress, out.tangent);
      for (point::GrainState& s : grains) s.orientation = s.orientation * k.rotation.transpose();
      out.stress = cr::mandel_rotation_operator(k.rotation) * out.stress;
    }
  }
  out.energies = increment_energies(m, before, grains);
  if (!out.stress.allFinite() || !out.tangent.allFinite())
    throw std::runtime_error("the increment gave a stress or tangent that is not finite");
  statev[SUBSLIP_UMAT_MARKER - 1] = 1.0;
  const auto block = static_cast<std::size_t>(grain_block(m.slip_count));
  for (std::size_t g = 0; g < grains.size(); ++g) pack_grain(grains[g], statev + 1 + g * block);
  return out;
}

}  // namespace subslip::fe
