// The MFront generic behaviour SubslipFCC of libsubslip_fe, loaded as MGIS loads a behaviour:
// dlopen of the library, its metadata symbols read by name (<behaviour>_<what>), and the
// integration function <behaviour>_Tridimensional called with mfront_gb_BehaviourData. It
// integrates a stretch path equal to the native grain, agrees with umat_ at finite strain on a
// path with rotation, follows the K[0] convention, and reports a failure with -1 and a message.
#include <dlfcn.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "subslip/crystal/rotation.hpp"
#include "subslip/fe/mgis_behaviour.h"
#include "umat_call.hpp"

namespace {

using namespace subslip::fe_testing;

class Library {
 public:
  Library() : handle_(dlopen(SUBSLIP_FE_LIBRARY, RTLD_NOW | RTLD_LOCAL)) {}
  ~Library() {
    if (handle_) dlclose(handle_);
  }
  bool loaded() const { return handle_ != nullptr; }
  template <class T>
  const T* symbol(const std::string& name) const {
    return static_cast<const T*>(dlsym(handle_, name.c_str()));
  }
  std::vector<std::string> names(const std::string& behaviour, const std::string& what) const {
    const auto* n = symbol<unsigned short>(behaviour + "_n" + what);
    const auto* v = symbol<const char*>(behaviour + "_" + what);
    std::vector<std::string> out;
    if (!n || (*n > 0 && !v)) return out;
    for (unsigned short k = 0; k < *n; ++k) out.emplace_back(v[k]);
    return out;
  }

 private:
  void* handle_;
};

using Integrate = int (*)(mfront_gb_BehaviourData*);

constexpr int kStates = 89;

// The behaviour's material properties: the UMAT PROPS from C11 on.
std::vector<double> material_properties() {
  const std::vector<double> p = fcc_props({30, 40, 50});
  return {p.begin() + (SUBSLIP_UMAT_C11 - 1), p.end()};
}

// TFEL tensor order 11 22 33 12 21 13 31 23 32.
std::array<double, 9> tfel_tensor(const Eigen::Matrix3d& f) {
  return {f(0, 0), f(1, 1), f(2, 2), f(0, 1), f(1, 0), f(0, 2), f(2, 0), f(1, 2), f(2, 1)};
}

// One point integrated through the generic interface.
struct GenericPoint {
  Integrate integrate;
  std::vector<double> mps = material_properties();
  std::vector<double> isv0 = std::vector<double>(kStates, 0.0), isv1 = isv0;
  std::array<double, 6> sig0{}, sig1{};
  std::array<double, 54> k{};
  double rdt = 1.0, sound = 0.0, temperature = 293.0, density = 1.0;
  char message[512] = "";

  // One step from F0 to F1 over dt with K[0] = request; returns the function's result.
  int step(const Eigen::Matrix3d& f0, const Eigen::Matrix3d& f1, double dt, double request) {
    const auto g0 = tfel_tensor(f0), g1 = tfel_tensor(f1);
    k.fill(0.0);
    k[0] = request;
    rdt = 1.0;
    mfront_gb_BehaviourData d{};
    d.error_message = message;
    d.dt = dt;
    d.K = k.data();
    d.rdt = &rdt;
    d.speed_of_sound = &sound;
    d.s0 = {g0.data(),   sig0.data(), &density, mps.data(),
            isv0.data(), nullptr,     nullptr,  &temperature};
    d.s1 = {g1.data(),   sig1.data(), &density, mps.data(),
            isv1.data(), nullptr,     nullptr,  &temperature};
    const int r = integrate(&d);
    if (r == 1 && request > -0.5) {  // commit, as a finite-element code does after convergence
      isv0 = isv1;
      sig0 = sig1;
    }
    return r;
  }
};

TEST(FeMgis, MetadataAreFoundAsMgisReadsThem) {
  const Library lib;
  ASSERT_TRUE(lib.loaded()) << dlerror();
  const std::string b = "SubslipFCC";
  ASSERT_NE(lib.symbol<unsigned short>(b + "_mfront_mkt"), nullptr);
  EXPECT_EQ(*lib.symbol<unsigned short>(b + "_mfront_mkt"), 1);
  EXPECT_EQ(*lib.symbol<unsigned short>(b + "_api_version"), 1);
  EXPECT_EQ(*lib.symbol<unsigned short>(b + "_BehaviourType"), 2);       // finite strain
  EXPECT_EQ(*lib.symbol<unsigned short>(b + "_BehaviourKinematic"), 3);  // F, Cauchy
  EXPECT_EQ(*lib.symbol<unsigned short>(b + "_SymmetryType"), 0);
  EXPECT_EQ(*lib.symbol<unsigned short>(b + "_requiresStiffnessTensor"), 0);
  EXPECT_EQ(*lib.symbol<unsigned short>(b + "_requiresThermalExpansionCoefficientTensor"), 0);
  EXPECT_EQ(std::string(*lib.symbol<const char*>(b + "_mfront_interface")), "Generic");
  EXPECT_EQ(lib.names(b, "Gradients"), std::vector<std::string>{"DeformationGradient"});
  EXPECT_EQ(lib.symbol<int>(b + "_GradientsTypes")[0], 3);
  EXPECT_EQ(lib.names(b, "ThermodynamicForces"), std::vector<std::string>{"Stress"});
  EXPECT_EQ(lib.symbol<int>(b + "_ThermodynamicForcesTypes")[0], 1);
  EXPECT_EQ(lib.names(b, "TangentOperatorBlocks"),
            (std::vector<std::string>{"Stress", "DeformationGradient"}));
  const auto mps = lib.names(b, "MaterialProperties");
  ASSERT_EQ(mps.size(), material_properties().size());
  EXPECT_EQ(mps.front(), "C11");
  EXPECT_EQ(mps.back(), "phi2");
  const auto isvs = lib.names(b, "InternalStateVariables");
  ASSERT_EQ(isvs.size(), static_cast<std::size_t>(kStates));
  EXPECT_EQ(isvs[0], "Initialised");
  EXPECT_EQ(isvs[1 + 16], "mu1");
  EXPECT_EQ(isvs[kStates - 1], "SlipRateTrendChange12");
  for (int k = 0; k < kStates; ++k)
    EXPECT_EQ(lib.symbol<int>(b + "_InternalStateVariablesTypes")[k], 0);
  EXPECT_EQ(lib.names(b, "ExternalStateVariables"), std::vector<std::string>{});
  EXPECT_EQ(lib.names(b, "Parameters"), std::vector<std::string>{});
  EXPECT_NE(lib.symbol<void>(b + "_Tridimensional"), nullptr);
}

// Stretching along the axes (F diagonal: every increment a pure stretch, log U diagonal):
// tension, then compression, equals the native grain under L = log(U) / dt.
TEST(FeMgis, AStretchPathEqualsTheNativeGrain) {
  const Library lib;
  ASSERT_TRUE(lib.loaded()) << dlerror();
  GenericPoint p{reinterpret_cast<Integrate>(
      const_cast<void*>(lib.symbol<void>("SubslipFCC_Tridimensional")))};
  const pt::GrainPoint grain(fcc_parameters());
  pt::GrainState s = grain.initial_state(orientation_of({30, 40, 50}));
  auto stretch = [](int k) {  // [-]
    const double e = 2e-4 * (k <= 25 ? k : 50 - k);
    return Eigen::Vector3d(1.0 - 0.3 * e, 1.0 - 0.3 * e, 1.0 + e);
  };
  const double dt = 0.2;
  for (int k = 1; k <= 40; ++k) {
    const Eigen::Vector3d l0 = stretch(k - 1), l1 = stretch(k);
    ASSERT_EQ(p.step(Eigen::Matrix3d(l0.asDiagonal()), Eigen::Matrix3d(l1.asDiagonal()), dt, 4.0),
              1)
        << p.message;
    const Eigen::Matrix3d l = Eigen::Vector3d((l1.array() / l0.array()).log()).asDiagonal();
    const pt::GrainUpdate u = grain.update(s, l / dt, dt);
    ASSERT_TRUE(u.report.ok);
    s = u.state;
    const Eigen::Matrix3d sigma = cr::symmetric_from_mandel(u.stress);
    const std::array<double, 6> expected{sigma(0, 0),
                                         sigma(1, 1),
                                         sigma(2, 2),
                                         std::sqrt(2.0) * sigma(0, 1),
                                         std::sqrt(2.0) * sigma(0, 2),
                                         std::sqrt(2.0) * sigma(1, 2)};
    const double scale = sigma.cwiseAbs().maxCoeff();
    for (std::size_t i = 0; i < 6; ++i)
      EXPECT_NEAR(p.sig0[i], expected[i], 1e-10 * scale) << "increment " << k << ", " << i;
    for (int a = 0; a < 12; ++a)
      EXPECT_NEAR(p.isv0[static_cast<std::size_t>(1 + 16 + 24 + a)], s.slip(a),
                  1e-10 * std::max(s.slip.cwiseAbs().maxCoeff(), 1e-300));
  }
  EXPECT_GT(s.slip.cwiseAbs().maxCoeff(), 1e-3);
}

// With rotation (tension with shear): the same as umat_ at finite strain with the same
// properties, component for component in each interface's order.
TEST(FeMgis, EqualsTheUmatAtFiniteStrain) {
  const Library lib;
  ASSERT_TRUE(lib.loaded()) << dlerror();
  GenericPoint p{reinterpret_cast<Integrate>(
      const_cast<void*>(lib.symbol<void>("SubslipFCC_Tridimensional")))};
  std::vector<double> props = fcc_props({30, 40, 50});
  props[SUBSLIP_UMAT_STRAIN - 1] = 1;
  UmatPoint u(props);
  Eigen::Matrix3d g;
  g << -0.5e-3, 3e-3, 0.0, 0.0, -0.5e-3, 0.0, 0.0, 0.0, 1e-3;
  const double dt = 0.2;
  for (int k = 1; k <= 30; ++k) {
    const Eigen::Matrix3d f0 = Eigen::Matrix3d::Identity() + dt * (k - 1) * g;
    const Eigen::Matrix3d f1 = Eigen::Matrix3d::Identity() + dt * k * g;
    ASSERT_EQ(p.step(f0, f1, dt, 4.0), 1) << p.message;
    Eigen::Map<Eigen::Matrix3d>(u.dfgrd0.data()) = f0;
    Eigen::Map<Eigen::Matrix3d>(u.dfgrd1.data()) = f1;
    ASSERT_EQ(u.call({}, dt), 1.0);
    EXPECT_EQ(p.isv0, u.statev) << "increment " << k;
    const std::array<double, 6> expected{u.stress[0],
                                         u.stress[1],
                                         u.stress[2],
                                         std::sqrt(2.0) * u.stress[3],
                                         std::sqrt(2.0) * u.stress[4],
                                         std::sqrt(2.0) * u.stress[5]};
    for (std::size_t i = 0; i < 6; ++i)
      EXPECT_NEAR(p.sig0[i], expected[i], 1e-12 * std::abs(u.stress[2]) + 1e-300);
  }
}

// K[0] < 0: the prediction operator, nothing integrated. K[0] = 0: integration without an
// operator. K[0] = 4: d sigma / d F1 (DSIG_DF), central differences of the stress.
TEST(FeMgis, TheRequestInKZero) {
  const Library lib;
  ASSERT_TRUE(lib.loaded()) << dlerror();
  GenericPoint p{reinterpret_cast<Integrate>(
      const_cast<void*>(lib.symbol<void>("SubslipFCC_Tridimensional")))};
  const Eigen::Matrix3d f0 = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d f1 = f0;
  f1(2, 2) += 2e-5;
  f1(0, 1) += 1e-5;
  ASSERT_EQ(p.step(f0, f1, 0.1, -3.0), 1) << p.message;
  EXPECT_EQ(p.isv1, std::vector<double>(kStates, 0.0));  // nothing integrated
  EXPECT_NE(p.k[2 * 9 + 2], 0.0);                        // the operator is there
  GenericPoint q = p;
  ASSERT_EQ(q.step(f0, f1, 0.1, 0.0), 1) << q.message;
  EXPECT_EQ(q.isv0[0], 1.0);
  EXPECT_EQ(q.k[2 * 9 + 2], 0.0);  // no operator asked
  GenericPoint r = p;
  ASSERT_EQ(r.step(f0, f1, 0.1, 4.0), 1) << r.message;
  const auto tangent = r.k;
  const double h = 1e-9;
  double scale = 0.0;
  for (double v : tangent) scale = std::max(scale, std::abs(v));
  const std::array<std::array<int, 2>, 9> tensor = {
      {{0, 0}, {1, 1}, {2, 2}, {0, 1}, {1, 0}, {0, 2}, {2, 0}, {1, 2}, {2, 1}}};
  for (int b = 0; b < 9; ++b) {
    Eigen::Matrix3d fp = f1, fm = f1;
    fp(tensor[b][0], tensor[b][1]) += h;
    fm(tensor[b][0], tensor[b][1]) -= h;
    GenericPoint plus = p, minus = p;
    ASSERT_EQ(plus.step(f0, fp, 0.1, 0.0), 1);
    ASSERT_EQ(minus.step(f0, fm, 0.1, 0.0), 1);
    for (int a = 0; a < 6; ++a) {
      const double fd =
          (plus.sig0[static_cast<std::size_t>(a)] - minus.sig0[static_cast<std::size_t>(a)]) /
          (2 * h);
      EXPECT_NEAR(tangent[static_cast<std::size_t>(9 * a + b)], fd, 1e-6 * scale) << a << ", " << b;
    }
  }
}

// The largest difference, relative to the largest entry, between K (d sigma / d F1, 6 x 9) of
// the step F0 -> F1 from p's state and central differences of the behaviour's own Cauchy stress
// in each component of F1.
double tangent_error(const GenericPoint& p, const Eigen::Matrix3d& f0, const Eigen::Matrix3d& f1,
                     double dt) {
  GenericPoint at = p;
  EXPECT_EQ(at.step(f0, f1, dt, 4.0), 1) << at.message;
  double scale = 0.0;
  for (double v : at.k) scale = std::max(scale, std::abs(v));
  const std::array<std::array<int, 2>, 9> tensor = {
      {{0, 0}, {1, 1}, {2, 2}, {0, 1}, {1, 0}, {0, 2}, {2, 0}, {1, 2}, {2, 1}}};
  const double h = 1e-8;
  double error = 0.0;
  for (int b = 0; b < 9; ++b) {
    Eigen::Matrix3d fp = f1, fm = f1;
    fp(tensor[b][0], tensor[b][1]) += h;
    fm(tensor[b][0], tensor[b][1]) -= h;
    GenericPoint plus = p, minus = p;
    EXPECT_EQ(plus.step(f0, fp, dt, 0.0), 1);
    EXPECT_EQ(minus.step(f0, fm, dt, 0.0), 1);
    for (std::size_t a = 0; a < 6; ++a) {
      const double fd = (plus.sig0[a] - minus.sig0[a]) / (2 * h);
      error = std::max(error, std::abs(at.k[9 * a + static_cast<std::size_t>(b)] - fd) / scale);
    }
  }
  return error;
}

// d sigma / d F1 is the derivative of the finite increment (MFront's DSIG_DF): tension with
// shear turning 0.1 rad per step, an elasto-plastic step and an elastic (unloading) one.
TEST(FeMgis, TheTangentIsTheDerivativeOfTheFiniteIncrement) {
  const Library lib;
  ASSERT_TRUE(lib.loaded()) << dlerror();
  GenericPoint p{reinterpret_cast<Integrate>(
      const_cast<void*>(lib.symbol<void>("SubslipFCC_Tridimensional")))};
  Eigen::Matrix3d g;
  g << -0.5e-3, 2e-3, 0.0, 0.0, -0.5e-3, 0.0, 0.0, 0.0, 1e-3;  // [1/s]
  const double dt = 0.2;                                       // [s]
  auto rotation = [](double t) {
    return subslip::crystal::rotation_exp(Eigen::Vector3d(1.0, 2.0, 3.0).normalized() * 0.5 * t);
  };
  auto motion = [&](double t) {
    return Eigen::Matrix3d(rotation(t) * (Eigen::Matrix3d::Identity() + t * g));
  };
  for (int k = 1; k <= 12; ++k) ASSERT_EQ(p.step(motion(dt * (k - 1)), motion(dt * k), dt, 0.0), 1);
  const Eigen::Matrix3d f0 = motion(12 * dt);
  const double plastic = tangent_error(p, f0, motion(13 * dt), dt);
  const Eigen::Matrix3d back =
      rotation(13 * dt) * (Eigen::Matrix3d::Identity() + (12 * dt - 0.02) * g);
  GenericPoint unloaded = p;
  ASSERT_EQ(unloaded.step(f0, back, dt, 0.0), 1);
  for (int a = 0; a < 12; ++a)  // slip unchanged: an elastic step
    EXPECT_EQ(unloaded.isv0[static_cast<std::size_t>(16 + 24 + a + 1)],
              p.isv0[static_cast<std::size_t>(16 + 24 + a + 1)]);
  const double elastic = tangent_error(p, f0, back, dt);
  std::printf("d sigma / d F1 against central differences: plastic %.2e, elastic %.2e\n", plastic,
              elastic);
  EXPECT_LT(plastic, 1e-6);
  EXPECT_LT(elastic, 1e-6);
}

TEST(FeMgis, AFailureReturnsMinusOneWithAMessage) {
  const Library lib;
  ASSERT_TRUE(lib.loaded()) << dlerror();
  GenericPoint p{reinterpret_cast<Integrate>(
      const_cast<void*>(lib.symbol<void>("SubslipFCC_Tridimensional")))};
  p.mps[SUBSLIP_UMAT_R_HAT - SUBSLIP_UMAT_C11] = 0.5;
  Eigen::Matrix3d f1 = Eigen::Matrix3d::Identity();
  f1(2, 2) += 1e-4;
  const auto isv1 = p.isv1;
  EXPECT_EQ(p.step(Eigen::Matrix3d::Identity(), f1, 0.1, 4.0), -1);
  EXPECT_NE(std::string(p.message).find("r_hat"), std::string::npos) << p.message;
  EXPECT_LT(p.rdt, 1.0);
  EXPECT_EQ(p.isv1, isv1);
}

}  // namespace
