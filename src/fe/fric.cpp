// fric_: one increment of a frictional contact point of the subloading-overstress friction law
// (point::ContactPoint) as Abaqus' user friction: the tangential tractions from the slip
// increments and the contact pressure, their derivatives, the point's state in STATEV. The law
// is elastic-viscoplastic (the tangential stiffness alpha_t carries the sticking), so every
// closed increment is a sliding one for Abaqus (LM = 0, TAU and its derivatives given).
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "export.hpp"
#include "material_cache.hpp"
#include "messages.hpp"
#include "props.hpp"
#include "subslip/fe/abaqus.h"
#include "subslip/fe/fric_layout.h"
#include "subslip/material_point.hpp"

namespace subslip::fe {

namespace {

struct FricMaterial {
  point::ContactPoint point;
  law::LawState initial;
};

FricMaterial make_fric_material(const double* p, int nprops) {
  if (nprops != SUBSLIP_FRIC_NPROPS)
    throw std::invalid_argument("NPROPS = " + std::to_string(nprops) + ": FRIC has " +
                                std::to_string(SUBSLIP_FRIC_NPROPS) + " PROPS (docs/fe.md)");
  point::ContactParameters c;
  c.law = law_props(p, SUBSLIP_FRIC_MU_S);
  // alpha_n enters only a normal approach at a given speed, which FRIC never has (the pressure
  // is given); it takes alpha_t's value to pass the point's checks.
  c.stiffness.alpha_t = prop(p, SUBSLIP_FRIC_ALPHA_T, "alpha_t");
  c.stiffness.alpha_n = c.stiffness.alpha_t;
  const double tolerance = prop(p, SUBSLIP_FRIC_TOLERANCE, "tolerance");
  if (tolerance != 0.0) c.residual_tolerance = tolerance;
  law::LawState initial;
  initial.mu = prop(p, SUBSLIP_FRIC_INITIAL_MU, "initial mu");
  if (initial.mu == 0.0) initial.mu = c.law.friction.mu_s;
  initial.r_s = prop(p, SUBSLIP_FRIC_INITIAL_R_S, "initial r_s");
  return {point::ContactPoint(c), initial};
}

MaterialCache<FricMaterial>& materials() {
  static MaterialCache<FricMaterial> cache;
  return cache;
}

double& at(double* statev, int index) {
  return statev[index - 1];
}

contact::ContactState unpack(const double* statev, const double* tau, int nfdir) {
  contact::ContactState s;
  s.time = statev[SUBSLIP_FRIC_TIME - 1];
  s.slip = {statev[SUBSLIP_FRIC_SLIP - 1], statev[SUBSLIP_FRIC_SLIP]};
  s.slip_path = statev[SUBSLIP_FRIC_SLIP_PATH - 1];
  s.vp_slip = statev[SUBSLIP_FRIC_VP_SLIP - 1];
  s.vp_rate = statev[SUBSLIP_FRIC_VP_RATE - 1];
  s.law.mu = statev[SUBSLIP_FRIC_MU - 1];
  s.law.r_s = statev[SUBSLIP_FRIC_R_S - 1];
  s.r = statev[SUBSLIP_FRIC_R - 1];
  s.traction_n = statev[SUBSLIP_FRIC_PRESSURE - 1];
  s.traction_t = {tau[0], nfdir > 1 ? tau[1] : 0.0};
  return s;
}

void pack(const contact::ContactState& s, double* statev) {
  at(statev, SUBSLIP_FRIC_MARKER) = 1.0;
  at(statev, SUBSLIP_FRIC_TIME) = s.time;
  at(statev, SUBSLIP_FRIC_SLIP) = s.slip(0);
  at(statev, SUBSLIP_FRIC_SLIP + 1) = s.slip(1);
  at(statev, SUBSLIP_FRIC_SLIP_PATH) = s.slip_path;
  at(statev, SUBSLIP_FRIC_VP_SLIP) = s.vp_slip;
  at(statev, SUBSLIP_FRIC_VP_RATE) = s.vp_rate;
  at(statev, SUBSLIP_FRIC_MU) = s.law.mu;
  at(statev, SUBSLIP_FRIC_R_S) = s.law.r_s;
  at(statev, SUBSLIP_FRIC_R) = s.r;
  at(statev, SUBSLIP_FRIC_PRESSURE) = s.traction_n;
  at(statev, SUBSLIP_FRIC_TRACTION) = s.traction_t(0);
  at(statev, SUBSLIP_FRIC_TRACTION + 1) = s.traction_t(1);
}

struct FricIo {
  int* lm;
  double* tau;
  double* ddtddg;
  double* ddtddp;
  double* dslip;
  double* sed;
  double* sfd;
  double* statev;
  const double* dgam;
  double press;
  double dpress;
  double dtime;
  int nfdir;
  int nstatv;
  const double* props;
  int nprops;
};

void fric_increment(const FricIo& io) {
  if (io.nfdir != 1 && io.nfdir != 2)
    throw std::invalid_argument("NFDIR = " + std::to_string(io.nfdir) + ": 1 or 2");
  if (io.nprops < 1 || !io.props) throw std::invalid_argument("NPROPS < 1: no PROPS");
  const auto material = materials().get(io.props, io.nprops, make_fric_material);
  if (io.nstatv < SUBSLIP_FRIC_NSTATV)
    throw std::invalid_argument("NSTATV = " + std::to_string(io.nstatv) + ": FRIC needs " +
                                std::to_string(SUBSLIP_FRIC_NSTATV) + " (docs/fe.md)");
  if (!std::isfinite(io.press) || !std::isfinite(io.dpress) || !std::isfinite(io.dtime) ||
      io.dtime < 0.0)
    throw std::invalid_argument("PRESS, DPRESS or DTIME is not finite, or DTIME < 0");
  const Eigen::Vector2d slip(io.dgam[0], io.nfdir > 1 ? io.dgam[1] : 0.0);
  if (!slip.allFinite()) throw std::invalid_argument("DGAM is not finite");
  const point::ContactPoint& point = material->point;
  const double alpha_t = point.parameters().stiffness.alpha_t;

  if (!(io.press > 0.0)) {
    // No pressure (an iteration that has only just closed the contact): no friction.
    *io.lm = 2;
    return;
  }
  const double marker = io.statev[SUBSLIP_FRIC_MARKER - 1];
  contact::ContactState s0;
  if (marker == 0.0) {
    s0 = point.initial_state(io.press - io.dpress, material->initial);
    s0.traction_t = {io.tau[0], io.nfdir > 1 ? io.tau[1] : 0.0};
  } else if (marker == 1.0) {
    s0 = unpack(io.statev, io.tau, io.nfdir);
  } else {
    throw std::invalid_argument("STATEV(1) = " + std::to_string(marker) +
                                ": 0 before the first increment, 1 after (docs/fe.md)");
  }

  contact::ContactState s1;
  Eigen::Matrix<double, 2, 3> tangent;
  if (io.dtime == 0.0) {
    if (!slip.isZero(0.0))
      throw std::invalid_argument("a slip over no time (DTIME = 0): the law is rate dependent");
    s1 = s0;
    tangent.setZero();
    tangent(0, 0) = tangent(1, 1) = alpha_t;
  } else {
    const point::ContactUpdate u = point.update(s0, {slip, io.press, io.dtime});
    if (!u.report.ok)
      throw std::runtime_error("the contact point did not take the increment: " + u.report.why);
    s1 = u.state;
    tangent = u.tangent;
  }
  if (!s1.traction_t.allFinite() || !tangent.allFinite())
    throw std::runtime_error("the increment gave a traction or tangent that is not finite");

  // Commit.
  *io.lm = 0;
  pack(s1, io.statev);
  const Eigen::Vector2d viscoplastic = slip - (s1.traction_t - s0.traction_t) / alpha_t;
  for (int a = 0; a < io.nfdir; ++a) {
    io.tau[a] = s1.traction_t(a);
    io.ddtddp[a] = tangent(a, 2);
    io.dslip[a] = viscoplastic(a);
    for (int b = 0; b < io.nfdir; ++b) io.ddtddg[a + io.nfdir * b] = tangent(a, b);
  }
  *io.sed = s1.traction_t.squaredNorm() / (2.0 * alpha_t);
  *io.sfd = s1.traction_t.dot(viscoplastic);
}

}  // namespace

}  // namespace subslip::fe

SUBSLIP_FE_EXPORT void fric_(int* lm, double* tau, double* ddtddg, double* ddtddp, double* dslip,
                             double* sed, double* sfd, double* /*ddtddt*/, double* pnewdt,
                             double* statev, const double* dgam, const double* /*taulm*/,
                             const double* press, const double* dpress, const double* /*ddpddh*/,
                             const double* /*slip*/, const int* /*kstep*/, const int* /*kinc*/,
                             const double* /*time*/, const double* dtime, const int* noel,
                             const char* /*ciname*/, const char* /*slname*/, const char* /*msname*/,
                             const int* npt, const int* /*node*/, const int* /*npatch*/,
                             const double* /*coords*/, const double* /*rcoord*/,
                             const double* /*drot*/, const double* /*temp*/,
                             const double* /*predef*/, const int* nfdir, const int* /*mcrd*/,
                             const int* /*npred*/, const int* nstatv, const double* /*chrlngth*/,
                             const double* props, const int* nprops, size_t, size_t, size_t) {
  namespace fe = subslip::fe;
  fe::clear_message();
  try {
    fe::fric_increment({lm, tau, ddtddg, ddtddp, dslip, sed, sfd, statev, dgam, *press, *dpress,
                        *dtime, *nfdir, *nstatv, props, *nprops});
  } catch (const std::exception& e) {
    fe::refuse("fric", "element " + std::to_string(noel ? *noel : 0) + ", point " +
                           std::to_string(npt ? *npt : 0) + ": " + e.what());
    *pnewdt = std::min(*pnewdt, 0.5);
  } catch (...) {
    fe::refuse("fric", "unknown failure");
    *pnewdt = std::min(*pnewdt, 0.5);
  }
}

// The same entry point under the names other compilers and conventions give it.
SUBSLIP_FE_EXPORT decltype(fric_) fric __attribute__((alias("fric_")));
SUBSLIP_FE_EXPORT decltype(fric_) FRIC __attribute__((alias("fric_")));
