#include "mav/planning/planner.h"

#include <gtest/gtest.h>

#include <cmath>
#include <thread>

#include "test_maps.h"

namespace mav::planning {
namespace {

class PlannerTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    ASSERT_NE(testing::RoomMap(), nullptr);
    RoadmapOptions options;
    options.max_milestones = 1500;
    options.seed = 2;
    auto built = Roadmap::Build(*testing::RoomMap(), options);
    ASSERT_TRUE(built.ok()) << built.status().ToString();
    roadmap_ = new std::shared_ptr<const Roadmap>(*built);
  }
  static void TearDownTestSuite() { delete roadmap_; }
  static const PlanningMap& map() { return *testing::RoomMap(); }
  static const Roadmap* roadmap() { return roadmap_->get(); }

  static PlanRequest Request(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    PlanRequest r;
    r.start = a;
    r.goal = b;
    return r;
  }

  static std::shared_ptr<const Roadmap>* roadmap_;
};
std::shared_ptr<const Roadmap>* PlannerTest::roadmap_ = nullptr;

// Every 1 cm along the trajectory, exactly.
double MinClearanceAlong(const ClearanceMap& map, const PlanResult& r) {
  double worst = 1e9;
  const double dt = 0.01 / std::max(0.1, r.max_speed_mps);
  for (double t = 0; t <= r.duration_s; t += dt) {
    worst = std::min(worst, map.Clearance(r.trajectory.Evaluate(t).position));
  }
  return worst;
}

TEST_F(PlannerTest, AroundTheWall) {
  auto r = PlanPath(map(), roadmap(), Request({2, 3, 2.5}, {8, 3, 2.5}));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->status, PlanStatus::kSuccess) << r->message;
  EXPECT_EQ(r->path.front(), Eigen::Vector3d(2, 3, 2.5));
  EXPECT_EQ(r->shortened_path.back(), Eigen::Vector3d(8, 3, 2.5));
  // Around the wall's end at y = 7: at least 2 * hypot(2, 4.1) + 2 - a little.
  EXPECT_GT(r->shortened_cost.length_m, 2 * std::hypot(2.0, 4.1) + 2 - 0.5);
  EXPECT_LE(r->shortened_cost.length_m, r->path_cost.length_m + 1e-9);
  EXPECT_LE(r->shortened_cost.total, 1.1 * r->path_cost.total + 1e-9);
  EXPECT_GE(r->shortened_cost.min_clearance_m, 0.5);
  EXPECT_GE(r->trajectory_min_clearance_m, 0.5);
  EXPECT_GE(MinClearanceAlong(map(), *r), 0.5);
  EXPECT_GT(r->duration_s, 0);
  EXPECT_NEAR(r->trajectory.duration_s(), r->duration_s, 1e-9);
  EXPECT_GT(r->timings.total_ms, 0);
}

TEST_F(PlannerTest, StraightWhenTheLineIsFree) {
  auto r = PlanPath(map(), roadmap(), Request({1, 8.5, 1}, {7, 8.5, 4}));
  ASSERT_TRUE(r.ok());
  ASSERT_TRUE(r->ok()) << r->message;
  EXPECT_EQ(r->shortened_path.size(), 2u);
  EXPECT_NEAR(r->trajectory_length_m, std::hypot(6.0, 3.0), 1e-3);
}

TEST_F(PlannerTest, InvalidPointsAreNamed) {
  auto r = PlanPath(map(), roadmap(), Request({5, 3, 2}, {8, 3, 2}));  // inside the wall
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->status, PlanStatus::kStartInvalid);
  EXPECT_NE(r->message.find("start"), std::string::npos);
  r = PlanPath(map(), roadmap(), Request({2, 3, 2}, {12, 3, 2}));  // outside the volume
  EXPECT_EQ(r->status, PlanStatus::kGoalInvalid);
  EXPECT_NE(r->message.find("outside the planning volume"), std::string::npos);
  PlanRequest request = Request({2, 3, 2}, {8, 3, 2});
  request.waypoints = {{2, 8, 2}, {3.7, 3, 2}};  // the second is 0.3 m from the wall
  r = PlanPath(map(), roadmap(), request);
  EXPECT_EQ(r->status, PlanStatus::kGoalInvalid);
  EXPECT_EQ(r->invalid_waypoint, 1);
  EXPECT_NE(r->message.find("waypoints[1]"), std::string::npos);
  EXPECT_NE(r->message.find("closer than the robot radius"), std::string::npos);
}

TEST_F(PlannerTest, WaypointsAreVisitedInOrder) {
  PlanRequest request = Request({1.5, 1.5, 1.5}, {8, 2, 1.5});
  request.waypoints = {{2, 9, 3}, {7, 9, 3}};
  auto r = PlanPath(map(), roadmap(), request);
  ASSERT_TRUE(r.ok());
  ASSERT_TRUE(r->ok()) << r->message;
  double t_first = -1, t_second = -1;
  for (double t = 0; t <= r->duration_s; t += 0.002) {
    const Eigen::Vector3d p = r->trajectory.Evaluate(t).position;
    if (t_first < 0 && (p - request.waypoints[0]).norm() < 0.01) t_first = t;
    if (t_second < 0 && (p - request.waypoints[1]).norm() < 0.01) t_second = t;
  }
  EXPECT_GT(t_first, 0);
  EXPECT_GT(t_second, t_first);
  EXPECT_GE(MinClearanceAlong(map(), *r), 0.5);
}

TEST_F(PlannerTest, NoPathIntoAnEnclosure) {
  // A closed box (walls 0.5 m thick) around free space: its inside is valid but unreachable.
  const std::string bytes =
      testing::MakeMapBytes(0.25, Box{{0, 0, 0}, {10, 10, 5}},
                            {Box{{6, 6, 0}, {10, 6.5, 5}}, Box{{6, 6, 0}, {6.5, 10, 5}}});
  MapOptions options;
  const auto enclosure = testing::LoadMap(bytes, options);
  ASSERT_NE(enclosure, nullptr);
  RoadmapOptions ro;
  ro.max_milestones = 800;
  auto rm = Roadmap::Build(*enclosure, ro);
  ASSERT_TRUE(rm.ok());
  auto r = PlanPath(*enclosure, rm->get(), Request({2, 2, 2.5}, {8.2, 8.2, 2.5}));
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->status, PlanStatus::kNoPath) << r->message;
  EXPECT_TRUE(r->trajectory.empty());
}

TEST_F(PlannerTest, CallErrorsAreStatuses) {
  PlanRequest request = Request({NAN, 3, 2}, {8, 3, 2});
  auto r = PlanPath(map(), roadmap(), request);
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("start"), std::string::npos);
  request = Request({2, 3, 2}, {8, 3, 2});
  request.limits.max_speed_mps = -1;
  r = PlanPath(map(), roadmap(), request);
  EXPECT_NE(r.status().message().find("limits.max_speed_mps"), std::string::npos);
  request = Request({2, 3, 2}, {8, 3, 2});
  request.weights.altitude = -1;
  r = PlanPath(map(), roadmap(), request);
  EXPECT_NE(r.status().message().find("weights.altitude"), std::string::npos);

  r = PlanPath(map(), roadmap(), Request({2, 3, 2}, {8, 3, 2}), Termination::AfterMs(0));
  EXPECT_EQ(r.status().code(), StatusCode::kDeadlineExceeded);
  CancelFlag cancel;
  cancel.Cancel();
  r = PlanPath(map(), roadmap(), Request({2, 3, 2}, {8, 3, 2}), Termination().WithCancel(cancel));
  EXPECT_EQ(r.status().code(), StatusCode::kCancelled);

  MapOptions other;
  other.unknown_space = UnknownSpace::kFree;
  const auto open = testing::LoadMap(testing::RoomBytes(), other);
  r = PlanPath(*open, roadmap(), Request({2, 3, 2}, {8, 3, 2}));
  EXPECT_EQ(r.status().code(), StatusCode::kFailedPrecondition);
}

TEST_F(PlannerTest, ConcurrentQueriesGiveTheSameAnswers) {
  std::vector<PlanRequest> requests;
  requests.reserve(12);
  for (int i = 0; i < 12; ++i) {
    requests.push_back(Request({1.5 + 0.1 * i, 1 + 0.5 * i, 1 + 0.2 * i},
                               {8.5 - 0.1 * i, 7 - 0.4 * i, 4 - 0.2 * i}));
  }
  std::vector<std::vector<Eigen::Vector3d>> serial(requests.size()), parallel(requests.size());
  for (size_t i = 0; i < requests.size(); ++i) {
    auto r = PlanPath(map(), roadmap(), requests[i]);
    ASSERT_TRUE(r.ok());
    serial[i] = r->shortened_path;
  }
  std::vector<std::thread> threads;
  threads.reserve(3);
  for (int t = 0; t < 3; ++t) {
    threads.emplace_back([&, t] {
      for (size_t i = t; i < requests.size(); i += 3) {
        auto r = PlanPath(map(), roadmap(), requests[i]);
        if (r.ok()) parallel[i] = r->shortened_path;
      }
    });
  }
  for (std::thread& th : threads) th.join();
  for (size_t i = 0; i < requests.size(); ++i) EXPECT_EQ(serial[i], parallel[i]) << i;
}

TEST_F(PlannerTest, WithoutARoadmapAFreshPrmStarRunsPerLeg) {
  PlanRequest request = Request({2, 3, 2.5}, {8, 3, 2.5});
  request.use_roadmap = false;
  request.time_budget_s = 0.3;
  auto r = PlanPath(map(), roadmap(), request);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_TRUE(r->ok()) << r->message;
  EXPECT_GE(MinClearanceAlong(map(), *r), 0.5);
  // The same with no roadmap at all.
  r = PlanPath(map(), nullptr, request);
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(r->ok()) << r->message;
}

TEST_F(PlannerTest, OmplPeersRunTheSameTrajectoryStage) {
  for (OmplPlanner planner : {OmplPlanner::kPrmStar, OmplPlanner::kRrtConnect}) {
    OmplPeerOptions options;
    options.planner = planner;
    options.time_budget_s = 0.3;
    auto r = PlanWithOmpl(map(), Request({2, 3, 2.5}, {8, 3, 2.5}), options);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    ASSERT_TRUE(r->ok()) << r->message;
    EXPECT_GE(MinClearanceAlong(map(), *r), 0.5);
    EXPECT_LE(r->shortened_cost.length_m, r->path_cost.length_m + 1e-6);
  }
  OmplPeerOptions bad;
  bad.time_budget_s = 0;
  EXPECT_EQ(PlanWithOmpl(map(), Request({2, 3, 2.5}, {8, 3, 2.5}), bad).status().code(),
            StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace mav::planning
