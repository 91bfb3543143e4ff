#include "mav/planning/path.h"

#include <gtest/gtest.h>

#include <random>

#include "mav/planning/planner.h"
#include "test_maps.h"

namespace mav::planning {
namespace {

TEST(PathCostTest, TermsOfAStraightSegment) {
  const auto map = testing::RoomMap();
  ASSERT_NE(map, nullptr);
  const std::vector<Eigen::Vector3d> path = {{1, 8, 1}, {1, 8, 3}, {3, 8, 3}};
  CostWeights w{2.0, 0.5, 0.25};
  const PathCost c = EvaluatePathCost(*map, w, path);
  EXPECT_NEAR(c.length_m, 4.0, 1e-12);
  EXPECT_NEAR(c.altitude_change_m, 2.0, 1e-12);
  EXPECT_GT(c.clearance_cost, 0.0);
  EXPECT_NEAR(c.total, 2.0 * 4 + 0.5 * c.clearance_cost + 0.25 * 2, 1e-9);
  // The closest approach: (1, 8, 1) is 1 m above the map's floor and 1 m from its x = 0 face.
  EXPECT_NEAR(c.min_clearance_m, 1.0, 1e-9);
  // The penalty vanishes at the saturation and grows towards the obstacles.
  EXPECT_EQ(ProximityPenalty(5.0, 5.0), 0.0);
  EXPECT_NEAR(ProximityPenalty(0.5, 5.0), 1.8, 1e-12);
  EXPECT_GT(ProximityPenalty(0.4, 5.0), ProximityPenalty(0.6, 5.0));
  std::string why;
  EXPECT_FALSE((CostWeights{1, -1, 0}).IsValid(&why));
  EXPECT_NE(why.find("clearance"), std::string::npos);
  EXPECT_FALSE((CostWeights{0, 0, 0}).IsValid(&why));
}

// Raw roadmap paths between random valid points of the room, shortened with several bounds.
class ShortenTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_NE(testing::RoomMap(), nullptr);
    RoadmapOptions options;
    options.max_milestones = 800;
    options.seed = 9;
    roadmap_ = *Roadmap::Build(*testing::RoomMap(), options);
  }
  std::shared_ptr<const Roadmap> roadmap_;
};

TEST_F(ShortenTest, NeverExceedsTheCostBoundAndKeepsTheEnds) {
  const PlanningMap& map = *testing::RoomMap();
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0, 1);
  int tested = 0, shorter = 0;
  const double required = map.robot_radius() + roadmap_->info().clearance_margin_m;
  for (int trial = 0; trial < 200 && tested < 40; ++trial) {
    PlanRequest request;
    request.start = {u(rng) * 4, u(rng) * 10, 0.6 + u(rng) * 3.8};
    request.goal = {6 + u(rng) * 4, u(rng) * 10, 0.6 + u(rng) * 3.8};
    auto result = PlanPath(map, roadmap_.get(), request);
    if (!result.ok() || result->path.size() < 3) continue;
    ++tested;
    for (const CostWeights& w : {CostWeights{}, CostWeights{1, 0, 0}, CostWeights{1, 1, 1}}) {
      const double raw_cost = EvaluatePathCost(map, w, result->path).total;
      for (double bound : {0.0, 0.1, 0.5}) {
        ShortenOptions options;
        options.max_cost_increase = bound;
        options.required_clearance_m = required;
        const std::vector<Eigen::Vector3d> out = ShortenPath(map, w, result->path, options);
        ASSERT_GE(out.size(), 2u);
        EXPECT_EQ(out.front(), result->path.front());
        EXPECT_EQ(out.back(), result->path.back());
        const PathCost c = EvaluatePathCost(map, w, out);
        EXPECT_LE(c.total, (1 + bound) * raw_cost * (1 + 1e-9)) << "bound " << bound;
        for (size_t i = 1; i < out.size(); ++i) {
          // New segments keep the required clearance; the raw path's own first and last
          // segments may only keep the radius (their ends can be closer).
          EXPECT_TRUE(map.IsSegmentValid(out[i - 1], out[i], map.robot_radius()));
        }
        if (w.clearance == 0 && w.altitude == 0) {
          EXPECT_LE(c.length_m, PathLength(result->path) + 1e-9);
          shorter += c.length_m < PathLength(result->path) - 1e-3;
        }
      }
    }
  }
  EXPECT_GE(tested, 30);
  EXPECT_GT(shorter, tested);  // the length-only runs did shorten
}

TEST_F(ShortenTest, ZeroBoundNeverRaisesTheCost) {
  const PlanningMap& map = *testing::RoomMap();
  // A detour around the wall's end through raw waypoints far from it.
  const std::vector<Eigen::Vector3d> raw = {{1.5, 1.5, 3.5}, {2, 6, 3.5}, {3, 9, 3.5},
                                            {5, 9.2, 3.5},   {7, 9, 3.5}, {8, 5, 3.5},
                                            {8, 2, 3.5}};
  for (size_t i = 1; i < raw.size(); ++i) ASSERT_TRUE(map.IsSegmentValid(raw[i - 1], raw[i], 0.6));
  const CostWeights w;
  ShortenOptions options;
  options.max_cost_increase = 0;
  options.required_clearance_m = 0.6;
  const auto out = ShortenPath(map, w, raw, options);
  EXPECT_LE(EvaluatePathCost(map, w, out).total, EvaluatePathCost(map, w, raw).total + 1e-9);
  EXPECT_LT(PathLength(out), PathLength(raw));
  // Without a bound on the length-only cost it pulls taut around the wall's end: the shortest
  // path keeping 0.6 m is tangent to the circles of 0.6 m around the wall's vertical edges
  // (4, 7) and (6, 7), follows them to their tops and runs straight between them.
  options.max_cost_increase = 10;
  options.corner_passes = 40;
  const auto taut = ShortenPath(map, CostWeights{1, 0, 0}, raw, options);
  const auto around = [](const Eigen::Vector2d& s, const Eigen::Vector2d& c, double r,
                         double sign) {
    const double d = (s - c).norm();
    const double to_s = std::atan2(s.y() - c.y(), s.x() - c.x());
    const double touch = to_s + sign * std::acos(r / d);  // the tangent point's angle
    return std::sqrt(d * d - r * r) + r * std::abs(std::remainder(touch - M_PI / 2, 2 * M_PI));
  };
  const double shortest =
      around({1.5, 1.5}, {4, 7}, 0.6, -1) + 2.0 + around({8, 2}, {6, 7}, 0.6, 1);
  EXPECT_NEAR(PathLength(taut), shortest, 0.02);
  options.corner_passes = ShortenOptions{}.corner_passes;  // the default stops earlier
  EXPECT_NEAR(PathLength(ShortenPath(map, CostWeights{1, 0, 0}, raw, options)), shortest, 0.05);
  EXPECT_GE(EvaluatePathCost(map, CostWeights{}, taut).min_clearance_m, 0.6 - 0.005);
}

TEST(ShortenOptionsTest, IsValidNamesTheField) {
  ShortenOptions options;
  options.max_cost_increase = -0.1;
  std::string why;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_NE(why.find("max_cost_increase"), std::string::npos);
  options = ShortenOptions{};
  options.corner_passes = -1;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_NE(why.find("corner_passes"), std::string::npos);
}

}  // namespace
}  // namespace mav::planning
