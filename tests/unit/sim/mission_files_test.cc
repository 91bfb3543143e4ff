// The mission files shipped in missions/ (mav/dataset/mission_file.h) against the exact worlds of
// their presets: they parse, start on free ground, keep every goal in the preset's flight volume
// with its clearance, fly far enough, and (the surveys) need the planner (a straight leg between
// consecutive waypoints comes closer to an obstacle than the vehicle's radius).

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <ostream>
#include <string>
#include <vector>

#include "mav/dataset/mission_file.h"
#include "mav/sim/presets.h"
#include "mav/sim/world.h"
#include "tests/common/build_paths.h"

namespace mav::sim {
namespace {

constexpr double kVehicleRadiusM = 0.35;  // the Firefly's radius with rotors (docs/control.md)

struct Shipped {
  std::string file;
  size_t min_goals;
  double min_path_m;
  bool needs_planner = true;  // some leg between goals is blocked (the hover mission has none)
};

// The closest approach of the segment a-b to the world's obstacles (sampled every 2 cm).
double MinClearanceAlong(const World& world, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const int steps = std::max(1, static_cast<int>((b - a).norm() / 0.02));
  double closest = 1e9;
  for (int i = 0; i <= steps; ++i) {
    closest = std::min(closest, world.SignedDistance(a + (b - a) * (double(i) / steps)));
  }
  return closest;
}

void PrintTo(const Shipped& shipped, std::ostream* os) { *os << shipped.file; }

// Every check of the file comment against one preset's world.
void CheckAgainstWorld(const Shipped& shipped, const dataset::MissionSpec& mission,
                       const std::string& world_name) {
  const Result<Preset> preset = MakePreset(world_name);
  ASSERT_TRUE(preset.ok()) << preset.status().ToString();
  const World& world = *preset->world;

  // On the ground, with a free column up to the take-off height.
  const Eigen::Vector3d takeoff = mission.start + Eigen::Vector3d(0, 0, mission.altitude_m);
  EXPECT_NEAR(mission.start.z(), 0.0, 1e-9) << "the start is on the ground (z = 0)";
  const Eigen::Vector3d lift_off = mission.start + Eigen::Vector3d(0, 0, kVehicleRadiusM + 0.05);
  EXPECT_GE(MinClearanceAlong(world, lift_off, takeoff), kVehicleRadiusM) << "the take-off column";

  // The waypoints as flown: take-off, the goals, and the landing point below the last goal.
  std::vector<Eigen::Vector3d> points = {mission.start, takeoff};
  for (const dataset::MissionGoal& g : mission.goals) {
    EXPECT_TRUE(preset->flight_bounds.contains(g.position))
        << shipped.file << ":" << g.line << ": outside the preset's flight volume";
    EXPECT_GE(world.SignedDistance(g.position), preset->min_clearance)
        << shipped.file << ":" << g.line << ": closer to an obstacle than the preset's clearance";
    points.push_back(g.position);
  }
  if (mission.land) {
    const Eigen::Vector3d ground(points.back().x(), points.back().y(), 0.0);
    EXPECT_GE(MinClearanceAlong(world, points.back(),
                                ground + Eigen::Vector3d(0, 0, kVehicleRadiusM + 0.05)),
              kVehicleRadiusM)
        << "the landing column below the last goal";
    points.push_back(ground);
  }
  double path_m = 0.0;
  int blocked_legs = 0;
  for (size_t i = 1; i < points.size(); ++i) {
    path_m += (points[i] - points[i - 1]).norm();
    // The take-off, first and landing legs end on the ground: only the legs between goals count.
    if (i >= 3 && i < 2 + mission.goals.size()) {
      const double clearance = MinClearanceAlong(world, points[i - 1], points[i]);
      blocked_legs += clearance < kVehicleRadiusM;
      std::printf("%s in %s: leg %zu -> %zu: %.2f m, straight-line clearance %.2f m\n",
                  shipped.file.c_str(), world_name.c_str(), i - 2, i - 1,
                  (points[i] - points[i - 1]).norm(), clearance);
    }
  }
  std::printf("%s in %s: %zu goals, %.1f m of straight legs, %d legs blocked\n",
              shipped.file.c_str(), world_name.c_str(), mission.goals.size(), path_m, blocked_legs);
  EXPECT_GE(mission.goals.size(), shipped.min_goals);
  EXPECT_GE(path_m, shipped.min_path_m);
  if (shipped.needs_planner) {
    EXPECT_GE(blocked_legs, 1) << "no leg needs a plan around an obstacle";
  }
}

class MissionFilesTest : public ::testing::TestWithParam<Shipped> {};

TEST_P(MissionFilesTest, FlyInFreeSpaceFarEnoughAndNeedThePlanner) {
  const Shipped& shipped = GetParam();
  const Result<dataset::MissionSpec> mission =
      dataset::ReadMissionFile(mav::testing::SourceDir() + "/missions/" + shipped.file);
  ASSERT_TRUE(mission.ok()) << mission.status().ToString();
  // A room mission flies in every room preset (one layout, harder images).
  std::vector<std::string> worlds = {mission->world};
  if (mission->world.rfind("room-", 0) == 0) worlds = {"room-easy", "room-medium", "room-hard"};
  for (const std::string& name : worlds) {
    SCOPED_TRACE(name);
    CheckAgainstWorld(shipped, *mission, name);
  }
}

INSTANTIATE_TEST_SUITE_P(Shipped, MissionFilesTest,
                         ::testing::Values(Shipped{"room_survey.yaml", 4, 30.0},
                                           Shipped{"plant_inspection.yaml", 3, 100.0},
                                           Shipped{"room_hover.yaml", 1, 0.0, false}));

}  // namespace
}  // namespace mav::sim
