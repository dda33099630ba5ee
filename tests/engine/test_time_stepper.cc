// The time step schedule: halving down to the floor, growing back on the coarser grid.
#include <gtest/gtest.h>

#include "activefoam/time_stepper.h"

using namespace activefoam;

TEST(TimeStepper, HalvesDownToTheFloorAndGrowsBackOnlyOnTheCoarserGrid) {
  TimeStepper s(0.5, 0.5 / 64, true);
  EXPECT_EQ(s.maxLevel(), 6);
  EXPECT_EQ(s.minDt(), 0.5 / 64);
  EXPECT_EQ(s.ticksPerBaseStep(), 64);
  // A decimal floor a hair above Δt/2^k still allows that halving; one clearly above does not.
  EXPECT_EQ(TimeStepper(0.1, 0.1 / 64, true).maxLevel(), 6);
  EXPECT_EQ(TimeStepper(0.1, 0.00156, true).maxLevel(), 6);
  EXPECT_EQ(TimeStepper(0.1, 0.002, true).maxLevel(), 5);
  EXPECT_EQ(TimeStepper(0.1, 0.1, true).maxLevel(), 0);
  EXPECT_EQ(TimeStepper(0.1, 0.001, false).maxLevel(), 0);  // not adaptive: never halves
  EXPECT_FALSE(TimeStepper(0.1, 0.001, false).canHalve());

  // Without halving, t = ticks · Δt/2^K is bit-identical to steps · Δt.
  TimeStepper plain(0.1, 0.1 / 64, true);
  for (int k = 1; k <= 1000; ++k) {
    plain.accept();
    ASSERT_EQ(plain.time(), static_cast<double>(k) * 0.1) << k;
  }

  s.accept();  // t = 0.5
  s.halve();   // 0.25
  s.halve();   // 0.125
  EXPECT_EQ(s.dt(), 0.125);
  EXPECT_EQ(s.growthWait(), TimeStepper::kGrowAfter);
  for (int k = 0; k < TimeStepper::kGrowAfter; ++k) s.accept();  // t = 1.0: on the 0.25 grid
  EXPECT_EQ(s.dt(), 0.25);
  EXPECT_EQ(s.time(), 1.0);
  s.accept();  // t = 1.25: one good step at 0.25
  s.halve();   // fails soon after growing: back to 0.125, and the next growth waits twice as long
  EXPECT_EQ(s.growthWait(), 2 * TimeStepper::kGrowAfter);
  for (int k = 0; k < 2 * TimeStepper::kGrowAfter - 1; ++k) s.accept();
  EXPECT_EQ(s.dt(), 0.125);
  s.accept();  // t = 2.25, on the 0.25 grid
  EXPECT_EQ(s.time(), 2.25);
  EXPECT_EQ(s.dt(), 0.25);
  // Eight good steps at 0.25 land at 4.25, not on the 0.5 grid: it waits for 4.5.
  for (int k = 0; k < 2 * TimeStepper::kGrowAfter; ++k) s.accept();
  EXPECT_EQ(s.time(), 4.25);
  EXPECT_EQ(s.dt(), 0.25);
  s.accept();
  EXPECT_EQ(s.time(), 4.5);
  EXPECT_EQ(s.dt(), 0.5);
  // 2 × max(4 × wait, kRecent) = 128 steps without a failure (17 so far) halve the wait again.
  for (int k = 0; k < 110; ++k) s.accept();
  EXPECT_EQ(s.growthWait(), 2 * TimeStepper::kGrowAfter);
  s.accept();
  EXPECT_EQ(s.growthWait(), TimeStepper::kGrowAfter);
  // A failure long after the last growth does not lengthen the wait.
  for (int k = 0; k < 100; ++k) s.accept();
  s.halve();
  EXPECT_EQ(s.growthWait(), TimeStepper::kGrowAfter);
  for (int k = 0; k < TimeStepper::kGrowAfter; ++k) s.accept();
  EXPECT_EQ(s.dt(), 0.5);
  // The schedule's state round-trips.
  TimeStepper copy(0.5, 0.5 / 64, true);
  copy.setState(s.state());
  EXPECT_EQ(copy.time(), s.time());
  EXPECT_EQ(copy.dt(), s.dt());
  EXPECT_EQ(copy.growthWait(), s.growthWait());
  EXPECT_EQ(s.ticks() % s.ticksPerBaseStep(), 0);
  EXPECT_EQ(s.ticksFor(2.5), 5 * 64);
}
