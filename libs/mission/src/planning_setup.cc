#include "mav/mission/planning_setup.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "mav/mission/vehicle.h"

namespace mav::mission {

bool PlanningOverrides::IsValid(std::string* why) const {
  auto fail = [&](const std::string& message) {
    if (why) *why = message;
    return false;
  };
  if (!(map_resolution_m == 0 || (map_resolution_m >= 0.02 && map_resolution_m <= 1))) {
    return fail("map_resolution_m: must be 0 (the world's default) or in [0.02, 1]");
  }
  if (!(robot_radius_m == 0 || (robot_radius_m > 0.1 && robot_radius_m <= 3))) {
    return fail("robot_radius_m: must be 0 (the world's default) or in (0.1, 3]");
  }
  if (roadmap_milestones > 1'000'000) return fail("roadmap_milestones: at most 1000000");
  std::string limits_why;
  if (limits && !limits->IsValid(&limits_why)) return fail("limits." + limits_why);
  return true;
}

planning::SpeedLimits SpeedLimitsForMaxSpeed(double max_speed_mps) {
  planning::SpeedLimits limits;
  limits.max_speed_mps = max_speed_mps;
  limits.max_acceleration_mps2 = std::min(2.0, max_speed_mps);
  limits.max_lateral_acceleration_mps2 = std::min(2.0, max_speed_mps);
  limits.max_jerk_mps3 = 5.0;
  return limits;
}

MissionPlanning MissionPlanningFor(const dataset::MissionSpec& mission, const sim::Preset& preset,
                                   const PlanningOverrides& overrides, uint64_t seed,
                                   bool unknown_is_free) {
  const bool room = IsRoomWorld(mission.world);
  MissionPlanning p;
  p.map_resolution_m =
      overrides.map_resolution_m > 0 ? overrides.map_resolution_m : (room ? 0.05 : 0.25);
  p.map.robot_radius_m =
      overrides.robot_radius_m > 0 ? overrides.robot_radius_m : (room ? 0.4 : 0.8);
  // Unknown space: an obstacle in the exact map (there is none inside the world); free in an
  // online map, where the forward camera has not seen most of the volume yet: legs are planned
  // through it and re-checked, and re-planned, as the map fills in (mission.h).
  p.map.unknown_space =
      unknown_is_free ? planning::UnknownSpace::kFree : planning::UnknownSpace::kObstacle;
  // The preset's flight volume down to the ground (landings descend through it).
  Eigen::Vector3d volume_min = preset.flight_bounds.min();
  volume_min.z() = std::min(volume_min.z(), mission.start.z());
  p.map.planning_bounds = planning::Box{volume_min, preset.flight_bounds.max()};
  p.roadmap.max_milestones =
      overrides.roadmap_milestones > 0 ? overrides.roadmap_milestones : (room ? 20'000 : 60'000);
  p.roadmap.seed = seed;
  p.roadmap.validity_resolution_m = std::min(p.map_resolution_m, 0.05);
  if (overrides.limits) {
    p.limits = *overrides.limits;
  } else {
    p.limits.max_speed_mps = room ? 1.0 : 3.0;
    p.limits.max_acceleration_mps2 = room ? 1.0 : 2.0;
    p.limits.max_lateral_acceleration_mps2 = room ? 1.0 : 2.0;
    p.limits.max_jerk_mps3 = room ? 3.0 : 5.0;
  }
  return p;
}

void AddGroundPrior(double ground_z, dataset::OccupancyGrid* grid) {
  for (int k = 0; k < grid->size().z(); ++k) {
    if (grid->CenterOf({0, 0, k}).z() >= ground_z) break;
    for (int j = 0; j < grid->size().y(); ++j) {
      for (int i = 0; i < grid->size().x(); ++i) {
        (*grid)[grid->Linear(i, j, k)] = dataset::VoxelState::kOccupied;
      }
    }
  }
}

Status CheckPointInMap(const planning::PlanningMap& map, const Eigen::Vector3d& p,
                       const std::string& map_name) {
  char why[400];
  if (!map.bounds().Contains(p)) {
    const planning::Box& b = map.bounds();
    std::snprintf(why, sizeof(why),
                  "outside the planning volume [%.1f, %.1f] x [%.1f, %.1f] x [%.1f, %.1f] m",
                  b.min.x(), b.max.x(), b.min.y(), b.max.y(), b.min.z(), b.max.z());
    return Status::InvalidArgument(why);
  }
  if (!map.HasClearance(p, map.robot_radius())) {
    std::snprintf(why, sizeof(why),
                  "%.2f m from an obstacle, closer than the vehicle's radius %.2f m (%s)",
                  map.Clearance(p), map.robot_radius(), map_name.c_str());
    return Status::InvalidArgument(why);
  }
  return Status::Ok();
}

Result<Eigen::Vector3d> LandingSpotInMap(const planning::PlanningMap& map,
                                         const Eigen::Vector3d& above, double ground_z) {
  // The robot radius plus room for the estimate's drift on the IMU alone.
  const double radius = map.robot_radius() + 0.1;
  const double lowest = ground_z + radius + 0.05;
  auto column_free = [&](const Eigen::Vector3d& top) {
    for (double z = top.z(); z > lowest; z -= 0.05) {
      if (!map.HasClearance({top.x(), top.y(), z}, radius)) return false;
    }
    return map.HasClearance({top.x(), top.y(), lowest}, radius);
  };
  // Rings of candidates 0.1 m apart, nearest first; the straight move there must be free too.
  constexpr double kStepM = 0.1, kMaxM = 4.0;
  for (double r = 0; r <= kMaxM; r += kStepM) {
    const int n = r == 0 ? 1 : static_cast<int>(std::ceil(2 * M_PI * r / kStepM));
    for (int i = 0; i < n; ++i) {
      const double a = 2 * M_PI * i / n;
      const Eigen::Vector3d p = above + Eigen::Vector3d(r * std::cos(a), r * std::sin(a), 0);
      if (!column_free(p)) continue;
      // The move there keeps the robot radius (from 0.1 m on: the vehicle may be holding
      // closer than that to something).
      bool path_free = true;
      for (double u = 0.1; u <= r && path_free; u += 0.05) {
        path_free = map.HasClearance(above + (p - above) * (u / r), map.robot_radius());
      }
      if (path_free) return p;
    }
  }
  return Status::NotFound("no free landing column within 4 m of the vehicle");
}

}  // namespace mav::mission
