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
  k.none = f0 == f1;
  if (k.none) return k;
  const Eigen::Matrix3d df = f1 * f0.inverse();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(df.transpose() * df);
  const Eigen::Vector3d stretch = eigen.eigenvalues().cwiseSqrt();
  const Eigen::Matrix3d& v = eigen.eigenvectors();
  const Eigen::Matrix3d log_u = v * stretch.array().log().matrix().asDiagonal() * v.transpose();
  k.rotation = df * v * stretch.cwiseInverse().asDiagonal() * v.transpose();
  if (dt > 0.0) k.l = log_u / dt;
  return k;
}

std::shared_ptr<const UmatMaterial> umat_material(const double* props, int nprops) {
  static MaterialCache<UmatMaterial> cache;
  if (nprops < 1 || !props) throw std::invalid_argument("NPROPS < 1: no PROPS");
  return cache.get(props, nprops, make_umat_material);
}

namespace {

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
    if (!k.rotation.isIdentity(0.0)) {
      for (point::GrainState& s : grains) s.orientation = s.orientation * k.rotation.transpose();
      const point::Matrix6 q = cr::mandel_rotation_operator(k.rotation);
      out.stress = q * out.stress;
      out.tangent = q * out.tangent * q.transpose();
    }
  }
  if (!out.stress.allFinite() || !out.tangent.allFinite())
    throw std::runtime_error("the increment gave a stress or tangent that is not finite");
  statev[SUBSLIP_UMAT_MARKER - 1] = 1.0;
  const auto block = static_cast<std::size_t>(grain_block(m.slip_count));
  for (std::size_t g = 0; g < grains.size(); ++g) pack_grain(grains[g], statev + 1 + g * block);
  return out;
}

}  // namespace subslip::fe
