// The fresh-planner legs: OMPL's PRMstar or RRTConnect per leg (the peers of mav-eval and the
// planner's no-roadmap mode), optionally followed by OMPL's PathSimplifier.

#include <ompl/base/ProblemDefinition.h>
#include <ompl/base/objectives/PathLengthOptimizationObjective.h>
#include <ompl/geometric/PathGeometric.h>
#include <ompl/geometric/PathSimplifier.h>
#include <ompl/geometric/planners/prm/PRMstar.h>
#include <ompl/geometric/planners/rrt/RRTConnect.h>

#include <sstream>

#include "mav/common/time.h"
#include "ompl_space.h"
#include "pipeline.h"

namespace mav::planning {

namespace ob = ompl::base;
namespace og = ompl::geometric;

bool OmplPeerOptions::IsValid(std::string* why) const {
  std::ostringstream msg;
  if (!(time_budget_s > 0 && time_budget_s <= 600)) {
    msg << "time_budget_s: must be in (0, 600] s, got " << time_budget_s;
  } else if (!(clearance_margin_m >= 0 && clearance_margin_m <= 1)) {
    msg << "clearance_margin_m: must be in [0, 1] m, got " << clearance_margin_m;
  }
  if (msg.str().empty()) return true;
  if (why) *why = msg.str();
  return false;
}

namespace internal {
namespace {

std::vector<Eigen::Vector3d> ToPoints(const og::PathGeometric& path) {
  std::vector<Eigen::Vector3d> out;
  out.reserve(path.getStateCount());
  for (size_t i = 0; i < path.getStateCount(); ++i) out.push_back(ToVector(path.getState(i)));
  return out;
}

}  // namespace

Result<LegOutcome> FreshOmplLeg(const ClearanceMap& map, const OmplPeerOptions& options,
                                bool simplify, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                const Termination& stop) {
  LegOutcome out;
  const int64_t t0 = MonotonicNowNs();
  // The margin where both ends have it, else the radius (the ends must be valid states).
  const double preferred = map.robot_radius() + options.clearance_margin_m;
  const double required =
      std::min(ConnectionClearance(map, a, preferred), ConnectionClearance(map, b, preferred));
  const ob::SpaceInformationPtr si =
      MakeSpaceInformation(map, required, ClearanceMap::kDefaultToleranceM, options.seed);
  auto problem = std::make_shared<ob::ProblemDefinition>(si);
  ob::ScopedState<> start(si->getStateSpace()), goal(si->getStateSpace());
  FromVector(a, start.get());
  FromVector(b, goal.get());
  problem->setStartAndGoalStates(start, goal);
  problem->setOptimizationObjective(std::make_shared<ob::PathLengthOptimizationObjective>(si));
  ob::PlannerPtr planner;
  if (options.planner == OmplPlanner::kPrmStar) {
    planner = std::make_shared<og::PRMstar>(si);
  } else {
    planner = std::make_shared<og::RRTConnect>(si);
  }
  planner->setProblemDefinition(problem);
  planner->setup();
  const int64_t deadline_ns = t0 + SecondsToNs(options.time_budget_s);
  const ob::PlannerStatus status = planner->solve(ob::PlannerTerminationCondition(
      [&] { return MonotonicNowNs() >= deadline_ns || stop.ShouldStop(); }));
  MAV_RETURN_IF_ERROR(stop.Check("plan"));
  out.search_ms = MsSince(t0);
  if (status != ob::PlannerStatus::EXACT_SOLUTION || !problem->hasExactSolution()) {
    out.status = PlanStatus::kTimeout;
    std::ostringstream msg;
    msg << (options.planner == OmplPlanner::kPrmStar ? "PRM*" : "RRTConnect")
        << " found no path in " << options.time_budget_s << " s (" << status.asString() << ")";
    out.message = msg.str();
    return out;
  }
  auto* path = problem->getSolutionPath()->as<og::PathGeometric>();
  out.raw = ToPoints(*path);
  if (simplify) {
    const int64_t t1 = MonotonicNowNs();
    og::PathGeometric simplified(*path);
    og::PathSimplifier(si).simplifyMax(simplified);
    out.shortened = ToPoints(simplified);
    out.shorten_ms = MsSince(t1);
  }
  out.status = PlanStatus::kSuccess;
  return out;
}

}  // namespace internal

Result<PlanResult> PlanWithOmpl(const ClearanceMap& map, const PlanRequest& request,
                                const OmplPeerOptions& options, const Termination& stop) {
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument(why);
  return internal::RunPipeline(
      map, request,
      [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
        return internal::FreshOmplLeg(map, options, /*simplify=*/true, a, b, stop);
      },
      map.robot_radius() + options.clearance_margin_m, stop);
}

}  // namespace mav::planning
