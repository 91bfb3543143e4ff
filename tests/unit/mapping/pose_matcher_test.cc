#include "mav/mapping/pose_matcher.h"

#include <gtest/gtest.h>

namespace mav::mapping {
namespace {

struct Frame {
  int64_t t_ns = 0;
};

geometry::SE3 At(double x) { return geometry::SE3(Eigen::Quaterniond::Identity(), {x, 0, 0}); }

PoseMatcherOptions Options(PoseMatcherOptions::Mode mode, int64_t wait_ns) {
  PoseMatcherOptions o;
  o.mode = mode;
  o.wait_ns = wait_ns;
  return o;
}

TEST(PoseMatcherTest, GroundTruthIsInterpolatedAtTheFrameTime) {
  PoseMatcher<Frame> matcher(Options(PoseMatcherOptions::Mode::kInterpolate, 1'000'000'000));
  uint64_t dropped = 0;
  EXPECT_TRUE(matcher.AddPose(1'000'000'000, At(1.0), &dropped).empty());
  // Frame between two samples 5 ms apart: waits for the later one, then gets the interpolation.
  EXPECT_TRUE(matcher.AddFrame({1'002'000'000}, 0, &dropped).empty());
  EXPECT_EQ(matcher.pending(), 1u);
  auto matched = matcher.AddPose(1'005'000'000, At(2.0), &dropped);
  ASSERT_EQ(matched.size(), 1u);
  EXPECT_NEAR(matched[0].T_world_body.Translation().x(), 1.4, 1e-9);
  // Exactly on a sample.
  matched = matcher.AddFrame({1'005'000'000}, 0, &dropped);
  ASSERT_EQ(matched.size(), 1u);
  EXPECT_NEAR(matched[0].T_world_body.Translation().x(), 2.0, 1e-12);
  // A frame older than the history, or in a gap over 25 ms, has no pose.
  EXPECT_TRUE(matcher.AddFrame({900'000'000}, 0, &dropped).empty());
  EXPECT_EQ(dropped, 1u);
  matcher.AddPose(1'100'000'000, At(3.0), &dropped);
  EXPECT_TRUE(matcher.AddFrame({1'050'000'000}, 0, &dropped).empty());
  EXPECT_EQ(dropped, 2u);
  EXPECT_EQ(matcher.pending(), 0u);
}

TEST(PoseMatcherTest, LocalizationPosesMatchExactlyAndPendingFramesExpire) {
  PoseMatcher<Frame> matcher(Options(PoseMatcherOptions::Mode::kExact, 100'000'000));
  uint64_t dropped = 0;
  // Frames arrive before the estimator's poses.
  EXPECT_TRUE(matcher.AddFrame({50}, 0, &dropped).empty());
  EXPECT_TRUE(matcher.AddFrame({100}, 0, &dropped).empty());
  auto matched = matcher.AddPose(50, At(5.0), &dropped);
  ASSERT_EQ(matched.size(), 1u);
  EXPECT_EQ(matched[0].frame.t_ns, 50);
  // The estimator skipped frame 100: a newer pose decides it has none.
  EXPECT_TRUE(matcher.AddPose(150, At(6.0), &dropped).empty());
  EXPECT_EQ(dropped, 1u);
  // No pose at all: expires after the wait.
  EXPECT_TRUE(matcher.AddFrame({200}, 1'000, &dropped).empty());
  EXPECT_EQ(matcher.Expire(50'000'000), 0u);
  EXPECT_EQ(matcher.Expire(200'000'000), 1u);
}

TEST(PoseMatcherTest, HistoryAndPendingFramesAreBounded) {
  PoseMatcherOptions o = Options(PoseMatcherOptions::Mode::kInterpolate, 1'000'000'000);
  o.max_history = 10;
  o.max_pending = 3;
  PoseMatcher<Frame> matcher(o);
  uint64_t dropped = 0;
  for (int i = 0; i < 100; ++i) matcher.AddPose(i * 5'000'000, At(i), &dropped);
  EXPECT_EQ(matcher.history().size(), 10u);
  // A repeated stamp replaces the sample; an out-of-order one is inserted in place.
  matcher.AddPose(99 * 5'000'000, At(-1), &dropped);
  EXPECT_EQ(matcher.history().size(), 10u);
  for (int i = 0; i < 5; ++i) matcher.AddFrame({int64_t{10'000'000'000} + i}, 0, &dropped);
  EXPECT_EQ(matcher.pending(), 3u);
  EXPECT_EQ(dropped, 2u);
}

}  // namespace
}  // namespace mav::mapping
