#include "mav/common/stats.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>

namespace mav {
namespace {

std::vector<double> OneTo(int n) {
  std::vector<double> v(static_cast<size_t>(n));
  std::iota(v.begin(), v.end(), 1.0);
  return v;
}

TEST(StatsTest, NearestRankOfTwentySamplesIsNotTheMaximum) {
  std::vector<double> v = OneTo(20);
  std::reverse(v.begin(), v.end());  // order must not matter
  const RuntimeStats s = SummarizeRuntimes(v);
  EXPECT_EQ(s.count, 20u);
  EXPECT_DOUBLE_EQ(s.mean_ms, 10.5);
  EXPECT_DOUBLE_EQ(s.median_ms, 10.5);
  EXPECT_DOUBLE_EQ(s.p95_ms, 19.0);
  EXPECT_DOUBLE_EQ(s.p99_ms, 20.0);
  EXPECT_DOUBLE_EQ(s.max_ms, 20.0);
}

TEST(StatsTest, HundredSamples) {
  const RuntimeStats s = SummarizeRuntimes(OneTo(100));
  EXPECT_DOUBLE_EQ(s.p95_ms, 95.0);
  EXPECT_DOUBLE_EQ(s.p99_ms, 99.0);
  EXPECT_DOUBLE_EQ(s.median_ms, 50.5);
}

TEST(StatsTest, OneAndNoSamples) {
  const RuntimeStats one = SummarizeRuntimes({7.0});
  EXPECT_DOUBLE_EQ(one.median_ms, 7.0);
  EXPECT_DOUBLE_EQ(one.p95_ms, 7.0);
  EXPECT_DOUBLE_EQ(one.p99_ms, 7.0);
  const RuntimeStats none = SummarizeRuntimes({});
  EXPECT_EQ(none.count, 0u);
  EXPECT_DOUBLE_EQ(none.max_ms, 0.0);
}

TEST(StatsTest, WindowKeepsOnlyTheLastSamples) {
  RuntimeWindow window(10);
  for (int i = 1; i <= 25; ++i) window.Add(i);
  EXPECT_EQ(window.size(), 10u);
  EXPECT_EQ(window.total_count(), 25u);
  const RuntimeStats s = window.Summary();
  EXPECT_EQ(s.count, 10u);
  EXPECT_DOUBLE_EQ(s.max_ms, 25.0);
  EXPECT_DOUBLE_EQ(s.mean_ms, 20.5);  // 16..25
  window.Clear();
  EXPECT_EQ(window.size(), 0u);
  EXPECT_EQ(window.total_count(), 0u);
}

}  // namespace
}  // namespace mav

namespace mav {
namespace {

constexpr int64_t kMs = 1'000'000;

// The clock is the test's: 100 Hz for 1.5 s, then silence.
TEST(RateMeterTest, WindowsPartialRateAndStaleness) {
  RateMeter meter;  // 1 s windows, stale after 2 s
  EXPECT_EQ(meter.Rate(0), 0.0);
  meter.Add(0);
  EXPECT_EQ(meter.Rate(0), 0.0);  // one event is no rate
  for (int i = 1; i <= 50; ++i) meter.Add(i * 10 * kMs);
  EXPECT_DOUBLE_EQ(meter.Rate(500 * kMs), 100.0);  // before the first whole window: so far
  for (int i = 51; i <= 150; ++i) meter.Add(i * 10 * kMs);
  EXPECT_NEAR(meter.Rate(1500 * kMs), 100.0, 1e-9);  // the first window: 100 Hz, not 101
  EXPECT_GT(meter.Rate(3400 * kMs), 0.0);
  EXPECT_EQ(meter.Rate(3600 * kMs), 0.0);  // more than 2 s after the last event
  meter.Clear();
  EXPECT_EQ(meter.Rate(1500 * kMs), 0.0);
}

}  // namespace
}  // namespace mav
