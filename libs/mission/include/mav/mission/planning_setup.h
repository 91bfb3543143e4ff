#pragma once
// How a mission plans, shared by its two drivers so that both plan on the same map with the same
// roadmap: the planning map's and the roadmap's options for the mission's world, and the two
// map queries the mission logic asks its driver (MissionDriver::CheckPoint, LandingSpot).
// The in-process driver (lockstep_driver.h) builds its map from these options; mavctl mission
// run uploads the simulator's ground-truth occupancy to the planning service with the same
// options and asks the same queries of its copy of that map.

#include <cstdint>
#include <optional>
#include <string>

#include <Eigen/Core>

#include "mav/common/status.h"
#include "mav/dataset/mission_file.h"
#include "mav/dataset/occupancy_grid.h"
#include "mav/planning/planner.h"
#include "mav/planning/planning_map.h"
#include "mav/planning/roadmap.h"
#include "mav/planning/trajectory.h"
#include "mav/sim/presets.h"

namespace mav::mission {

// 0 / unset = the world's default (rooms / plant).
struct PlanningOverrides {
  double map_resolution_m = 0;      // 0.05 / 0.25 m
  double robot_radius_m = 0;        // 0.4 / 0.8 m
  uint64_t roadmap_milestones = 0;  // 20 000 / 60 000
  // rooms: 1 m/s, 1 m/s^2, jerk 3 m/s^3; plant: 3 m/s, 2 m/s^2, 5 m/s^3.
  std::optional<planning::SpeedLimits> limits;
  // The field named ("robot_radius_m: must be 0 (the world's default) or in (0.1, 3]").
  bool IsValid(std::string* why) const;
};

// Limits for a planned top speed (mav-eval mission / mavctl mission run --max-speed):
// acceleration and lateral acceleration min(2, v), jerk 5.
planning::SpeedLimits SpeedLimitsForMaxSpeed(double max_speed_mps);

struct MissionPlanning {
  double map_resolution_m = 0;
  planning::MapOptions map;
  planning::RoadmapOptions roadmap;
  planning::SpeedLimits limits;
};

// The options for `mission` in `preset`'s world: the planning volume is the preset's flight
// volume down to the mission's ground; unknown space is an obstacle unless `unknown_is_free`
// (an online map); the roadmap's seed is `seed`.
MissionPlanning MissionPlanningFor(const dataset::MissionSpec& mission, const sim::Preset& preset,
                                   const PlanningOverrides& overrides, uint64_t seed,
                                   bool unknown_is_free);

// An online map's prior: the voxels below the take-off's ground (ground_z) are occupied.
void AddGroundPrior(double ground_z, dataset::OccupancyGrid* grid);

// MissionDriver::CheckPoint on `map`: InvalidArgument saying why the vehicle may not be at `p`
// (outside the planning volume, or closer to an obstacle than the robot radius; `map_name` is
// quoted).
Status CheckPointInMap(const planning::PlanningMap& map, const Eigen::Vector3d& p,
                       const std::string& map_name);

// MissionDriver::LandingSpot on `map`: the nearest point at the height of `above` (rings 0.1 m
// apart, out to 4 m) whose column down to the ground at `ground_z` keeps the robot radius plus
// 0.1 m, reachable in a straight line; NotFound when none.
Result<Eigen::Vector3d> LandingSpotInMap(const planning::PlanningMap& map,
                                         const Eigen::Vector3d& above, double ground_z);

}  // namespace mav::mission
