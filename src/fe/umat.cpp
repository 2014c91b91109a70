// umat_: one increment of a single crystal or a Taylor aggregate at one integration point,
// through the material-point API (GrainPoint, TaylorPoint). Nothing is written to STRESS,
// STATEV or DDSDDE before the whole increment has succeeded.
#include <algorithm>
#include <stdexcept>
#include <string>

#include "abaqus_order.hpp"
#include "export.hpp"
#include "grain_increment.hpp"
#include "messages.hpp"
#include "subslip/fe/abaqus.h"
#include "subslip/fe/umat_layout.h"

namespace subslip::fe {

namespace {

std::string where(const int* noel, const int* npt) {
  return "element " + std::to_string(noel ? *noel : 0) + ", point " +
         std::to_string(npt ? *npt : 0) + ": ";
}

void check_dimensions(int ndi, int nshr, int ntens) {
  if (ndi != 3 || (nshr != 3 && nshr != 1) || ntens != ndi + nshr)
    throw std::invalid_argument("NDI = " + std::to_string(ndi) + ", NSHR = " +
                                std::to_string(nshr) + ", NTENS = " + std::to_string(ntens) +
                                ": only three direct components with three shears (3D) or one "
                                "(plane strain, axisymmetry) are offered");
}

struct UmatIo {
  double* stress;
  double* statev;
  double* ddsdde;
  const double* dstran;
  double dtime;
  int ntens;
  int nstatv;
  const double* props;
  int nprops;
  const double* dfgrd0;
  const double* dfgrd1;
  double* sse;
  double* spd;
  double* scd;
};

// Abaqus' Jacobian under NLGEOM is that of the Kirchhoff stress per unit current volume,
// (1/J) d tau / d eps under F1 -> (I + d eps) F1: with tau = J sigma and dJ = J tr(d eps) it is
// d sigma / d eps + sigma (x) I.
point::Matrix6 kirchhoff_jacobian(const point::Matrix6& d_sigma, const point::Mandel6& sigma) {
  point::Mandel6 identity = point::Mandel6::Zero();
  identity.head<3>().setOnes();
  return d_sigma + sigma * identity.transpose();
}

void umat_increment(const UmatIo& io) {
  const auto material = umat_material(io.props, io.nprops);
  const UmatMaterial& m = *material;
  if (io.nstatv < m.statev_count)
    throw std::invalid_argument("NSTATV = " + std::to_string(io.nstatv) + ": these PROPS need " +
                                std::to_string(m.statev_count) + " (1 + grains x (16 + 6 x " +
                                std::to_string(m.slip_count) + " slip systems), docs/fe.md)");
  Kinematics k;
  if (m.finite_strain) {
    const Eigen::Map<const Eigen::Matrix3d> f0(io.dfgrd0), f1(io.dfgrd1);  // column major
    k = finite_strain_kinematics(f0, f1, io.dtime);
  } else {
    const Eigen::Matrix3d e = strain_from_abaqus(io.dstran, io.ntens);
    if (!e.allFinite()) throw std::invalid_argument("DSTRAN is not finite");
    k = small_strain_kinematics(e, io.dtime);
  }
  // The new state goes to a copy of STATEV: nothing changes unless the increment is taken.
  std::vector<double> statev(io.statev, io.statev + m.statev_count);
  const GrainIncrement r = grain_increment(m, statev.data(), k, io.dtime);
  std::copy(statev.begin(), statev.end(), io.statev);
  to_abaqus_stress(r.stress, io.ntens, io.stress);
  to_abaqus_tangent(m.finite_strain ? kirchhoff_jacobian(r.tangent, r.stress) : r.tangent, io.ntens,
                    io.ddsdde);
  if (io.sse) *io.sse = r.energies.elastic;
  if (io.spd) *io.spd += r.energies.plastic;
  if (io.scd) *io.scd += r.energies.viscous;
}

}  // namespace

}  // namespace subslip::fe

SUBSLIP_FE_EXPORT void umat_(double* stress, double* statev, double* ddsdde, double* sse,
                             double* spd, double* scd, double* /*rpl*/, double* /*ddsddt*/,
                             double* /*drplde*/, double* /*drpldt*/, const double* /*stran*/,
                             const double* dstran, const double* /*time*/, const double* dtime,
                             const double* /*temp*/, const double* /*dtemp*/,
                             const double* /*predef*/, const double* /*dpred*/,
                             const char* /*cmname*/, const int* ndi, const int* nshr,
                             const int* ntens, const int* nstatv, const double* props,
                             const int* nprops, const double* /*coords*/, const double* /*drot*/,
                             double* pnewdt, const double* /*celent*/, const double* dfgrd0,
                             const double* dfgrd1, const int* noel, const int* npt,
                             const int* /*layer*/, const int* /*kspt*/, const int* /*jstep*/,
                             const int* /*kinc*/, size_t /*cmname_length*/) {
  namespace fe = subslip::fe;
  fe::clear_message();
  try {
    fe::check_dimensions(*ndi, *nshr, *ntens);
    fe::umat_increment({stress, statev, ddsdde, dstran, *dtime, *ntens, *nstatv, props, *nprops,
                        dfgrd0, dfgrd1, sse, spd, scd});
  } catch (const std::exception& e) {
    fe::refuse("umat", fe::where(noel, npt) + e.what());
    *pnewdt = std::min(*pnewdt, 0.5);
  } catch (...) {
    fe::refuse("umat", fe::where(noel, npt) + "unknown failure");
    *pnewdt = std::min(*pnewdt, 0.5);
  }
}

// The same entry point under the names other compilers and conventions give it.
SUBSLIP_FE_EXPORT decltype(umat_) umat __attribute__((alias("umat_")));
SUBSLIP_FE_EXPORT decltype(umat_) UMAT __attribute__((alias("umat_")));

SUBSLIP_FE_EXPORT int subslip_fe_umat_statev_count(const double* props, int nprops) {
  namespace fe = subslip::fe;
  fe::clear_message();
  try {
    return fe::umat_material(props, nprops)->statev_count;
  } catch (const std::exception& e) {
    fe::refuse("umat", e.what());
    return 0;
  }
}
