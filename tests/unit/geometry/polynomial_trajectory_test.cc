#include "mav/geometry/polynomial_trajectory.h"

#include <gtest/gtest.h>

#include <cmath>

namespace mav::geometry {
namespace {

// p(t) = 1 + 2t + 3t^2 on x, a constant on y, t^5 on z.
PolynomialSegment Segment(double duration) {
  PolynomialSegment s;
  s.duration_s = duration;
  s.coefficients.row(0) << 1, 2, 3, 0, 0, 0;
  s.coefficients.row(1) << 4, 0, 0, 0, 0, 0;
  s.coefficients.row(2) << 0, 0, 0, 0, 0, 1;
  return s;
}

TEST(PolynomialTrajectoryTest, EvaluatesValueAndDerivatives) {
  auto t = PolynomialTrajectory::Create({Segment(2.0)});
  ASSERT_TRUE(t.ok()) << t.status().ToString();
  const TrajectoryPoint p = t->Evaluate(1.5);
  EXPECT_DOUBLE_EQ(p.position.x(), 1 + 3 + 3 * 2.25);
  EXPECT_DOUBLE_EQ(p.velocity.x(), 2 + 6 * 1.5);
  EXPECT_DOUBLE_EQ(p.acceleration.x(), 6);
  EXPECT_DOUBLE_EQ(p.jerk.x(), 0);
  EXPECT_DOUBLE_EQ(p.position.y(), 4);
  EXPECT_NEAR(p.position.z(), std::pow(1.5, 5), 1e-12);
  EXPECT_NEAR(p.snap.z(), 120 * 1.5, 1e-12);
  EXPECT_NEAR(t->EvaluateDerivative(1.5, 5).z(), 120, 1e-12);
}

TEST(PolynomialTrajectoryTest, SegmentsAreLocatedAndTimeIsClamped) {
  PolynomialSegment second = Segment(1.0);
  second.coefficients.row(1)[0] = 9;
  auto t = PolynomialTrajectory::Create({Segment(2.0), second});
  ASSERT_TRUE(t.ok());
  EXPECT_DOUBLE_EQ(t->duration_s(), 3.0);
  EXPECT_DOUBLE_EQ(t->Evaluate(1.999).position.y(), 4);
  EXPECT_DOUBLE_EQ(t->Evaluate(2.0).position.y(), 9);
  EXPECT_DOUBLE_EQ(t->Evaluate(2.5).position.x(), 1 + 1 + 0.75);  // local time 0.5
  EXPECT_DOUBLE_EQ(t->Evaluate(-1).position.x(), 1);
  EXPECT_DOUBLE_EQ(t->Evaluate(10).position.x(), 1 + 2 + 3);  // end of segment 2 (tau = 1)
  EXPECT_DOUBLE_EQ(t->Evaluate(10).t_s, 3.0);
  const auto samples = t->Sample(0.4);
  ASSERT_EQ(samples.size(), 9u);  // 0, 0.4, ..., 2.8, then the end 3.0
  EXPECT_DOUBLE_EQ(samples.back().t_s, 3.0);
}

TEST(PolynomialTrajectoryTest, RejectsBadInputNamingTheField) {
  EXPECT_EQ(PolynomialTrajectory::Create({}).status().code(), StatusCode::kInvalidArgument);
  PolynomialSegment bad = Segment(0.0);
  auto r = PolynomialTrajectory::Create({Segment(1.0), bad});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message().rfind("segments[1].duration_s", 0), 0u) << r.status().message();
  PolynomialSegment nan = Segment(1.0);
  nan.coefficients(2, 3) = std::nan("");
  EXPECT_FALSE(PolynomialTrajectory::Create({nan}).ok());
  EXPECT_FALSE(PolynomialTrajectory::Create({Segment(1.0)}, YawPolicy::kSegment).ok());
}

TEST(PolynomialTrajectoryTest, YawPolicies) {
  auto along = PolynomialTrajectory::Create({Segment(2.0)}, YawPolicy::kAlongPath, 0.3);
  ASSERT_TRUE(along.ok());
  EXPECT_DOUBLE_EQ(along->Evaluate(1.0).yaw_rad, 0.0);  // moving along +x
  PolynomialSegment s = Segment(1.0);
  s.yaw = Vector6d::Zero();
  (*s.yaw)[1] = 0.5;
  auto seg = PolynomialTrajectory::Create({s}, YawPolicy::kSegment);
  ASSERT_TRUE(seg.ok());
  EXPECT_DOUBLE_EQ(seg->Evaluate(0.5).yaw_rad, 0.25);
  EXPECT_DOUBLE_EQ(seg->Evaluate(0.5).yaw_rate_radps, 0.5);
  auto constant = PolynomialTrajectory::Create({Segment(1.0)}, YawPolicy::kConstant, 1.2);
  EXPECT_DOUBLE_EQ(constant->Evaluate(0.5).yaw_rad, 1.2);
}

TEST(PolynomialTrajectoryTest, TranslatedShiftsPositionsOnly) {
  auto t = PolynomialTrajectory::Create({Segment(2.0)});
  const PolynomialTrajectory moved = t->Translated({1, -1, 2});
  EXPECT_DOUBLE_EQ(moved.Evaluate(1.0).position.x(), t->Evaluate(1.0).position.x() + 1);
  EXPECT_DOUBLE_EQ(moved.Evaluate(1.0).velocity.x(), t->Evaluate(1.0).velocity.x());
  EXPECT_DOUBLE_EQ(moved.Evaluate(1.0).position.z(), t->Evaluate(1.0).position.z() + 2);
}

}  // namespace
}  // namespace mav::geometry
