// Statistics over seeds on the contest's real map (as OMPL's planner tests do): success rate and
// zero clearance violations, with the near-optimal reference deciding which queries have a
// solution. Reads maps/power_plant.bt (maps/README.md).

#include <gtest/gtest.h>

#include <cstdio>
#include <random>

#include "mav/common/file.h"
#include "mav/planning/planner.h"
#include "mav/planning/planning_map.h"
#include "mav/planning/reference_path.h"
#include "tests/common/build_paths.h"
#include "tests/common/sanitizers.h"

namespace mav::planning {
namespace {

const std::string kMapPath = mav::testing::SourceDir() + "/maps/power_plant.bt";

// The exact clearance every 1 cm of the trajectory.
double MinClearance(const ClearanceMap& map, const PlanResult& r) {
  double worst = 1e9;
  for (double t = 0; t <= r.duration_s;) {
    worst = std::min(worst, map.Clearance(r.trajectory.Evaluate(t).position));
    const double speed = r.trajectory.EvaluateDerivative(t, 1).norm();
    t += 0.01 / (speed + 0.5);  // < 1 cm per step (the speed changes < 0.5 m/s per step)
  }
  return worst;
}

// The map and the default roadmap, built once for both tests.
class PowerPlantTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!PathExists(kMapPath)) return;
    auto map = PlanningMap::LoadFile(kMapPath, MapOptions{});
    ASSERT_TRUE(map.ok()) << map.status().ToString();
    map_ = new std::shared_ptr<const PlanningMap>(*map);
    auto roadmap = Roadmap::Build(**map, RoadmapOptions{});
    ASSERT_TRUE(roadmap.ok()) << roadmap.status().ToString();
    roadmap_ = new std::shared_ptr<const Roadmap>(*roadmap);
  }
  static void TearDownTestSuite() {
    delete map_;
    delete roadmap_;
  }
  void SetUp() override {
    ASSERT_TRUE(PathExists(kMapPath)) << kMapPath << " is missing from the source tree";
    ASSERT_NE(map_, nullptr);
    ASSERT_NE(roadmap_, nullptr);
  }
  static std::shared_ptr<const PlanningMap>* map_;
  static std::shared_ptr<const Roadmap>* roadmap_;
};
std::shared_ptr<const PlanningMap>* PowerPlantTest::map_ = nullptr;
std::shared_ptr<const Roadmap>* PowerPlantTest::roadmap_ = nullptr;

TEST_F(PowerPlantTest, SuccessOverFiftySeedsWithoutClearanceViolations) {
  const PlanningMap& m = **map_;
  const Roadmap* roadmap = roadmap_->get();
  // Under ASan the first 10 seeds (113 s of the sanitizer pass for all 50, docs/quality.md "CI
  // time"): the same code paths, both kinds of query; the Release run keeps the statistics.
  const int seeds = test_support::kUnderAddressSanitizer ? 10 : 50;

  int solvable = 0, succeeded = 0, violations = 0, blocked = 0;
  for (uint32_t seed = 1; seed <= static_cast<uint32_t>(seeds); ++seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    const Box& b = m.bounds();
    // One query per seed: two valid states 20-40 m apart that the reference connects.
    for (int attempt = 0; attempt < 200; ++attempt) {
      Eigen::Vector3d start = b.min + b.size().cwiseProduct(Eigen::Vector3d(u(rng), u(rng), 0));
      Eigen::Vector3d goal = b.min + b.size().cwiseProduct(Eigen::Vector3d(u(rng), u(rng), 0));
      start.z() = 1 + 24 * u(rng);
      goal.z() = 1 + 24 * u(rng);
      const double d = (goal - start).norm();
      if (d < 20 || d > 40 || !m.IsValid(start) || !m.IsValid(goal)) continue;
      ReferenceOptions ro;
      ro.max_expansions = 400000;
      auto reference = ShortestReferencePath(m, start, goal, ro);
      if (!reference.ok() || !reference->found) continue;
      ++solvable;
      blocked += reference->path.size() > 2;
      PlanRequest request;
      request.start = start;
      request.goal = goal;
      auto result = PlanPath(m, roadmap, request);
      ASSERT_TRUE(result.ok()) << result.status().ToString();
      if (result->ok()) {
        ++succeeded;
        const double clearance = MinClearance(m, *result);
        violations += clearance < m.robot_radius();
        EXPECT_GE(clearance, m.robot_radius()) << "seed " << seed;
        EXPECT_LE(result->trajectory_length_m, 1.1 * reference->length_m) << "seed " << seed;
      } else {
        ADD_FAILURE() << "seed " << seed << ": " << PlanStatusName(result->status) << ": "
                      << result->message;
      }
      break;
    }
  }
  std::printf(
      "power_plant: %d solvable queries (%d with the straight line blocked), %d succeeded, "
      "%d with clearance violations\n",
      solvable, blocked, succeeded, violations);
  EXPECT_EQ(solvable, seeds);
  // Both kinds of query: straight line blocked and free.
  EXPECT_GE(blocked, 3 * seeds / 10);
  EXPECT_LE(blocked, seeds - 1);
  EXPECT_GE(succeeded, 0.99 * solvable);
  EXPECT_EQ(violations, 0);
}

TEST_F(PowerPlantTest, ContestLegsOnTheDefaultRoadmap) {
  const PlanningMap& m = **map_;
  const std::vector<Eigen::Vector3d> legs = {{2, -27, 15}, {20, -15, 15}, {25, 0, 5}, {0, 0, 1}};
  for (size_t i = 0; i + 1 < legs.size(); ++i) {
    PlanRequest request;
    request.start = legs[i];
    request.goal = legs[i + 1];
    auto result = PlanPath(m, roadmap_->get(), request);
    ASSERT_TRUE(result.ok());
    ASSERT_TRUE(result->ok()) << "leg " << i << ": " << result->message;
    EXPECT_GE(MinClearance(m, *result), 0.5) << "leg " << i;
    // The paper flew its legs at 4.2 m/s on average; ours are planned faster.
    EXPECT_GT(result->mean_speed_mps, 4.2) << "leg " << i;
  }
}

}  // namespace
}  // namespace mav::planning
