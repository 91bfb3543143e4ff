#include "mav/planning/trajectory.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "test_maps.h"

namespace mav::planning {
namespace {

using geometry::EvaluatePolynomial;
using geometry::PolynomialTrajectory;

// Free space everywhere in a big box: the clearance is always the saturation.
class OpenSpace : public ClearanceMap {
 public:
  double Clearance(const Eigen::Vector3d&) const override { return 5.0; }
  const Box& bounds() const override { return bounds_; }
  double resolution() const override { return 0.25; }
  double robot_radius() const override { return 0.5; }
  double max_distance() const override { return 5.0; }
  uint64_t fingerprint() const override { return 1; }

 private:
  Box bounds_{{-100, -100, -100}, {100, 100, 100}};
};

// Value of derivative n of segment i at local time tau, per axis.
Eigen::Vector3d Derivative(const PolynomialTrajectory& t, size_t i, double tau, int n) {
  Eigen::Vector3d out;
  for (int a = 0; a < 3; ++a) {
    out[a] = EvaluatePolynomial(t.segments()[i].coefficients.row(a).transpose(), tau, n);
  }
  return out;
}

TEST(QuinticSplineTest, InterpolatesIsC4AndAtRestAtBothEnds) {
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(-5, 5), dt(0.1, 0.6);
  for (int trial = 0; trial < 20; ++trial) {
    const int n = 2 + trial;
    std::vector<double> times = {0};
    std::vector<Eigen::Vector3d> points = {{u(rng), u(rng), u(rng)}};
    for (int i = 1; i < n; ++i) {
      times.push_back(times.back() + dt(rng));
      points.emplace_back(u(rng), u(rng), u(rng));
    }
    auto spline = FitQuinticSpline(times, points);
    ASSERT_TRUE(spline.ok()) << spline.status().ToString();
    const PolynomialTrajectory& t = *spline;
    ASSERT_EQ(t.segments().size(), static_cast<size_t>(n - 1));
    EXPECT_NEAR(t.duration_s(), times.back(), 1e-12);
    for (int i = 0; i < n; ++i) {
      EXPECT_LT((t.Evaluate(times[i]).position - points[i]).norm(), 1e-9) << "knot " << i;
    }
    for (int d : {1, 2}) {
      EXPECT_LT(t.EvaluateDerivative(0, d).norm(), 1e-9) << "start, derivative " << d;
      EXPECT_LT(t.EvaluateDerivative(t.duration_s(), d).norm(), 1e-9) << "end, derivative " << d;
    }
    // At every joint: derivatives 0..4 from the left (end of segment i) equal those from the
    // right (start of segment i + 1); relative to the size of the derivative.
    for (size_t i = 0; i + 1 < t.segments().size(); ++i) {
      const double tau = t.segments()[i].duration_s;
      for (int d = 0; d <= 4; ++d) {
        const Eigen::Vector3d left = Derivative(t, i, tau, d), right = Derivative(t, i + 1, 0, d);
        EXPECT_LT((left - right).norm(), 1e-7 * (1 + left.norm())) << "joint " << i << " d " << d;
      }
      // The same numerically, through the trajectory's own evaluation 1e-7 s either side: a
      // jump would show; a continuous derivative moves by at most the next one times 2e-7 s.
      const double joint = times[i + 1];
      for (int d = 0; d <= 4; ++d) {
        const Eigen::Vector3d before = t.EvaluateDerivative(joint - 1e-7, d);
        const Eigen::Vector3d after = t.EvaluateDerivative(joint + 1e-7, d);
        const double next =
            std::max(Derivative(t, i, tau, d + 1).norm(), Derivative(t, i + 1, 0, d + 1).norm());
        EXPECT_LE((after - before).norm(), 3e-7 * next + 1e-9 * (1 + before.norm()))
            << "joint " << i << " d " << d;
      }
    }
  }
}

TEST(QuinticSplineTest, BadInput) {
  EXPECT_EQ(FitQuinticSpline({0}, {{0, 0, 0}}).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(FitQuinticSpline({0, 1}, {{0, 0, 0}}).status().code(), StatusCode::kInvalidArgument);
  auto r = FitQuinticSpline({0, 1, 1}, {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}});
  EXPECT_NE(r.status().message().find("times_s[2]"), std::string::npos);
  r = FitQuinticSpline({0, 1}, {{0, 0, 0}, {NAN, 0, 0}});
  EXPECT_NE(r.status().message().find("points[1]"), std::string::npos);
}

// Samples every millisecond and checks the limits with the rule of trajectory.h.
void ExpectWithinLimits(const PolynomialTrajectory& t, const SpeedLimits& limits) {
  const double tol = 1e-6;
  for (double s = 0; s <= t.duration_s(); s += 0.001) {
    const Eigen::Vector3d v = t.EvaluateDerivative(s, 1), a = t.EvaluateDerivative(s, 2);
    const double speed = v.norm();
    ASSERT_LE(speed, limits.max_speed_mps * (1 + tol)) << "t " << s;
    if (speed > 0.3) {
      const Eigen::Vector3d dir = v / speed;
      const double along = a.dot(dir), across = (a - along * dir).norm();
      ASSERT_LE(std::abs(along), limits.max_acceleration_mps2 * (1 + tol)) << "t " << s;
      ASSERT_LE(across, limits.max_lateral_acceleration_mps2 * (1 + tol)) << "t " << s;
    } else {
      ASSERT_LE(
          a.norm(),
          std::max(limits.max_acceleration_mps2, limits.max_lateral_acceleration_mps2) * (1 + tol))
          << "t " << s;
    }
  }
}

TEST(SpeedPlanTest, RespectsTheLimitsOnStraightAndTurningPaths) {
  const OpenSpace space;
  std::mt19937 rng(8);
  std::uniform_real_distribution<double> u(-20, 20);
  for (int trial = 0; trial < 12; ++trial) {
    std::vector<Eigen::Vector3d> path = {{0, 0, 0}};
    for (int i = 0; i < 2 + trial % 5; ++i) path.emplace_back(u(rng), u(rng), u(rng) * 0.2);
    TrajectoryOptions options;
    options.limits.max_speed_mps = trial % 2 ? 4.0 : 10.0;
    options.limits.max_acceleration_mps2 = trial % 3 ? 3.0 : 6.0;
    options.limits.max_lateral_acceleration_mps2 = trial % 4 ? 2.0 : 7.0;
    auto result = PlanTrajectory(space, path, {}, options);
    ASSERT_TRUE(result.ok()) << result.status().ToString();
    ExpectWithinLimits(result->trajectory, options.limits);
    EXPECT_LT((result->trajectory.Evaluate(0).position - path.front()).norm(), 1e-9);
    EXPECT_LT((result->trajectory.Evaluate(result->duration_s).position - path.back()).norm(),
              1e-9);
    EXPECT_LT(result->trajectory.EvaluateDerivative(result->duration_s, 1).norm(), 1e-9);
    EXPECT_GT(result->mean_speed_mps, 0.1 * options.limits.max_speed_mps);
    EXPECT_LE(result->max_speed_mps, options.limits.max_speed_mps * (1 + 1e-6));
  }
}

TEST(SpeedPlanTest, ALongStraightLineReachesTheSpeedLimit) {
  const OpenSpace space;
  auto result = PlanTrajectory(space, {{0, 0, 0}, {60, 0, 0}}, {}, TrajectoryOptions{});
  ASSERT_TRUE(result.ok());
  const SpeedLimits limits;
  EXPECT_GT(result->max_speed_mps, 0.9 * limits.max_speed_mps);
  // Rest to rest at the limits: at least L / v + v / a; our plan is within 15 % of that.
  const double bound =
      60 / limits.max_speed_mps + limits.max_speed_mps / limits.max_acceleration_mps2;
  EXPECT_GT(result->duration_s, bound);
  EXPECT_LT(result->duration_s, 1.15 * bound);
  // The path stays on the line.
  for (double t = 0; t < result->duration_s; t += 0.05) {
    const Eigen::Vector3d p = result->trajectory.Evaluate(t).position;
    EXPECT_LT(std::hypot(p.y(), p.z()), 1e-9);
  }
}

TEST(SpeedPlanTest, StopsAtWaypoints) {
  const OpenSpace space;
  const std::vector<Eigen::Vector3d> path = {{0, 0, 0}, {10, 0, 0}, {10, 10, 0}, {20, 10, 0}};
  auto through = PlanTrajectory(space, path, {}, TrajectoryOptions{});
  auto stopping = PlanTrajectory(space, path, {2}, TrajectoryOptions{});
  ASSERT_TRUE(through.ok() && stopping.ok());
  // Speed where the trajectory comes closest to the corner path[2], and how close.
  const auto at_corner = [&](const PolynomialTrajectory& t, double* closest) {
    double speed = 0;
    *closest = 1e9;
    for (double s = 0; s < t.duration_s(); s += 0.002) {
      const double d = (t.Evaluate(s).position - path[2]).norm();
      if (d < *closest) {
        *closest = d;
        speed = t.EvaluateDerivative(s, 1).norm();
      }
    }
    return speed;
  };
  double closest = 0;
  // The stop is passed exactly, nearly at rest; without it the corner is rounded at speed.
  EXPECT_LT(at_corner(stopping->trajectory, &closest), 0.2);
  EXPECT_LT(closest, 1e-3);
  EXPECT_GT(at_corner(through->trajectory, &closest), 2.0);
  EXPECT_GT(closest, 0.1);
}

TEST(SpeedPlanTest, TheSplineKeepsTheClearanceAroundTheWall) {
  const auto map = testing::RoomMap();
  ASSERT_NE(map, nullptr);
  // Around the wall's end, 0.6 m from it: the corners are rounded and checked.
  const std::vector<Eigen::Vector3d> path = {
      {2, 1.5, 3.5}, {3.4, 7.65, 3.5}, {6.6, 7.65, 3.5}, {8, 2, 3.5}};
  for (size_t i = 1; i < path.size(); ++i)
    ASSERT_TRUE(map->IsSegmentValid(path[i - 1], path[i], 0.6));
  auto result = PlanTrajectory(*map, path, {}, TrajectoryOptions{});
  ASSERT_TRUE(result.ok()) << result.status().ToString();
  EXPECT_GE(result->min_clearance_m, 0.5);
  double worst = 1e9;
  for (double t = 0; t <= result->duration_s; t += 0.0005) {
    worst = std::min(worst, map->Clearance(result->trajectory.Evaluate(t).position));
  }
  EXPECT_GE(worst, 0.5);
  ExpectWithinLimits(result->trajectory, SpeedLimits{});
}

TEST(SpeedPlanTest, ViolationsAreRepairedNotReturned) {
  const auto map = testing::RoomMap();
  ASSERT_NE(map, nullptr);
  // Corners hugging the wall's end at 0.55 m, arcs allowed down to the radius itself and knots
  // 1.5 s apart: the first spline strays closer than 0.5 m; the repairs (closer knots, lower
  // speed, smaller arcs) must bring it back, and what comes back keeps the radius everywhere.
  const std::vector<Eigen::Vector3d> path = {
      {1.5, 1.0, 3.5}, {3.45, 7.55, 3.5}, {6.55, 7.55, 3.5}, {8.5, 1.0, 3.5}};
  TrajectoryOptions options;
  options.corner_clearance_m = 0.5005;
  options.knot_interval_s = 1.5;
  auto result = PlanTrajectory(*map, path, {}, options);
  ASSERT_TRUE(result.ok()) << result.status().ToString();
  EXPECT_GT(result->refits, 0);
  double worst = 1e9;
  for (double t = 0; t <= result->duration_s; t += 0.0005) {
    worst = std::min(worst, map->Clearance(result->trajectory.Evaluate(t).position));
  }
  EXPECT_GE(worst, 0.5 - 1e-3);  // at the 1 cm check steps >= 0.5 exactly; between, 0.5 mm less
  EXPECT_GE(result->min_clearance_m, 0.5);
  // With no repairs allowed the same input is refused, not returned.
  options.max_refits = 0;
  auto refused = PlanTrajectory(*map, path, {}, options);
  EXPECT_EQ(refused.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(refused.status().message().find("closer than"), std::string::npos);
}

TEST(SpeedPlanTest, OptionsNameTheField) {
  TrajectoryOptions options;
  options.limits.max_speed_mps = 0;
  std::string why;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_NE(why.find("limits.max_speed_mps"), std::string::npos);
  options = TrajectoryOptions{};
  options.knot_interval_s = 5;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_NE(why.find("knot_interval_s"), std::string::npos);
  const OpenSpace space;
  EXPECT_EQ(PlanTrajectory(space, {{0, 0, 0}}, {}, {}).status().code(),
            StatusCode::kInvalidArgument);
  EXPECT_EQ(PlanTrajectory(space, {{0, 0, 0}, {0, 0, 0}}, {}, {}).status().code(),
            StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace mav::planning
