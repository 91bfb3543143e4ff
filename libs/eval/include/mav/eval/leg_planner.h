#pragma once
// The leg planner of the control evaluation's planned-legs tasks (t4_3): libs/planning behind
// the LegPlanner hook (mav/eval/flight_mission.h), the same code mav-planning serves.
//   * the task's OctoMap as a planning::PlanningMap (robot radius 0.5 m, unknown = obstacle);
//   * a PRM* roadmap (planning::Roadmap, default options: 100 000 milestones, seed 1) loaded from
//     `roadmap_path` when it holds one of this map, else built and saved there;
//   * each leg planning::PlanPath from the vehicle's reference to the goal with `limits` (by
//     default the Firefly's SpeedLimits, docs/planning.md), at rest at both ends, yaw constant
//     at the goal's yaw.
// The collision world the mission passes is not used: the planner sees the map, as the vehicle
// of the contest did.

#include <memory>
#include <string>
#include <vector>

#include "mav/common/status.h"
#include "mav/eval/flight_mission.h"
#include "mav/planning/trajectory.h"

namespace mav::eval {

// One leg as planned.
struct PlannedLeg {
  double length_m = 0;  // the trajectory's
  double planning_ms = 0;
  double duration_s = 0;
  double mean_speed_mps = 0;
  double peak_speed_mps = 0;
  double min_clearance_m = 0;
};

struct RoadmapLegPlanner {
  LegPlanner planner;
  // Every leg the planner planned, in order (appended by `planner`; the caller may clear it).
  std::shared_ptr<std::vector<PlannedLeg>> legs;
  // What setting up did: the roadmap loaded, or built (and saved or not), one line each.
  std::vector<std::string> log;
};

// `roadmap_path` empty: a file in the temporary directory named by the map's fingerprint.
// InvalidArgument "--leg-limits: ..." for invalid limits; the library's errors (map, roadmap)
// are returned; a leg that fails to plan returns its PlanResult's status and message as
// FAILED_PRECONDITION.
Result<RoadmapLegPlanner> MakeRoadmapLegPlanner(const std::string& map_path,
                                                const std::string& roadmap_path,
                                                const planning::SpeedLimits& limits);

}  // namespace mav::eval
