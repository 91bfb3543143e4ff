#pragma once
// A planning query, start -> waypoints... -> goal, the paper's Section 3 end to end (Holzmann
// et al. 2015):
// 1. connection: each point is checked (inside the planning volume, clearance >= robot radius)
//    and joined to its nearest roadmap milestones by every valid straight segment (and to the
//    next point directly when that segment is valid);
// 2. search: our own A* over the immutable roadmap with the cost of path.h (heuristic
//    w_length |p - goal| + w_altitude |z - z_goal|, admissible), one leg per pair of points;
// 3. shortening with the bounded cost increase (path.h), leg by leg (waypoints are kept);
// 4. speed plan, quintic spline and its clearance check (trajectory.h) over the whole path,
//    stopping at every waypoint.
// Without a roadmap (or with use_roadmap false), step 2 is a fresh OMPL PRM* run per leg for
// time_budget_s (Karaman & Frazzoli 2011); then steps 3 and 4 as above.
//
// PlanPath is a const function of its arguments: no locks, no shared mutable state, so any number
// of queries run at once on the same map and roadmap snapshot.
//
// Outcomes are values, as OMPL's PlannerStatus: a PlanResult with a status and a message. Errors
// of the call itself are Status values: INVALID_ARGUMENT (a request field, named), FAILED_
// PRECONDITION (a roadmap of another map), DEADLINE_EXCEEDED / CANCELLED (the caller's `stop`).

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mav/common/status.h"
#include "mav/common/termination.h"
#include "mav/geometry/polynomial_trajectory.h"
#include "mav/planning/clearance_map.h"
#include "mav/planning/path.h"
#include "mav/planning/roadmap.h"
#include "mav/planning/trajectory.h"

namespace mav::planning {

enum class PlanStatus {
  kSuccess,
  kNoPath,            // the roadmap (or the fresh PRM*) does not connect the points
  kStartInvalid,      // start outside the volume or closer than the robot radius to an obstacle
  kGoalInvalid,       // goal (or a waypoint: see invalid_waypoint and the message) invalid
  kTimeout,           // without a roadmap: the time budget passed without a path
  kTrajectoryFailed,  // a path, but no spline that keeps the clearance
};

// "SUCCESS", "NO_PATH", ... (the proto's names without the prefix).
const char* PlanStatusName(PlanStatus status);

struct PlanRequest {
  Eigen::Vector3d start = Eigen::Vector3d::Zero();  // world frame, m
  Eigen::Vector3d goal = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> waypoints;  // visited in order between start and goal
  CostWeights weights;
  // Shortening keeps a shortcut while the cost stays within (1 + this) x the raw path's.
  // Validated [0, 10].
  double max_cost_increase = 0.1;
  SpeedLimits limits;
  // Search the roadmap (when one is given); false: a fresh PRM* per leg.
  bool use_roadmap = true;
  // Without a roadmap: PRM*'s time per leg, s. Validated (0, 600].
  double time_budget_s = 1.0;
  // Seed of the fresh PRM* runs.
  uint64_t seed = 0;
  geometry::YawPolicy yaw_policy = geometry::YawPolicy::kConstant;
  double start_yaw_rad = 0;
  // Roadmap milestones each point is tried against (nearest first; more when none is
  // visible). 30: PRM*'s own k for 100 k milestones is 3.62 ln(1e5) = 42. Validated [1, 1000].
  int connection_candidates = 30;

  bool IsValid(std::string* why) const;
};

struct PlanTimings {
  double connect_ms = 0;  // point checks + connections to the roadmap
  double search_ms = 0;   // A* (or the fresh PRM* runs)
  double shorten_ms = 0;
  double speed_plan_ms = 0;  // corners + speed profile
  double spline_ms = 0;      // spline fits
  double check_ms = 0;       // spline checks
  double total_ms = 0;
  // The proto's split: planning = connection + search + shortening, trajectory = the rest.
  double planning_ms() const { return connect_ms + search_ms + shorten_ms; }
  double trajectory_ms() const { return speed_plan_ms + spline_ms + check_ms; }
};

struct PlanResult {
  PlanStatus status = PlanStatus::kNoPath;
  std::string message;                          // why, when status != kSuccess
  int invalid_waypoint = -1;                    // index into request.waypoints when one is invalid
  std::vector<Eigen::Vector3d> path;            // raw: start, roadmap milestones, ..., goal
  std::vector<Eigen::Vector3d> shortened_path;  // incl. start, waypoints and goal
  PathCost path_cost;
  PathCost shortened_cost;
  geometry::PolynomialTrajectory trajectory;  // empty unless kSuccess
  PlanTimings timings;
  double duration_s = 0;
  double max_speed_mps = 0;
  double mean_speed_mps = 0;
  double trajectory_length_m = 0;
  double trajectory_min_clearance_m = 0;  // over the 1 cm check samples
  int trajectory_refits = 0;

  bool ok() const { return status == PlanStatus::kSuccess; }
};

// Plans `request` on `map` with `roadmap` (may be null: then as use_roadmap = false). The
// roadmap must belong to the map (Roadmap::CheckBelongsTo).
Result<PlanResult> PlanPath(const ClearanceMap& map, const Roadmap* roadmap,
                            const PlanRequest& request, const Termination& stop = {});

// The peers of mav-eval: a fresh OMPL planner per leg, OMPL's own path simplifier
// (PathSimplifier::simplifyMax) instead of our shortening, then the same speed plan and spline.
enum class OmplPlanner {
  kPrmStar,     // PRMstar, runs the whole budget (Karaman & Frazzoli 2011)
  kRrtConnect,  // RRTConnect, stops at the first path (Kuffner & LaValle, ICRA 2000)
};

struct OmplPeerOptions {
  OmplPlanner planner = OmplPlanner::kPrmStar;
  // Per leg, s: the paper's 0.75 s. Validated (0, 600].
  double time_budget_s = 0.75;
  // Clearance kept beyond the robot radius by the planner and the simplifier, m (as the
  // roadmap's clearance_margin_m, so the spline gets the same room). Validated [0, 1].
  double clearance_margin_m = 0.05;
  uint64_t seed = 1;

  bool IsValid(std::string* why) const;
};

Result<PlanResult> PlanWithOmpl(const ClearanceMap& map, const PlanRequest& request,
                                const OmplPeerOptions& options, const Termination& stop = {});

}  // namespace mav::planning
