#pragma once
// The steps every planning query shares (internal to libs/planning): checking the points, one
// leg planner per pair of points, the shortening, the trajectory, the costs and timings. The
// roadmap search (planner.cc) and the fresh OMPL planners (ompl_planners.cc) plug in as leg
// planners, so ours and the peers run the very same speed plan and spline.

#include <functional>
#include <vector>

#include <Eigen/Core>

#include "mav/planning/planner.h"

namespace mav::planning::internal {

struct LegOutcome {
  PlanStatus status = PlanStatus::kNoPath;  // kSuccess, kNoPath or kTimeout
  std::string message;
  std::vector<Eigen::Vector3d> raw;        // from a to b
  std::vector<Eigen::Vector3d> shortened;  // empty: the pipeline shortens `raw` itself
  double connect_ms = 0, search_ms = 0, shorten_ms = 0;
};

// Plans one leg from a to b (both already valid). Errors only for the caller's stop.
using LegPlanner =
    std::function<Result<LegOutcome>(const Eigen::Vector3d& a, const Eigen::Vector3d& b)>;

// `path_clearance_m`: what the shortening keeps (robot radius + the planner's margin).
Result<PlanResult> RunPipeline(const ClearanceMap& map, const PlanRequest& request,
                               const LegPlanner& plan_leg, double path_clearance_m,
                               const Termination& stop);

// A fresh OMPL planner (options.planner) from a to b for options.time_budget_s; with `simplify`,
// OMPL's simplifier's result goes to LegOutcome::shortened (else the pipeline shortens).
Result<LegOutcome> FreshOmplLeg(const ClearanceMap& map, const OmplPeerOptions& options,
                                bool simplify, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                const Termination& stop);

// Clearance a connection from p keeps: `preferred` when p has it, else the robot radius.
double ConnectionClearance(const ClearanceMap& map, const Eigen::Vector3d& p, double preferred);

}  // namespace mav::planning::internal
