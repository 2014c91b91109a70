// Test helper: one integration point driven through umat_ (the C ABI of libsubslip_fe), as an
// FE code calls it, and the material of the FE tests in both forms (PROPS, and the native
// parameters of the material-point API built independently from the same numbers).
#pragma once

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/LU>
#include <array>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "subslip/fe/abaqus.h"
#include "subslip/fe/umat_layout.h"
#include "subslip/material_point.hpp"

namespace subslip::fe_testing {

namespace pt = subslip::point;
namespace cr = subslip::crystal;

// Copper with the law of the material-point tests [MPa, s].
constexpr double kC11 = 168400, kC12 = 121400, kC44 = 75400, kTau0 = 10.0;

inline std::vector<double> fcc_props(const Eigen::Vector3d& euler_degrees) {
  std::vector<double> p(SUBSLIP_UMAT_SINGLE_NPROPS, 0.0);
  auto set = [&](int index, double v) { p[static_cast<std::size_t>(index - 1)] = v; };
  set(SUBSLIP_UMAT_POINT, 1);
  set(SUBSLIP_UMAT_STRAIN, 0);
  set(SUBSLIP_UMAT_LATTICE, 1);
  set(SUBSLIP_UMAT_C11, kC11);
  set(SUBSLIP_UMAT_C12, kC12);
  set(SUBSLIP_UMAT_C44, kC44);
  set(SUBSLIP_UMAT_TAU0, kTau0);
  set(SUBSLIP_UMAT_MU_S, 1.0);
  set(SUBSLIP_UMAT_MU_K, 3.0);
  set(SUBSLIP_UMAT_KAPPA, 5.0);
  set(SUBSLIP_UMAT_XI, 0.0);
  set(SUBSLIP_UMAT_U_FUNCTION, 1);
  set(SUBSLIP_UMAT_U_TILDE, 200.0);
  set(SUBSLIP_UMAT_OVERSTRESS, 1);
  set(SUBSLIP_UMAT_ETA_V, 1.0e-3);
  set(SUBSLIP_UMAT_N, 16.0);
  set(SUBSLIP_UMAT_R_HAT, 1.6);
  set(SUBSLIP_UMAT_PHI1, euler_degrees(0));
  set(SUBSLIP_UMAT_PHI, euler_degrees(1));
  set(SUBSLIP_UMAT_PHI2, euler_degrees(2));
  return p;
}

// The same material for the material-point API.
inline pt::GrainParameters fcc_parameters() {
  pt::GrainParameters d;
  cr::SlipGroupSettings g;
  g.tau0 = kTau0;
  g.law.friction = {1.0, 3.0, 5.0, 0.0};
  g.law.subloading = {subslip::law::SubloadingFunction::cot, 200.0};
  g.law.overstress = {subslip::law::OverstressForm::exponential, 1.0e-3, 16.0, 1.6};
  d.families = {cr::SlipFamily::fcc_111_110};
  d.family_settings = {g};
  d.stiffness = cr::cubic_stiffness(kC11, kC12, kC44);
  return d;
}

// A Taylor aggregate of three FCC grains of unequal weights, small strain.
inline std::vector<double> taylor_fcc_props() {
  const std::array<std::array<double, 3>, 3> euler = {{{0, 0, 0}, {30, 40, 50}, {80, 20, 10}}};
  const std::array<double, 3> weights = {1.0, 2.0, 0.5};
  std::vector<double> props = fcc_props({0, 0, 0});
  props.resize(SUBSLIP_UMAT_TAYLOR_NPROPS(3));
  props[SUBSLIP_UMAT_POINT - 1] = 2;
  props[SUBSLIP_UMAT_TAYLOR_GRAINS - 1] = 3;
  for (std::size_t g = 0; g < 3; ++g) {
    for (std::size_t i = 0; i < 3; ++i) props[SUBSLIP_UMAT_TAYLOR_GRAINS + 4 * g + i] = euler[g][i];
    props[SUBSLIP_UMAT_TAYLOR_GRAINS + 4 * g + 3] = weights[g];
  }
  return props;
}

inline Eigen::Matrix3d orientation_of(const Eigen::Vector3d& euler_degrees) {
  return cr::Orientation::from_euler(cr::degrees_to_radians(euler_degrees)).g;
}

// One integration point: its STRESS, STATEV and DDSDDE between calls, 3D (NTENS = 6) unless
// told otherwise.
struct UmatPoint {
  std::vector<double> props;
  std::vector<double> statev;
  std::array<double, 6> stress{};
  std::array<double, 36> ddsdde{};
  double sse = 0, spd = 0, scd = 0;  // as Abaqus passes them: the values so far
  int ndi = 3, nshr = 3;
  int noel = 1, npt = 1;
  std::array<double, 9> dfgrd0{1, 0, 0, 0, 1, 0, 0, 0, 1};  // column major
  std::array<double, 9> dfgrd1{1, 0, 0, 0, 1, 0, 0, 0, 1};

  explicit UmatPoint(std::vector<double> p, int nstatv = -1) : props(std::move(p)) {
    const int needed = subslip_fe_umat_statev_count(props.data(), static_cast<int>(props.size()));
    statev.assign(static_cast<std::size_t>(nstatv >= 0 ? nstatv : needed), 0.0);
  }

  // One increment; returns PNEWDT (1 when the increment was taken).
  double call(const std::array<double, 6>& dstran, double dtime) {
    std::array<double, 6> stran{};
    double rpl = 0, drpldt = 0, temp = 293, dtemp = 0, celent = 1;
    std::array<double, 6> ddsddt{}, drplde{};
    std::array<double, 2> time{0.0, 0.0};
    std::array<double, 1> predef{}, dpred{};
    std::array<double, 3> coords{};
    std::array<double, 9> drot{1, 0, 0, 0, 1, 0, 0, 0, 1};
    double pnewdt = 1.0;
    const int ntens = ndi + nshr, nstatv = static_cast<int>(statev.size());
    const int nprops = static_cast<int>(props.size()), layer = 1, kspt = 1, kinc = 1;
    const std::array<int, 4> jstep{1, 0, 1, 0};
    char cmname[80];
    std::memset(cmname, ' ', sizeof cmname);
    umat_(stress.data(), statev.data(), ddsdde.data(), &sse, &spd, &scd, &rpl, ddsddt.data(),
          drplde.data(), &drpldt, stran.data(), dstran.data(), time.data(), &dtime, &temp, &dtemp,
          predef.data(), dpred.data(), cmname, &ndi, &nshr, &ntens, &nstatv, props.data(), &nprops,
          coords.data(), drot.data(), &pnewdt, &celent, dfgrd0.data(), dfgrd1.data(), &noel, &npt,
          &layer, &kspt, jstep.data(), &kinc, sizeof cmname);
    return pnewdt;
  }

  double ddsdde_at(int i, int j) const {
    const int ntens = ndi + nshr;
    return ddsdde[static_cast<std::size_t>(i + ntens * j)];
  }
};

inline std::string last_message() {
  char buffer[512];
  subslip_fe_last_message(buffer, sizeof buffer);
  return buffer;
}

// Abaqus component a is Mandel component kMandel[a]; a Mandel entry is kScale[a] times the
// Abaqus stress, an engineering strain kScale[a] times the Mandel entry.
inline constexpr std::array<int, 6> kMandel = {0, 1, 2, 5, 4, 3};
inline const std::array<double, 6> kScale = {
    1, 1, 1, std::sqrt(2.0), std::sqrt(2.0), std::sqrt(2.0)};

// STRESS order (11 22 33 12 13 23) of a Mandel vector.
inline std::array<double, 6> abaqus_stress(const pt::Mandel6& m) {
  const Eigen::Matrix3d t = cr::symmetric_from_mandel(m);
  return {t(0, 0), t(1, 1), t(2, 2), t(0, 1), t(0, 2), t(1, 2)};
}

// The velocity gradient of an engineering strain increment over dt.
inline Eigen::Matrix3d rate_of(const std::array<double, 6>& dstran, double dt) {
  Eigen::Matrix3d e;
  e << dstran[0], dstran[3] / 2, dstran[4] / 2, dstran[3] / 2, dstran[1], dstran[5] / 2,
      dstran[4] / 2, dstran[5] / 2, dstran[2];
  return e / dt;
}

// The same with the material-point API, in Mandel components (lateral: all but 33).
inline pt::GrainUpdate native_uniaxial_step(const pt::GrainPoint& grain, const pt::GrainState& s,
                                            double d33, double dt) {
  constexpr std::array<int, 5> lateral = {0, 1, 3, 4, 5};  // Mandel components
  pt::Mandel6 e = pt::Mandel6::Zero();
  e(2) = d33;
  for (int it = 0; it < 30; ++it) {
    const pt::GrainUpdate u = grain.update(s, cr::symmetric_from_mandel(e) / dt, dt);
    EXPECT_TRUE(u.report.ok) << u.report.why;
    Eigen::Matrix<double, 5, 1> r;
    Eigen::Matrix<double, 5, 5> j;
    for (int a = 0; a < 5; ++a) {
      r(a) = u.stress(lateral[a]);
      for (int b = 0; b < 5; ++b) j(a, b) = u.tangent(lateral[a], lateral[b]);
    }
    if (r.norm() <= 1e-11 * std::abs(u.stress(2))) return u;
    const Eigen::Matrix<double, 5, 1> step = j.partialPivLu().solve(r);
    for (int a = 0; a < 5; ++a) e(lateral[a]) -= step(a);
  }
  ADD_FAILURE() << "the native Newton iteration on the lateral strains did not converge";
  return {};
}

}  // namespace subslip::fe_testing
