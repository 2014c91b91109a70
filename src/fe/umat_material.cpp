#include "umat_material.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include "props.hpp"
#include "subslip/crystal/elasticity.hpp"
#include "subslip/crystal/rotation.hpp"
#include "subslip/fe/umat_layout.h"

namespace subslip::fe {

namespace cr = subslip::crystal;

namespace {

std::vector<cr::SlipFamily> families(int lattice) {
  using F = cr::SlipFamily;
  switch (lattice) {
    case 1:
      return {F::fcc_111_110};
    case 2:
      return {F::bcc_110_111};
    case 3:
      return {F::bcc_110_111, F::bcc_112_111};
    default:
      return {F::bcc_110_111, F::bcc_112_111, F::bcc_123_111};
  }
}

point::GrainParameters grain_parameters(const double* p) {
  point::GrainParameters d;
  d.families = families(prop_code(p, SUBSLIP_UMAT_LATTICE, "lattice", 1, 4));
  cr::SlipGroupSettings g;
  g.tau0 = prop(p, SUBSLIP_UMAT_TAU0, "tau0");
  if (!(g.tau0 > 0.0))
    throw std::invalid_argument(prop_name(SUBSLIP_UMAT_TAU0, "tau0") + " must be > 0");
  g.law = law_props(p, SUBSLIP_UMAT_MU_S);
  g.initial_mu = prop(p, SUBSLIP_UMAT_INITIAL_MU, "initial mu");
  if (g.initial_mu < 0.0)
    throw std::invalid_argument(prop_name(SUBSLIP_UMAT_INITIAL_MU, "initial mu") +
                                " must be >= 0 (0: mu_s)");
  d.family_settings.assign(d.families.size(), g);
  d.stiffness =
      cr::cubic_stiffness(prop(p, SUBSLIP_UMAT_C11, "C11"), prop(p, SUBSLIP_UMAT_C12, "C12"),
                          prop(p, SUBSLIP_UMAT_C44, "C44"));
  const double coplanar = prop(p, SUBSLIP_UMAT_Q_COPLANAR, "q coplanar");
  const double non_coplanar = prop(p, SUBSLIP_UMAT_Q_NON_COPLANAR, "q non-coplanar");
  if (coplanar < 0.0 || non_coplanar < 0.0)
    throw std::invalid_argument("PROPS(19), PROPS(20) (latent hardening) must be >= 0");
  if (coplanar == 0.0 && non_coplanar == 0.0) {
    d.latent.kind = cr::LatentHardening::Kind::none;
  } else if (coplanar == non_coplanar) {
    d.latent.kind = cr::LatentHardening::Kind::ratio;
    d.latent.ratio = coplanar;
  } else {
    d.latent.kind = cr::LatentHardening::Kind::coplanar;
    d.latent.coplanar = coplanar;
    d.latent.non_coplanar = non_coplanar;
  }
  d.kinematics = prop_code(p, SUBSLIP_UMAT_LATTICE_ROTATION, "lattice rotation", 0, 1) == 0
                     ? cr::Kinematics::finite_rotation
                     : cr::Kinematics::small_strain;
  return d;
}

point::GrainOptions grain_options(const double* p) {
  point::GrainOptions o;
  const double tolerance = prop(p, SUBSLIP_UMAT_TOLERANCE, "tolerance");
  if (tolerance != 0.0) o.tolerance = tolerance;
  const int iterations = prop_code(p, SUBSLIP_UMAT_MAX_ITERATIONS, "max iterations", 0, 100000);
  if (iterations != 0) o.max_iterations = iterations;
  return o;
}

Eigen::Matrix3d orientation(const double* p, int first) {
  const Eigen::Vector3d degrees(prop(p, first, "phi1"), prop(p, first + 1, "Phi"),
                                prop(p, first + 2, "phi2"));
  return cr::Orientation::from_euler(cr::degrees_to_radians(degrees)).g;
}

}  // namespace

int grain_block(int slip_count) {
  return SUBSLIP_UMAT_GRAIN_BLOCK(slip_count);
}

UmatMaterial make_umat_material(const double* props, int nprops) {
  if (nprops < SUBSLIP_UMAT_TAYLOR_GRAINS)
    throw std::invalid_argument("NPROPS = " + std::to_string(nprops) + ": at least " +
                                std::to_string(SUBSLIP_UMAT_TAYLOR_GRAINS) +
                                " PROPS are needed (docs/fe.md)");
  UmatMaterial m;
  m.taylor = prop_code(props, SUBSLIP_UMAT_POINT, "point", 1, 2) == 2;
  m.finite_strain = prop_code(props, SUBSLIP_UMAT_STRAIN, "strain", 0, 1) == 1;
  const point::GrainParameters parameters = grain_parameters(props);
  const point::GrainOptions options = grain_options(props);
  m.lattice_stiffness = parameters.stiffness;
  if (!m.taylor) {
    if (nprops != SUBSLIP_UMAT_SINGLE_NPROPS)
      throw std::invalid_argument("NPROPS = " + std::to_string(nprops) + ": a single crystal has " +
                                  std::to_string(SUBSLIP_UMAT_SINGLE_NPROPS) + " PROPS");
    m.orientations = {orientation(props, SUBSLIP_UMAT_PHI1)};
    m.weights = {1.0};
    m.grain = std::make_unique<point::GrainPoint>(parameters, options);
  } else {
    const int grains = prop_code(props, SUBSLIP_UMAT_TAYLOR_GRAINS, "grain count", 1, 1000000);
    if (nprops != SUBSLIP_UMAT_TAYLOR_NPROPS(grains))
      throw std::invalid_argument("NPROPS = " + std::to_string(nprops) +
                                  ": a Taylor aggregate of " + std::to_string(grains) +
                                  " grains has " +
                                  std::to_string(SUBSLIP_UMAT_TAYLOR_NPROPS(grains)) + " PROPS");
    double total = 0.0;
    for (int k = 0; k < grains; ++k) {
      const int first = SUBSLIP_UMAT_TAYLOR_GRAINS + 1 + 4 * k;
      m.orientations.push_back(orientation(props, first));
      const double w = prop(props, first + 3, "grain weight");
      if (!(w > 0.0))
        throw std::invalid_argument(prop_name(first + 3, "grain weight") + " must be > 0");
      m.weights.push_back(w);
      total += w;
    }
    m.aggregate =
        std::make_unique<point::TaylorPoint>(parameters, m.orientations, m.weights, options);
    for (double& w : m.weights) w /= total;
  }
  m.slip_count = m.grain_point().slip_count();
  m.statev_count = SUBSLIP_UMAT_NSTATV(static_cast<int>(m.orientations.size()), m.slip_count);
  return m;
}

point::GrainState unpack_grain(const double* b, int n) {
  point::GrainState s;
  for (int i = 0; i < 6; ++i) s.stress(i) = b[i];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) s.orientation(i, j) = b[6 + 3 * i + j];
  s.trend_step = b[15];
  point::SlipVector* fields[] = {&s.mu,   &s.r_s,        &s.slip,
                                 &s.rate, &s.rate_trend, &s.rate_trend_change};
  const double* v = b + 16;
  for (point::SlipVector* f : fields) {
    f->resize(n);
    for (int a = 0; a < n; ++a) (*f)(a) = *v++;
  }
  return s;
}

void pack_grain(const point::GrainState& s, double* b) {
  for (int i = 0; i < 6; ++i) b[i] = s.stress(i);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) b[6 + 3 * i + j] = s.orientation(i, j);
  b[15] = s.trend_step;
  const point::SlipVector* fields[] = {&s.mu,   &s.r_s,        &s.slip,
                                       &s.rate, &s.rate_trend, &s.rate_trend_change};
  double* v = b + 16;
  for (const point::SlipVector* f : fields)
    for (int a = 0; a < f->size(); ++a) *v++ = (*f)(a);
}

}  // namespace subslip::fe
