#include "mav/eval/leg_planner.h"

#include <cstdio>
#include <filesystem>
#include <sstream>

#include "mav/common/file.h"
#include "mav/planning/planner.h"
#include "mav/planning/planning_map.h"
#include "mav/planning/roadmap.h"

namespace mav::eval {
namespace {

// The roadmap at `path` when it holds one of `map`, else a new one saved there. Progress lines
// go to `log`.
Result<std::shared_ptr<const planning::Roadmap>> LoadOrBuildRoadmap(
    const planning::PlanningMap& map, const std::string& path, std::ostringstream* log) {
  if (PathExists(path)) {
    Result<std::shared_ptr<const planning::Roadmap>> loaded = planning::Roadmap::Load(path, map);
    if (loaded.ok()) {
      *log << "leg planner: roadmap " << path << " loaded in " << (*loaded)->info().load_ms
           << " ms\n";
      return loaded;
    }
    *log << "leg planner: " << loaded.status().message() << "; building a new roadmap\n";
  }
  MAV_ASSIGN_OR_RETURN(std::shared_ptr<const planning::Roadmap> roadmap,
                       planning::Roadmap::Build(map, planning::RoadmapOptions()));
  *log << "leg planner: roadmap of " << roadmap->info().milestones << " milestones built in "
       << roadmap->info().build_s << " s";
  if (Status s = roadmap->Save(path); s.ok()) {
    *log << ", saved to " << path << "\n";
  } else {
    *log << " (not saved: " << s.message() << ")\n";
  }
  return roadmap;
}

}  // namespace

Result<RoadmapLegPlanner> MakeRoadmapLegPlanner(const std::string& map_path,
                                                const std::string& roadmap_path,
                                                const planning::SpeedLimits& limits) {
  std::string why;
  if (!limits.IsValid(&why)) return Status::InvalidArgument("--leg-limits: " + why);
  MAV_ASSIGN_OR_RETURN(std::shared_ptr<const planning::PlanningMap> map,
                       planning::PlanningMap::LoadFile(map_path, planning::MapOptions()));
  std::string path = roadmap_path;
  if (path.empty()) {
    char name[64];
    std::snprintf(name, sizeof(name), "mav-eval-roadmap-%016llx.mavprm",
                  static_cast<unsigned long long>(map->fingerprint()));
    path = (std::filesystem::temp_directory_path() / name).string();
  }
  std::ostringstream log;
  MAV_ASSIGN_OR_RETURN(std::shared_ptr<const planning::Roadmap> roadmap,
                       LoadOrBuildRoadmap(*map, path, &log));
  RoadmapLegPlanner out;
  std::istringstream lines(log.str());
  for (std::string line; std::getline(lines, line);) out.log.push_back(line);
  out.legs = std::make_shared<std::vector<PlannedLeg>>();
  out.planner = [map, roadmap, limits, legs = out.legs](
                    const Eigen::Vector3d& start, const Eigen::Vector3d& goal, double yaw_rad,
                    const sim::CollisionWorld*) -> Result<geometry::PolynomialTrajectory> {
    planning::PlanRequest request;
    request.start = start;
    request.goal = goal;
    request.start_yaw_rad = yaw_rad;
    request.limits = limits;
    MAV_ASSIGN_OR_RETURN(planning::PlanResult plan,
                         planning::PlanPath(*map, roadmap.get(), request));
    if (!plan.ok()) {
      return Status::FailedPrecondition(std::string(planning::PlanStatusName(plan.status)) + ": " +
                                        plan.message);
    }
    legs->push_back({plan.trajectory_length_m, plan.timings.total_ms, plan.duration_s,
                     plan.mean_speed_mps, plan.max_speed_mps, plan.trajectory_min_clearance_m});
    return plan.trajectory;
  };
  return out;
}

}  // namespace mav::eval
