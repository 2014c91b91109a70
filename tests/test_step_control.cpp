// The adaptive step clock (integrators/step_control.hpp): the noise floor of the error estimate
// (issue 15, item 6). A true local error falls as dt^2 when a rejected step is retried shorter;
// an estimate that stays put while the step shrinks by 1e3 is round-off, and the clock stops
// there with a message naming the tolerance, instead of crawling down to dt ~ 1e-20.
#include <gtest/gtest.h>

#include <string>

#include "subslip/integrators/step_control.hpp"

using subslip::integrators::AdaptiveSegment;

// An estimate that does not fall: stopped once the step is 1e3 times shorter, with the message.
TEST(StepControl, EstimateThatDoesNotFallStopsAtTheNoiseFloor) {
  AdaptiveSegment clock(1.0, 1e-2, 1e-9);
  int refusals = 0;
  while (clock.refuse(false, 3e-9)) ++refusals;
  EXPECT_TRUE(clock.at_noise_floor());
  EXPECT_LE(clock.step(), 1e-5);
  EXPECT_LT(refusals, 20);  // 0.1 x per refusal at most: a few refusals, not a crawl to 1e-20
  const std::string why = clock.noise_floor_message();
  EXPECT_NE(why.find("no longer falls as the step shrinks (3e-09 at dt = 0.01"), std::string::npos)
      << why;
  EXPECT_NE(why.find("the tolerance 1e-09 is below what double precision resolves here; use a "
                     "tolerance above 3e-09"),
            std::string::npos)
      << why;
}

// An estimate that falls as dt^2 is a real error: retried until it fits, never a floor.
TEST(StepControl, EstimateThatFallsAsDtSquaredIsRetriedUntilItFits) {
  AdaptiveSegment clock(1.0, 1e-2, 1e-9);
  const double c = 1e-3 / (1e-2 * 1e-2);  // error 1e-3 at the first step
  double error = c * clock.step() * clock.step();
  int refusals = 0;
  while (error > 1e-9) {
    ASSERT_TRUE(clock.refuse(false, error));
    ASSERT_FALSE(clock.at_noise_floor());
    error = c * clock.step() * clock.step();
    ++refusals;
  }
  EXPECT_GT(refusals, 2);
  clock.accept(error);
  EXPECT_FALSE(clock.at_noise_floor());
}

// Failed attempts (no solution) halve the step without an estimate: no floor from them.
TEST(StepControl, FailedAttemptsAreNoNoiseFloor) {
  AdaptiveSegment clock(1.0, 1e-2, 1e-9);
  for (int i = 0; i < 15; ++i) ASSERT_TRUE(clock.refuse(true, 0.0));
  EXPECT_FALSE(clock.at_noise_floor());
  EXPECT_TRUE(clock.refuse(false, 3e-9));  // the first estimate: the start of a new run
  EXPECT_FALSE(clock.at_noise_floor());
}
