#include "mav/mapping/keyframes.h"

#include <cmath>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

namespace mav::mapping {
namespace {

using geometry::SE3;

constexpr int64_t kFramePeriodNs = 50'000'000;  // 20 Hz

std::vector<StampedCameraPose> Line(int frames, double spacing_m) {
  std::vector<StampedCameraPose> poses;
  poses.reserve(frames);
  for (int k = 0; k < frames; ++k) {
    poses.push_back({k * kFramePeriodNs, SE3(Eigen::Quaterniond::Identity(),
                                             Eigen::Vector3d(k * spacing_m, 1.0, 2.0))});
  }
  return poses;
}

std::vector<StampedCameraPose> Yaw(int frames, double step_rad, const Eigen::Vector3d& axis) {
  std::vector<StampedCameraPose> poses;
  poses.reserve(frames);
  for (int k = 0; k < frames; ++k) {
    poses.push_back({k * kFramePeriodNs,
                     SE3(Eigen::Quaterniond(Eigen::AngleAxisd(k * step_rad, axis.normalized())),
                         Eigen::Vector3d(0.5, -1.0, 1.5))});
  }
  return poses;
}

TEST(KeyframesTest, StraightLineAtKnownSpacing) {
  KeyframeOptions options;
  options.min_translation_m = 0.25;
  options.min_rotation_rad = 0.2;
  // 0.1 m apart: the distance to the last keyframe reaches 0.3 m >= 0.25 m every third frame.
  auto kf = SelectKeyframes(Line(10, 0.1), options);
  ASSERT_TRUE(kf.ok()) << kf.status().ToString();
  EXPECT_EQ(*kf, (std::vector<int64_t>{0, 3, 6, 9}));

  // 0.07 m apart: 0.28 m after four frames.
  kf = SelectKeyframes(Line(14, 0.07), options);
  ASSERT_TRUE(kf.ok());
  EXPECT_EQ(*kf, (std::vector<int64_t>{0, 4, 8, 12}));

  // Steps above the threshold: every frame is a keyframe.
  kf = SelectKeyframes(Line(5, 0.3), options);
  ASSERT_TRUE(kf.ok());
  EXPECT_EQ(*kf, (std::vector<int64_t>{0, 1, 2, 3, 4}));
}

TEST(KeyframesTest, PureRotationTriggersTheRotationThreshold) {
  KeyframeOptions options;
  options.min_translation_m = 0.25;
  options.min_rotation_rad = 0.25;
  // 0.1 rad per frame about a tilted axis, no translation: 0.3 rad every third frame.
  auto kf = SelectKeyframes(Yaw(10, 0.1, Eigen::Vector3d(0.2, -0.3, 1.0)), options);
  ASSERT_TRUE(kf.ok());
  EXPECT_EQ(*kf, (std::vector<int64_t>{0, 3, 6, 9}));

  // Rotations below the threshold never trigger; translation alone does.
  options.min_rotation_rad = 10.0;
  kf = SelectKeyframes(Yaw(10, 0.1, Eigen::Vector3d::UnitZ()), options);
  ASSERT_TRUE(kf.ok());
  EXPECT_EQ(*kf, (std::vector<int64_t>{0}));
}

TEST(KeyframesTest, DistanceIsMeasuredToTheLastKeyframeNotThePreviousFrame) {
  KeyframeOptions options;
  options.min_translation_m = 0.25;
  // Slow drift of 1.1 cm per frame: frame-to-frame motion never passes, accumulated motion does
  // (0.253 m after 23 frames).
  auto kf = SelectKeyframes(Line(60, 0.011), options);
  ASSERT_TRUE(kf.ok());
  EXPECT_EQ(*kf, (std::vector<int64_t>{0, 23, 46}));
}

TEST(KeyframesTest, EitherThresholdTriggers) {
  KeyframeOptions options;
  options.min_translation_m = 0.25;
  options.min_rotation_rad = 0.25;
  std::vector<StampedCameraPose> poses;
  // Frames 0-2 translate 0.1 m each (frame 3 reaches 0.3 m), frames 4-6 then rotate 0.15 rad each
  // in place (frame 5 reaches 0.3 rad from keyframe 3).
  const Eigen::Vector3d axis = Eigen::Vector3d::UnitY();
  for (int k = 0; k <= 3; ++k) {
    poses.push_back(
        {k * kFramePeriodNs, SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.1 * k, 0, 0))});
  }
  for (int k = 4; k <= 6; ++k) {
    poses.push_back(
        {k * kFramePeriodNs, SE3(Eigen::Quaterniond(Eigen::AngleAxisd(0.15 * (k - 3), axis)),
                                 Eigen::Vector3d(0.3, 0, 0))});
  }
  auto kf = SelectKeyframes(poses, options);
  ASSERT_TRUE(kf.ok());
  EXPECT_EQ(*kf, (std::vector<int64_t>{0, 3, 5}));
}

TEST(KeyframesTest, IncrementalSelectorMatchesBatchAndResets) {
  const auto poses = Line(30, 0.06);
  auto batch = SelectKeyframes(poses);
  ASSERT_TRUE(batch.ok());
  KeyframeSelector selector;
  std::vector<int64_t> incremental;
  for (size_t i = 0; i < poses.size(); ++i) {
    if (selector.Consider(poses[i].T_world_cam)) incremental.push_back(static_cast<int64_t>(i));
  }
  EXPECT_EQ(incremental, *batch);
  EXPECT_EQ(selector.num_keyframes(), static_cast<int64_t>(batch->size()));
  selector.Reset();
  EXPECT_EQ(selector.num_keyframes(), 0);
  EXPECT_TRUE(selector.Consider(poses[5].T_world_cam));  // first after Reset
  EXPECT_FALSE(selector.Consider(poses[6].T_world_cam));
}

TEST(KeyframesTest, EmptyInputGivesNoKeyframes) {
  auto kf = SelectKeyframes({});
  ASSERT_TRUE(kf.ok());
  EXPECT_TRUE(kf->empty());
}

TEST(KeyframesTest, DefaultsAreValid) {
  std::string why;
  EXPECT_TRUE(KeyframeOptions().IsValid(&why)) << why;
}

TEST(KeyframesTest, InvalidOptionsNameTheField) {
  KeyframeOptions options;
  options.min_translation_m = 0.0;
  auto kf = SelectKeyframes(Line(3, 0.1), options);
  ASSERT_FALSE(kf.ok());
  EXPECT_EQ(kf.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(kf.status().message().find("options.min_translation_m"), std::string::npos)
      << kf.status().message();

  options = KeyframeOptions();
  options.min_rotation_rad = std::numeric_limits<double>::quiet_NaN();
  kf = SelectKeyframes(Line(3, 0.1), options);
  ASSERT_FALSE(kf.ok());
  EXPECT_NE(kf.status().message().find("options.min_rotation_rad"), std::string::npos)
      << kf.status().message();

  options.min_rotation_rad = -1.0;
  std::string why;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_NE(why.find("min_rotation_rad"), std::string::npos);
}

TEST(KeyframesTest, BadPosesNameTheIndex) {
  auto poses = Line(5, 0.1);
  poses[3].t_ns = poses[2].t_ns;
  auto kf = SelectKeyframes(poses);
  ASSERT_FALSE(kf.ok());
  EXPECT_EQ(kf.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(kf.status().message().find("poses[3].t_ns"), std::string::npos)
      << kf.status().message();

  poses = Line(5, 0.1);
  poses[2].T_world_cam = SE3(Eigen::Quaterniond::Identity(),
                             Eigen::Vector3d(std::numeric_limits<double>::infinity(), 0, 0));
  kf = SelectKeyframes(poses);
  ASSERT_FALSE(kf.ok());
  EXPECT_NE(kf.status().message().find("poses[2].T_world_cam"), std::string::npos)
      << kf.status().message();
}

TEST(KeyframesDeathTest, SelectorChecksOptions) {
  KeyframeOptions options;
  options.min_translation_m = -1.0;
  EXPECT_DEATH(KeyframeSelector selector(options), "min_translation_m");
}

}  // namespace
}  // namespace mav::mapping
