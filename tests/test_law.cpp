#include <gtest/gtest.h>

#include "subslip/law/subloading_friction.hpp"

using namespace subslip::law;

TEST(Law, Placeholder) { EXPECT_GT(SubloadingFrictionLaw(LawParameters{}).subloading_rate(0.5), 0.0); }
