// crystal/measures.hpp, the one implementation of the derived measures (run summary, subslip
// post, the Python package): von Mises values of known states, the equivalent plastic strain of
// single slip (reversals accumulate), weighted means, and shape errors.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <vector>

#include "subslip/crystal/measures.hpp"

using namespace subslip;

TEST(Measures, VonMisesOfUniaxialAndShearStates) {
  // Uniaxial stress 100 along z, plus a hydrostatic part that must not count.
  Eigen::Matrix3d s = Eigen::Matrix3d::Identity() * 40.0;
  s(2, 2) += 100.0;
  EXPECT_NEAR(crystal::von_mises_stress(s), 100.0, 1e-12);
  // Pure shear tau: sqrt(3) tau, whichever of the two off-diagonal entries carries it.
  Eigen::Matrix3d shear = Eigen::Matrix3d::Zero();
  shear(0, 1) = 20.0;  // sym part: 10 in both (0, 1) and (1, 0)
  EXPECT_NEAR(crystal::von_mises_stress(shear), std::sqrt(3.0) * 10.0, 1e-12);
  // Isochoric uniaxial strain: eps.
  const Eigen::Matrix3d e = Eigen::Vector3d(-0.005, -0.005, 0.01).asDiagonal();
  EXPECT_NEAR(crystal::von_mises_strain(e), 0.01, 1e-15);
}

TEST(Measures, ArraysAreRowMajorTensorsOneValueEach) {
  // Two tensors as a result file stores them, [k, i, j], nine values each: the first gives
  // what the matrix form gives, the second (a shear 7 in (1, 2) only, tensor shear 3.5) its own.
  const std::vector<double> t = {1, 2, 3, 4, 5, 6, 7, 8, 10,  //
                                 0, 0, 0, 0, 0, 7, 0, 0, 0};
  const auto vm = crystal::von_mises_stress(t);
  ASSERT_EQ(vm.size(), 2u);
  Eigen::Matrix3d m;
  m << 1, 2, 3, 4, 5, 6, 7, 8, 10;
  EXPECT_EQ(vm[0], crystal::von_mises_stress(m));
  EXPECT_NEAR(vm[1], std::sqrt(3.0) * 3.5, 1e-12);
  EXPECT_THROW(crystal::von_mises_strain(std::vector<double>(10, 0.0)), std::invalid_argument);
}

TEST(Measures, EquivalentPlasticStrainAccumulatesSingleSlip) {
  // Two systems: s = x on m = y (shear 12), s = y on m = z (shear 23). Grain 0 slips 0.3
  // forward on system 0, then 0.2 back; grain 1 slips 0.1 on system 1. Slip g on one system is
  // a tensor shear of g/2: von Mises equivalent g/sqrt(3); a reversal adds.
  const std::vector<double> systems = {1, 0, 0, 0, 1, 0, 0, 1, 0, 0, 0, 1};
  const std::vector<double> slip = {0,   0, 0, 0,  //
                                    0.3, 0, 0, 0.1, 0.1, 0, 0, 0.1};
  const auto eps = crystal::equivalent_plastic_strain(slip, 3, 2, systems);
  const double r3 = std::sqrt(3.0);
  ASSERT_EQ(eps.size(), 6u);
  EXPECT_EQ(eps[0], 0.0);
  EXPECT_EQ(eps[1], 0.0);
  EXPECT_NEAR(eps[2], 0.3 / r3, 1e-15);
  EXPECT_NEAR(eps[3], 0.1 / r3, 1e-15);
  EXPECT_NEAR(eps[4], 0.5 / r3, 1e-15);
  EXPECT_NEAR(eps[5], 0.1 / r3, 1e-15);
  EXPECT_THROW(crystal::equivalent_plastic_strain(slip, 4, 2, systems), std::invalid_argument);
}

TEST(Measures, WeightedMeanOfAbsoluteValuesNormalisesTheWeights) {
  // rows 2, grains 2, k 2; weights 1 : 3 (not summing to 1).
  const std::vector<double> v = {1, -2, -3, 0,  //
                                 0, 4,  2,  -8};
  const auto m = crystal::weighted_mean_abs(v, 2, 2, std::vector<double>{1.0, 3.0});
  ASSERT_EQ(m.size(), 4u);
  EXPECT_NEAR(m[0], 0.25 * 1 + 0.75 * 3, 1e-15);
  EXPECT_NEAR(m[1], 0.25 * 2, 1e-15);
  EXPECT_NEAR(m[2], 0.75 * 2, 1e-15);
  EXPECT_NEAR(m[3], 0.25 * 4 + 0.75 * 8, 1e-15);
  EXPECT_THROW(crystal::weighted_mean_abs(v, 2, 2, std::vector<double>{1.0}),
               std::invalid_argument);
}
