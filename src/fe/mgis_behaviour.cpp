// The MFront generic behaviour SubslipFCC (subslip/fe/mgis_behaviour.h): an FCC single crystal
// at finite strain, with the symbols MGIS reads to describe it (material knowledge type, API
// version, behaviour type and kinematic, gradients, thermodynamic forces, tangent blocks,
// material properties, internal state variables and their types). Its material properties are
// the UMAT PROPS from C11 on (the point is a single crystal, the strain finite, the lattice FCC)
// and its internal state variables are the UMAT STATEV, one scalar each: the same grain update
// through the same code.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <numbers>
#include <stdexcept>
#include <string>

#include "export.hpp"
#include "grain_increment.hpp"
#include "subslip/crystal/elasticity.hpp"
#include "subslip/fe/mgis_behaviour.h"
#include "subslip/fe/umat_layout.h"

namespace subslip::fe {

namespace {

constexpr int kSlipCount = 12;
constexpr int kStateCount = SUBSLIP_UMAT_NSTATV(1, kSlipCount);
constexpr int kPropertyCount = SUBSLIP_UMAT_SINGLE_NPROPS - SUBSLIP_UMAT_C11 + 1;

// TFEL's component orders: symmetric tensors 11 22 33 12 13 23 (shears times sqrt2), tensors
// 11 22 33 12 21 13 31 23 32.
constexpr std::array<std::array<int, 2>, 6> kStensor = {
    {{0, 0}, {1, 1}, {2, 2}, {0, 1}, {0, 2}, {1, 2}}};
constexpr std::array<std::array<int, 2>, 9> kTensor = {
    {{0, 0}, {1, 1}, {2, 2}, {0, 1}, {1, 0}, {0, 2}, {2, 0}, {1, 2}, {2, 1}}};

Eigen::Matrix3d tensor_from_tfel(const double* v) {
  Eigen::Matrix3d t;
  for (int k = 0; k < 9; ++k) t(kTensor[k][0], kTensor[k][1]) = v[k];
  return t;
}

void stensor_to_tfel(const Eigen::Matrix3d& s, double* v) {
  for (int k = 0; k < 6; ++k)
    v[k] = (k < 3 ? 1.0 : std::numbers::sqrt2) * s(kStensor[k][0], kStensor[k][1]);
}

// d sigma / d F1 (6 x 9, row major, TFEL orders), MFront's DSIG_DF, from `c` = d sigma / d e
// under F1 -> (I + e) F1 (e symmetric, Mandel; GrainIncrement::tangent) and the stress sigma at
// the increment's end. A variation dF of F1 is F1 -> (I + l) F1 with l = dF F1^-1; its skew
// part w turns the relative deformation's rotation and nothing else, so d sigma = c : sym(l) +
// w sigma - sigma w. With the exact c of the increment this is the derivative of the finite
// increment; with the elastic operator, the elastic response's.
void dsigma_df(const point::Matrix6& c, const Eigen::Matrix3d& sigma, const Eigen::Matrix3d& f,
               double* k) {
  const Eigen::Matrix3d f_inverse = f.inverse();
  for (int b = 0; b < 9; ++b) {
    Eigen::Matrix3d df = Eigen::Matrix3d::Zero();
    df(kTensor[b][0], kTensor[b][1]) = 1.0;
    const Eigen::Matrix3d l = df * f_inverse;
    const Eigen::Matrix3d w = 0.5 * (l - l.transpose());
    const Eigen::Matrix3d ds =
        crystal::symmetric_from_mandel(c * crystal::mandel_from_symmetric(l)) + w * sigma -
        sigma * w;
    double column[6];
    stensor_to_tfel(ds, column);
    for (int a = 0; a < 6; ++a) k[9 * a + b] = column[a];
  }
}

// The UMAT PROPS of the behaviour's material properties.
std::array<double, SUBSLIP_UMAT_SINGLE_NPROPS> props_of(const double* mps) {
  std::array<double, SUBSLIP_UMAT_SINGLE_NPROPS> p{};
  p[SUBSLIP_UMAT_POINT - 1] = 1;
  p[SUBSLIP_UMAT_STRAIN - 1] = 1;
  p[SUBSLIP_UMAT_LATTICE - 1] = 1;
  std::copy(mps, mps + kPropertyCount, p.begin() + (SUBSLIP_UMAT_C11 - 1));
  return p;
}

void report(mfront_gb_BehaviourData* d, const std::string& text) {
  if (d->error_message) {
    const std::string m = "SubslipFCC: " + text;
    const std::size_t n = std::min<std::size_t>(m.size(), 511);
    std::memcpy(d->error_message, m.data(), n);
    d->error_message[n] = '\0';
  }
  if (d->rdt) *d->rdt = std::min(*d->rdt, 0.5);
}

// K[0] as the generic interface defines it (K[0] - 100 where above 50: the speed of sound is
// asked too): below -0.5 the prediction operator alone; in [-0.5, 0.5] the integration alone;
// in [0.5, 1.5] the integration and the elastic operator; above that the integration and the
// tangent operator (the secant operators of [1.5, 3.5] are given the tangent one).
int integrate(mfront_gb_BehaviourData* d) {
  double request = d->K[0];
  const bool speed_of_sound = request > 50.0;
  if (speed_of_sound) request -= 100.0;
  if (d->K[1] > 0.5 || d->K[2] > 0.5)
    throw std::invalid_argument(
        "only the Cauchy stress and d sigma / d F are offered (K[1] = "
        "K[2] = 0)");
  const auto props = props_of(d->s0.material_properties);
  // The UMAT's TAU0 = 0 (a tau0 per family after the base PROPS) has no material property here.
  if (!(props[SUBSLIP_UMAT_TAU0 - 1] > 0.0))
    throw std::invalid_argument("the material property tau0 must be > 0");
  const auto material = umat_material(props.data(), static_cast<int>(props.size()));
  const Eigen::Matrix3d f0 = tensor_from_tfel(d->s0.gradients);
  const Eigen::Matrix3d f1 = tensor_from_tfel(d->s1.gradients);

  std::array<double, kStateCount> state;
  std::copy(d->s0.internal_state_variables, d->s0.internal_state_variables + kStateCount,
            state.begin());
  const bool integration = request > -0.5;
  // The prediction: the elastic operator at the start (an increment of no time, no motion).
  const Kinematics k =
      integration ? finite_strain_kinematics(f0, f1, d->dt) : finite_strain_kinematics(f0, f0, 0.0);
  const GrainIncrement r = grain_increment(*material, state.data(), k, integration ? d->dt : 0.0);
  const Eigen::Matrix3d sigma = crystal::symmetric_from_mandel(r.stress);
  if (integration) {
    std::copy(state.begin(), state.end(), d->s1.internal_state_variables);
    stensor_to_tfel(sigma, d->s1.thermodynamic_forces);
  }
  if (request < -0.5 || request > 0.5) {
    point::Matrix6 c = r.tangent;
    if (integration && request < 1.5) {  // the elastic operator after the increment
      std::array<double, kStateCount> after = state;
      c = grain_increment(*material, after.data(), finite_strain_kinematics(f1, f1, 0.0), 0.0)
              .tangent;
    }
    dsigma_df(c, sigma, integration ? f1 : f0, d->K);
  }
  if (speed_of_sound && d->speed_of_sound) *d->speed_of_sound = 0.0;  // not computed
  return 1;
}

// Names of the material properties and the internal state variables, made once at load time.
struct Names {
  std::array<std::string, kStateCount> state_storage;
  std::array<const char*, kStateCount> state;  // into state_storage
  Names() {
    std::size_t k = 0;
    state_storage[k++] = "Initialised";
    for (int i = 1; i <= 6; ++i) state_storage[k++] = "LatticeStress" + std::to_string(i);
    for (int i = 1; i <= 3; ++i)
      for (int j = 1; j <= 3; ++j)
        state_storage[k++] = "Orientation" + std::to_string(i) + std::to_string(j);
    state_storage[k++] = "LastStepLength";
    for (const char* field :
         {"mu", "r_s", "slip", "SlipRate", "SlipRateTrend", "SlipRateTrendChange"})
      for (int a = 1; a <= kSlipCount; ++a)
        state_storage[k++] = std::string(field) + std::to_string(a);
    for (std::size_t i = 0; i < state.size(); ++i) state[i] = state_storage[i].c_str();
  }
};

const Names& names() {
  static const Names n;
  return n;
}

}  // namespace

}  // namespace subslip::fe

SUBSLIP_FE_EXPORT int SubslipFCC_Tridimensional(mfront_gb_BehaviourData* d) {
  try {
    return subslip::fe::integrate(d);
  } catch (const std::exception& e) {
    subslip::fe::report(d, e.what());
  } catch (...) {
    subslip::fe::report(d, "unknown failure");
  }
  return -1;
}

// The metadata MGIS reads (LibrariesManager): every symbol is <behaviour>_<what>.
SUBSLIP_FE_EXPORT const unsigned short SubslipFCC_mfront_mkt = 1;  // a behaviour
SUBSLIP_FE_EXPORT const unsigned short SubslipFCC_api_version = 1;
SUBSLIP_FE_EXPORT const char* const SubslipFCC_mfront_interface = "Generic";
SUBSLIP_FE_EXPORT const char* const SubslipFCC_src = "subslip (libsubslip_fe, docs/fe.md)";
SUBSLIP_FE_EXPORT const char* const SubslipFCC_tfel_version = "";
SUBSLIP_FE_EXPORT const unsigned short SubslipFCC_nModellingHypotheses = 1;
SUBSLIP_FE_EXPORT const char* const SubslipFCC_ModellingHypotheses[1] = {"Tridimensional"};
SUBSLIP_FE_EXPORT const unsigned short SubslipFCC_BehaviourType = 2;       // finite strain
SUBSLIP_FE_EXPORT const unsigned short SubslipFCC_BehaviourKinematic = 3;  // F, Cauchy
SUBSLIP_FE_EXPORT const unsigned short SubslipFCC_SymmetryType = 0;  // orientation: a property
SUBSLIP_FE_EXPORT const unsigned short SubslipFCC_ElasticSymmetryType = 0;
SUBSLIP_FE_EXPORT const unsigned short SubslipFCC_requiresStiffnessTensor = 0;
SUBSLIP_FE_EXPORT const unsigned short SubslipFCC_requiresThermalExpansionCoefficientTensor = 0;
SUBSLIP_FE_EXPORT const unsigned short SubslipFCC_ComputesInternalEnergy = 0;
SUBSLIP_FE_EXPORT const unsigned short SubslipFCC_ComputesDissipatedEnergy = 0;
SUBSLIP_FE_EXPORT const unsigned short SubslipFCC_TemperatureRemovedFromExternalStateVariables = 1;
SUBSLIP_FE_EXPORT const unsigned short SubslipFCC_nGradients = 1;
SUBSLIP_FE_EXPORT const char* const SubslipFCC_Gradients[1] = {"DeformationGradient"};
SUBSLIP_FE_EXPORT const int SubslipFCC_GradientsTypes[1] = {3};  // tensor
SUBSLIP_FE_EXPORT const unsigned short SubslipFCC_nThermodynamicForces = 1;
SUBSLIP_FE_EXPORT const char* const SubslipFCC_ThermodynamicForces[1] = {"Stress"};
SUBSLIP_FE_EXPORT const int SubslipFCC_ThermodynamicForcesTypes[1] = {1};  // symmetric tensor
SUBSLIP_FE_EXPORT const unsigned short SubslipFCC_nTangentOperatorBlocks = 2;
SUBSLIP_FE_EXPORT const char* const SubslipFCC_TangentOperatorBlocks[2] = {"Stress",
                                                                           "DeformationGradient"};
SUBSLIP_FE_EXPORT const unsigned short SubslipFCC_nMaterialProperties = subslip::fe::kPropertyCount;
SUBSLIP_FE_EXPORT const char* const SubslipFCC_MaterialProperties[subslip::fe::kPropertyCount] = {
    "C11",
    "C12",
    "C44",
    "tau0",
    "mu_s",
    "mu_k",
    "kappa",
    "xi",
    "UFunction",
    "u_tilde",
    "OverstressForm",
    "eta_v",
    "n",
    "r_hat",
    "InitialMu",
    "QCoplanar",
    "QNonCoplanar",
    "LatticeRotation",
    "Tolerance",
    "MaxIterations",
    "phi1",
    "Phi",
    "phi2"};
SUBSLIP_FE_EXPORT const unsigned short SubslipFCC_nInternalStateVariables =
    subslip::fe::kStateCount;
// An array of names (MGIS reads the symbol as the array), filled when the library is loaded.
extern "C" {  // a definition (the braces make it one without an initialiser)
__attribute__((visibility("default"))) const char*
    SubslipFCC_InternalStateVariables[subslip::fe::kStateCount];
}
SUBSLIP_FE_EXPORT const int SubslipFCC_InternalStateVariablesTypes[subslip::fe::kStateCount] = {};
namespace {
const bool state_names_filled = [] {
  const auto& n = subslip::fe::names().state;
  std::copy(n.begin(), n.end(), SubslipFCC_InternalStateVariables);
  return true;
}();
}  // namespace
SUBSLIP_FE_EXPORT const unsigned short SubslipFCC_nExternalStateVariables = 0;
SUBSLIP_FE_EXPORT const unsigned short SubslipFCC_nParameters = 0;
SUBSLIP_FE_EXPORT const int SubslipFCC_ParametersTypes[1] = {0};
SUBSLIP_FE_EXPORT const unsigned short SubslipFCC_nInitializeFunctions = 0;
SUBSLIP_FE_EXPORT const unsigned short SubslipFCC_nPostProcessings = 0;
