// The Fortran driver (tests/fe/umat_driver.f90, gfortran, CALL UMAT(...)) against the
// material-point API on its paths: uniaxial stress with its own Newton iteration on the lateral
// strains, simple shear out and back, and uniaxial stress at finite strain (each increment a
// stretch exp(E), the native grain under L = E / dt). Skipped where the build found no Fortran compiler.
#include <gtest/gtest.h>

#include <cstdio>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "umat_call.hpp"

namespace {

using namespace subslip::fe_testing;

// Each line of the driver's output by path letter: the increment's STRESS(6) and STATEV(89).
std::map<char, std::vector<std::vector<double>>> run_driver(const std::string& program) {
  std::map<char, std::vector<std::vector<double>>> out;
  FILE* pipe = popen(program.c_str(), "r");
  if (!pipe) return out;
  char line[8192];
  while (std::fgets(line, sizeof line, pipe)) {
    std::istringstream in(line);
    char path;
    int k;
    in >> path >> k;
    std::vector<double> values;
    std::string v;
    while (in >> v) values.push_back(std::stod(v));
    out[path].push_back(values);
  }
  EXPECT_EQ(pclose(pipe), 0) << program << " failed";
  return out;
}

void expect_line(const std::vector<double>& line, const pt::Mandel6& stress,
                 const pt::GrainState& s, const std::string& what) {
  ASSERT_EQ(line.size(), 6u + 89u) << what;
  const auto expected = abaqus_stress(stress);
  double scale = 0.0;
  for (double v : expected) scale = std::max(scale, std::abs(v));
  for (std::size_t i = 0; i < 6; ++i)
    EXPECT_NEAR(line[i], expected[i], 1e-10 * scale) << what << " STRESS(" << i + 1 << ")";
  const double* statev = line.data() + 6;
  EXPECT_EQ(statev[0], 1.0);
  for (int field = 0; field < 3; ++field) {  // mu, r_s, slip
    const pt::SlipVector& v = field == 0 ? s.mu : field == 1 ? s.r_s : s.slip;
    const double vs = std::max(v.cwiseAbs().maxCoeff(), 1e-300);
    for (int a = 0; a < 12; ++a)
      EXPECT_NEAR(statev[1 + 16 + 12 * field + a], v(a), 1e-10 * vs) << what << " field " << field;
  }
}

TEST(FeFortran, DriverCallingUmatEqualsTheNativeGrain) {
#ifndef SUBSLIP_FE_FORTRAN_DRIVER
  GTEST_SKIP() << "no Fortran compiler in this build";
#else
  const auto out = run_driver(SUBSLIP_FE_FORTRAN_DRIVER);
  ASSERT_EQ(out.count('U'), 1u);
  ASSERT_EQ(out.count('S'), 1u);
  ASSERT_EQ(out.count('F'), 1u);
  ASSERT_EQ(out.at('U').size(), 50u);
  ASSERT_EQ(out.at('S').size(), 90u);
  ASSERT_EQ(out.at('F').size(), 50u);
  const pt::GrainPoint grain(fcc_parameters());
  const Eigen::Matrix3d g = orientation_of({30, 40, 50});
  pt::GrainState s = grain.initial_state(g);
  for (const char path : {'U', 'F'}) {
    s = grain.initial_state(g);
    for (int k = 1; k <= 50; ++k) {
      const pt::GrainUpdate u = native_uniaxial_step(grain, s, k > 20 ? -2e-4 : 2e-4, 0.2);
      s = u.state;
      expect_line(out.at(path)[static_cast<std::size_t>(k - 1)], u.stress, s,
                  std::string(path == 'U' ? "uniaxial" : "finite-strain uniaxial") +
                      " increment " + std::to_string(k));
    }
  }
  s = grain.initial_state(g);
  for (int k = 1; k <= 90; ++k) {
    const std::array<double, 6> dstran{0, 0, 0, k > 30 ? -2e-4 : 2e-4, 0, 0};
    const pt::GrainUpdate u = grain.update(s, rate_of(dstran, 0.1), 0.1);
    ASSERT_TRUE(u.report.ok);
    s = u.state;
    expect_line(out.at('S')[static_cast<std::size_t>(k - 1)], u.stress, s,
                "shear increment " + std::to_string(k));
  }
#endif
}

}  // namespace
