#include "mav/common/pacing.h"

#include <cstdint>
#include <limits>

#include <gtest/gtest.h>

namespace mav {
namespace {

constexpr int64_t kMs = 1'000'000;

// The test states every time: no sleeps, no clock.
TEST(RealTimePacerTest, DueTimesFollowTheFactor) {
  RealTimePacer pacer(2.0, 200 * kMs);
  pacer.Anchor(/*t_ns=*/10'000 * kMs, /*wall_ns=*/5 * kMs);
  EXPECT_EQ(pacer.DueNs(10'000 * kMs, 5 * kMs), 5 * kMs);
  EXPECT_EQ(pacer.DueNs(10'100 * kMs, 5 * kMs), 55 * kMs);  // 100 ms of data in 50 ms
  pacer.set_factor(0.5);
  EXPECT_EQ(pacer.DueNs(10'100 * kMs, 5 * kMs), 205 * kMs);
}

TEST(RealTimePacerTest, FarBehindStartsAnewInsteadOfBursting) {
  RealTimePacer pacer(1.0, 200 * kMs);
  pacer.Anchor(0, 0);
  // 150 ms late: within the lateness allowed, the schedule stays (the caller runs at once).
  EXPECT_EQ(pacer.DueNs(100 * kMs, 250 * kMs), 100 * kMs);
  EXPECT_EQ(pacer.anchor_wall_ns(), 0);
  // 300 ms late: re-anchored at (t, now); the next step is due one step later, not at once.
  EXPECT_EQ(pacer.DueNs(200 * kMs, 500 * kMs), 500 * kMs);
  EXPECT_EQ(pacer.anchor_t_ns(), 200 * kMs);
  EXPECT_EQ(pacer.DueNs(250 * kMs, 510 * kMs), 550 * kMs);
}

TEST(RealTimePacerTest, NoOverflowAtTheSlowestFactorOverLongData) {
  RealTimePacer pacer(0.001, 200 * kMs);
  pacer.Anchor(0, 1'000 * kMs);
  const int64_t ten_days_ns = int64_t{10} * 24 * 3600 * 1'000'000'000;
  const int64_t due = pacer.DueNs(ten_days_ns, 1'000 * kMs);
  EXPECT_GT(due, 1'000 * kMs);  // saturated far in the future, not wrapped negative
  EXPECT_LT(due, std::numeric_limits<int64_t>::max());
}

}  // namespace
}  // namespace mav
