#include "umat_material.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
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
    case 4:
      return {F::bcc_110_111, F::bcc_112_111, F::bcc_123_111};
    default:
      return {F::hcp_basal_a, F::hcp_prismatic_a, F::hcp_pyramidal_a, F::hcp_pyramidal_ca};
  }
}

// Where the entries after the orientation or the grain list are (umat_layout.h).
struct Tail {
  int base = 0;             // PROPS(base + offset)
  bool hcp = false;         // C13, C33, c/a first
  bool per_family = false;  // then one tau0 per family
  int lattice = 0;

  int size() const { return SUBSLIP_UMAT_TAIL(lattice, per_family); }
  int first_tau0() const { return base + 1 + (hcp ? SUBSLIP_UMAT_HCP_TAIL : 0); }
};

double positive_prop(const double* p, int index, const char* name) {
  const double v = prop(p, index, name);
  if (!(v > 0.0)) throw std::invalid_argument(prop_name(index, name) + " must be > 0");
  return v;
}

point::GrainParameters grain_parameters(const double* p, const Tail& tail) {
  point::GrainParameters d;
  d.families = families(tail.lattice);
  cr::SlipGroupSettings g;
  g.law = law_props(p, SUBSLIP_UMAT_MU_S);
  g.initial_mu = prop(p, SUBSLIP_UMAT_INITIAL_MU, "initial mu");
  if (g.initial_mu < 0.0)
    throw std::invalid_argument(prop_name(SUBSLIP_UMAT_INITIAL_MU, "initial mu") +
                                " must be >= 0 (0: mu_s)");
  d.family_settings.assign(d.families.size(), g);
  for (std::size_t f = 0; f < d.families.size(); ++f)
    d.family_settings[f].tau0 =
        tail.per_family
            ? positive_prop(p, tail.first_tau0() + static_cast<int>(f), "tau0 of a slip family")
            : prop(p, SUBSLIP_UMAT_TAU0, "tau0");
  const double c11 = prop(p, SUBSLIP_UMAT_C11, "C11"), c12 = prop(p, SUBSLIP_UMAT_C12, "C12"),
               c44 = prop(p, SUBSLIP_UMAT_C44, "C44");
  if (tail.hcp) {
    d.stiffness =
        cr::hexagonal_stiffness(c11, c12, prop(p, tail.base + SUBSLIP_UMAT_HCP_C13, "C13"),
                                prop(p, tail.base + SUBSLIP_UMAT_HCP_C33, "C33"), c44);
    const int c_over_a = tail.base + SUBSLIP_UMAT_HCP_C_OVER_A;
    if (prop(p, c_over_a, "c/a") != 0.0) d.c_over_a = positive_prop(p, c_over_a, "c/a");
  } else {
    d.stiffness = cr::cubic_stiffness(c11, c12, c44);
  }
  if (!(Eigen::SelfAdjointEigenSolver<point::Matrix6>(d.stiffness, Eigen::EigenvaluesOnly)
            .eigenvalues()
            .minCoeff() > 0.0))
    throw std::invalid_argument("PROPS(4..6) (C11, C12, C44)" +
                                std::string(tail.hcp ? " with C13, C33" : "") +
                                ": the elastic stiffness is not positive definite");
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

// The tail's place and content; NPROPS checked against it.
Tail tail_of(const double* props, int nprops, bool taylor) {
  Tail t;
  t.lattice = prop_code(props, SUBSLIP_UMAT_LATTICE, "lattice", 1, SUBSLIP_UMAT_LATTICE_HCP);
  t.hcp = t.lattice == SUBSLIP_UMAT_LATTICE_HCP;
  const double tau0 = prop(props, SUBSLIP_UMAT_TAU0, "tau0");
  if (tau0 < 0.0)
    throw std::invalid_argument(prop_name(SUBSLIP_UMAT_TAU0, "tau0") +
                                " must be > 0 (or 0: one per slip family after the base PROPS)");
  t.per_family = tau0 == 0.0;
  std::string what = "a single crystal";
  if (taylor) {
    const int grains = prop_code(props, SUBSLIP_UMAT_TAYLOR_GRAINS, "grain count", 1, 1000000);
    t.base = SUBSLIP_UMAT_TAYLOR_NPROPS(grains);
    what = "a Taylor aggregate of " + std::to_string(grains) + " grains";
  } else {
    t.base = SUBSLIP_UMAT_SINGLE_NPROPS;
  }
  if (nprops != t.base + t.size())
    throw std::invalid_argument(
        "NPROPS = " + std::to_string(nprops) + ": " + what + " of lattice " +
        std::to_string(t.lattice) + (t.hcp ? " (HCP: C13, C33, c/a after the base)" : "") +
        (t.per_family ? " with tau0 per slip family (PROPS(7) = 0)" : "") + " has " +
        std::to_string(t.base + t.size()) + " PROPS (docs/fe.md)");
  return t;
}

// What the energies need per slip system, in the grain's order.
void describe_systems(const point::GrainParameters& d, UmatMaterial& m) {
  for (const cr::DescribedSystem& system : cr::described_systems(d)) {
    const Eigen::Matrix3d sm = system.s * system.m.transpose();
    m.schmid.push_back(cr::mandel_from_symmetric(0.5 * (sm + sm.transpose())));
    const cr::SlipGroupSettings& g = d.family_settings[static_cast<std::size_t>(system.group)];
    m.tau0.push_back(g.tau0);
    m.viscous.push_back(g.law.overstress.form != law::OverstressForm::rate_independent);
  }
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
  const Tail tail = tail_of(props, nprops, m.taylor);
  const point::GrainParameters parameters = grain_parameters(props, tail);
  const point::GrainOptions options = grain_options(props);
  m.lattice_stiffness = parameters.stiffness;
  m.lattice_compliance = parameters.stiffness.inverse();
  if (!m.taylor) {
    m.orientations = {orientation(props, SUBSLIP_UMAT_PHI1)};
    m.weights = {1.0};
    m.grain = std::make_unique<point::GrainPoint>(parameters, options);
  } else {
    const int grains = prop_code(props, SUBSLIP_UMAT_TAYLOR_GRAINS, "grain count", 1, 1000000);
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
  describe_systems(parameters, m);
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
