#include "mav/eval/trajectory_metrics.h"

#include <gtest/gtest.h>

#include <cmath>

namespace mav::eval {
namespace {

using geometry::SE3;

// A straight line along x at 1 m per frame.
std::vector<SE3> Line(int n, double step_m = 1.0) {
  std::vector<SE3> poses;
  poses.reserve(n);
  for (int i = 0; i < n; ++i) {
    poses.emplace_back(Eigen::Quaterniond::Identity(), Eigen::Vector3d(i * step_m, 0, 0));
  }
  return poses;
}

TEST(RelativeErrorTest, PerfectEstimateHasZeroError) {
  const auto gt = Line(100);
  const auto r = ComputeRelativeError(gt, gt, RelativeErrorOptions());
  ASSERT_TRUE(r.ok());
  ASSERT_TRUE(r->average_pct.has_value());
  EXPECT_NEAR(*r->average_pct, 0.0, 1e-12);
  ASSERT_EQ(r->per_length.size(), 8u);
  // 100 poses span 99 m: every length has segments.
  for (const auto& e : r->per_length) EXPECT_GT(e.segments, 0) << e.length_m;
}

TEST(RelativeErrorTest, ScaleErrorShowsAsThatPercentage) {
  // The estimate travels 2 % too far: every segment is off by 2 % of its length.
  const auto gt = Line(101);
  const auto est = Line(101, 1.02);
  const auto r = ComputeRelativeError(est, gt, RelativeErrorOptions());
  ASSERT_TRUE(r.ok());
  for (const auto& e : r->per_length) EXPECT_NEAR(e.translation_error_pct, 2.0, 1e-9);
  EXPECT_NEAR(*r->average_pct, 2.0, 1e-9);
}

TEST(RelativeErrorTest, SegmentsAreAlignedAtTheirFirstFrame) {
  // A constant offset (wrong start) must not count: relative error is motion-based.
  const auto gt = Line(50);
  std::vector<SE3> est;
  const SE3 offset(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ())),
                   Eigen::Vector3d(5, -2, 1));
  est.reserve(gt.size());
  for (const SE3& p : gt) est.push_back(offset * p);
  const auto r = ComputeRelativeError(est, gt, RelativeErrorOptions());
  ASSERT_TRUE(r.ok());
  EXPECT_NEAR(*r->average_pct, 0.0, 1e-9);
}

TEST(RelativeErrorTest, HandComputedSegmentCountsAndShortTrajectories) {
  // 11 poses, 1 m apart: 10 m in all. Step 1. Length 2 m: starts 0..8 -> 9 segments.
  // Length 10 m: only start 0. Length 15 m: none.
  RelativeErrorOptions options;
  options.lengths_m = {2, 10, 15};
  options.step = 1;
  const auto gt = Line(11);
  const auto r = ComputeRelativeError(gt, gt, options);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->per_length[0].segments, 9);
  EXPECT_EQ(r->per_length[1].segments, 1);
  EXPECT_EQ(r->per_length[2].segments, 0);
  // An estimate that drifts 0.5 m sideways at the last frame only.
  auto est = gt;
  est.back() = SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(10, 0.5, 0));
  const auto d = ComputeRelativeError(est, gt, options);
  ASSERT_TRUE(d.ok());
  // 2 m: one of 9 segments (start 8) has error 0.5/2 -> mean 2.777..%; 10 m: 0.5/10 = 5 %.
  EXPECT_NEAR(d->per_length[0].translation_error_pct, 100.0 * 0.25 / 9.0, 1e-9);
  EXPECT_NEAR(d->per_length[1].translation_error_pct, 5.0, 1e-9);
  EXPECT_NEAR(*d->average_pct, (100.0 * 0.25 / 9.0 + 5.0) / 2.0, 1e-9);
}

TEST(RelativeErrorTest, BadInputNamesTheField) {
  const auto gt = Line(10);
  const auto r = ComputeRelativeError(Line(9), gt, RelativeErrorOptions());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("estimate"), std::string::npos);
  RelativeErrorOptions options;
  options.step = 0;
  const auto s = ComputeRelativeError(gt, gt, options);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.status().message().find("step"), std::string::npos);
}

TEST(AteTest, RigidlyMovedCopyHasZeroErrorAndNoiseShows) {
  std::vector<SE3> gt;
  gt.reserve(50);
  for (int i = 0; i < 50; ++i) {
    gt.emplace_back(Eigen::Quaterniond::Identity(),
                    Eigen::Vector3d(std::cos(0.2 * i), std::sin(0.2 * i), 0.05 * i));
  }
  const SE3 offset(
      Eigen::Quaterniond(Eigen::AngleAxisd(1.0, Eigen::Vector3d(1, 2, 3).normalized())),
      Eigen::Vector3d(3, 4, 5));
  std::vector<SE3> est;
  est.reserve(gt.size());
  for (const SE3& p : gt) est.push_back(offset * p);
  EXPECT_NEAR(*AbsoluteTrajectoryRmse(est, gt), 0.0, 1e-9);
  // Alternate +-0.1 m along z: alignment cannot remove it (mean zero), RMSE is 0.1.
  for (size_t i = 0; i < est.size(); ++i) {
    est[i] =
        SE3(gt[i].Rotation(), gt[i].Translation() + Eigen::Vector3d(0, 0, i % 2 == 0 ? 0.1 : -0.1));
  }
  EXPECT_NEAR(*AbsoluteTrajectoryRmse(est, gt), 0.1, 2e-3);
}

TEST(EndPointTest, DistanceAfterFirstPoseAlignment) {
  const auto gt = Line(11);
  auto est = Line(11, 1.1);  // ends at 11 m instead of 10
  EXPECT_NEAR(*EndPointError(est, gt), 1.0, 1e-12);
  EXPECT_NEAR(PathLength(gt), 10.0, 1e-12);
}

TEST(AssociateTest, InterpolatesGroundTruthAtEstimateTimes) {
  std::vector<dataset::StampedPose> gt = {
      {0, SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 0))},
      {100, SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 0, 0))}};
  std::vector<dataset::StampedPose> est = {{-5, SE3()}, {25, SE3()}, {100, SE3()}, {150, SE3()}};
  const auto a = AssociateByTime(est, gt);
  ASSERT_TRUE(a.ok());
  ASSERT_EQ(a->t_ns.size(), 2u);  // -5 and 150 are outside the span
  EXPECT_NEAR(a->ground_truth[0].Translation().x(), 0.25, 1e-12);
  EXPECT_NEAR(a->ground_truth[1].Translation().x(), 1.0, 1e-12);
  gt[1].t_ns = 0;
  EXPECT_FALSE(AssociateByTime(est, gt).ok());
}

}  // namespace
}  // namespace mav::eval

namespace mav::eval {
namespace {

std::vector<dataset::StampedPose> Stamped(const std::vector<geometry::SE3>& poses, int64_t t0_ns) {
  std::vector<dataset::StampedPose> out;
  out.reserve(poses.size());
  for (size_t i = 0; i < poses.size(); ++i) {
    out.push_back({t0_ns + static_cast<int64_t>(i) * 50'000'000, poses[i]});
  }
  return out;
}

std::vector<geometry::SE3> Straight(int n, double step_m) {
  std::vector<geometry::SE3> poses;
  poses.reserve(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    poses.emplace_back(Eigen::Quaterniond::Identity(), Eigen::Vector3d(i * step_m, 0, 0));
  }
  return poses;
}

TEST(EvaluateTrajectoryTest, GathersEveryFigureAtTheEstimatesFrames) {
  const auto gt = Stamped(Straight(101, 1.0), 0);
  // The estimate is 2 % too long and covers frames 10..100 only.
  std::vector<geometry::SE3> est_poses;
  for (int i = 10; i <= 100; ++i) {
    est_poses.emplace_back(Eigen::Quaterniond::Identity(),
                           Eigen::Vector3d(10 + (i - 10) * 1.02, 0, 0));
  }
  const auto est = Stamped(est_poses, 10 * 50'000'000);
  Result<TrajectoryAccuracy> a = EvaluateTrajectory(est, gt, RelativeErrorOptions());
  ASSERT_TRUE(a.ok()) << a.status().ToString();
  EXPECT_EQ(a->associated.t_ns.size(), 91u);
  EXPECT_EQ(a->associated.t_ns.front(), 10 * 50'000'000);
  EXPECT_NEAR(a->path_length_m, 90.0, 1e-9);  // of the truth at the estimate's frames
  ASSERT_TRUE(a->relative.average_pct.has_value());
  EXPECT_NEAR(*a->relative.average_pct, 2.0, 1e-6);
  EXPECT_NEAR(a->end_point_error_m, 90 * 0.02, 1e-9);
  EXPECT_GT(a->ate_rmse_m, 0.0);
}

TEST(EvaluateTrajectoryTest, TooFewFramesNamesTheCount) {
  const auto gt = Stamped(Straight(10, 1.0), 0);
  const auto est = Stamped(Straight(2, 1.0), 0);
  Result<TrajectoryAccuracy> a = EvaluateTrajectory(est, gt, RelativeErrorOptions());
  ASSERT_FALSE(a.ok());
  EXPECT_EQ(a.status().message(), "too few frames to evaluate (2)");
}

}  // namespace
}  // namespace mav::eval
