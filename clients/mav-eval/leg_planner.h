#pragma once
// The leg planner of mav-eval control's planned-legs tasks (t4_3): libs/planning behind the
// eval::LegPlanner hook (mav/eval/flight_mission.h), the same code mav-planning serves.
//   * the task's OctoMap as a planning::PlanningMap (robot radius 0.5 m, unknown = obstacle);
//   * a PRM* roadmap (planning::Roadmap, default options: 100 000 milestones, seed 1) loaded from
//     `roadmap_path` when it holds one of this map, else built and saved there;
//   * each leg planning::PlanPath from the vehicle's reference to the goal with `limits` (by
//     default the Firefly's SpeedLimits, docs/planning.md), at rest at both ends, yaw constant
//     at the goal's yaw.
// The collision world the mission passes is not used: the planner sees the map, as the vehicle
// of the contest did.

#include <ostream>
#include <string>

#include "mav/common/status.h"
#include "mav/eval/flight_mission.h"
#include "mav/planning/trajectory.h"

namespace mav::eval_cli {

// `roadmap_path` empty: a file in the temporary directory named by the map's fingerprint.
// Progress lines go to `log`. The library's errors (map, roadmap) are returned; a leg that
// fails to plan returns its PlanResult's status and message as FAILED_PRECONDITION.
Result<eval::LegPlanner> MakeRoadmapLegPlanner(const std::string& map_path,
                                               const std::string& roadmap_path,
                                               const planning::SpeedLimits& limits,
                                               std::ostream& log);

}  // namespace mav::eval_cli
