#pragma once
// The in-process MissionDriver (driver.h): the whole loop in one thread, lock-stepped and
// deterministic for a seed (mav-eval mission, tests and seed sweeps).
//
//   FlightSimulation (vehicle, IMU at imu_rate_hz, collisions with the preset's exact world)
//     -> StereoRigRenderer: the stereo pair at camera_rate_hz from the flown state, with the
//        preset's exposure, blur and noise (vision in the loop)
//     -> RigOdometry (sparse VO by default), started at the true initial pose
//     -> the Autopilot's estimator (pose source vo | contest | truth), the controller
//     -> rotor speeds -> FlightSimulation
//   Plan() runs libs/planning (PRM* roadmap + PlanPath) on the map (see MapSource).
//
// Time: the vehicle's clock starts at 0. Frame k is captured at k / camera_rate_hz, rendered
// as soon as the state over its shutter is known, and its VO pose reaches the estimator
// vo_latency_s after the capture (a fixed modelled latency keeps runs deterministic; the wall
// time the VO took is measured and reported beside it).
//
// The camera rig: the preset's EuRoC rig (body = the VI sensor's IMU frame, x up, z forward)
// mounted on the vehicle (body x forward, z up) looking forward, T_vehicle_rig.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "mav/common/stats.h"
#include "mav/common/status.h"
#include "mav/common/termination.h"
#include "mav/control/autopilot.h"
#include "mav/dataset/mission_file.h"
#include "mav/eval/contest_score.h"
#include "mav/geometry/se3.h"
#include "mav/localization/odometry.h"
#include "mav/mission/driver.h"
#include "mav/mission/mission.h"
#include "mav/mission/planning_setup.h"
#include "mav/mission/record.h"
#include "mav/mission/report.h"
#include "mav/mission/vehicle.h"
#include "mav/planning/trajectory.h"

namespace mav::sim {
class FlightSimulation;
class World;
}  // namespace mav::sim
namespace mav::planning {
class PlanningMap;
}

namespace mav::mission {

// The localization is down over [start_s, start_s + duration_s) of the vehicle's clock (its
// frames are not processed). With `restart` it comes back as a restarted process would: without
// a reference, until the mission seeds it (MissionDriver::SeedLocalization).
struct LocalizationOutage {
  double start_s = 0;
  double duration_s = 0;
  bool restart = true;
};

// Where Plan() gets its obstacles.
enum class MapSource {
  kGroundTruth,  // the preset world's exact occupancy at map_resolution_m
  // Built during the flight from the VO's keyframes and poses (libs/mapping's sparse mesh),
  // rebuilt every map_rebuild_s while keyframes come; unknown space counts as free for the
  // planner (the mission re-checks its legs as the map fills in); the ground below the take-off
  // is known from the start.
  kOnline,
};
const char* MapSourceName(MapSource source);  // "truth", "online"
std::optional<MapSource> ParseMapSource(std::string_view name);

struct LockstepOptions {
  // The vehicle, its camera and flight software (the simulator service's mission flight takes
  // the same).
  VehicleOptions vehicle;
  localization::Method vo_method = localization::Method::kSparseSubpixel;
  // After a lost frame the VO restarts at the estimator's pose (false: it goes on from its own
  // last pose, RigOdometry's default, which drops the motion over the lost frames).
  bool reseed_after_loss = true;
  // Planning: the world's defaults unless overridden (planning_setup.h).
  MapSource map_source = MapSource::kGroundTruth;
  PlanningOverrides planning;
  double map_rebuild_s = 2.0;
  // The online map's stereo points reach this far (their depth noise grows as Z^2: ~0.1 m at
  // 3.5 m on the rig, ~0.5 m at 6 m, which would put phantom surfaces in the room's middle).
  double map_max_depth_m = 3.5;
  // Points meshed only when this many keyframes saw them (single-view mismatches make phantom
  // surfaces in a map of a few keyframes).
  int map_min_visibility = 2;
  std::vector<LocalizationOutage> outages;
  double record_rate_hz = 20;
  bool IsValid(std::string* why) const;
};

struct LockstepStats {
  uint64_t frames = 0;          // stereo pairs rendered
  uint64_t vo_tracked = 0;      // VO frames with a pose (OK, degraded or initialising)
  uint64_t vo_lost = 0;         // VO frames lost
  uint64_t vo_skipped = 0;      // frames while the localization was down or unseeded
  uint64_t poses_fed = 0;       // poses given to the estimator
  uint64_t poses_rejected = 0;  // by its gate
  uint64_t plans = 0;
  uint64_t plans_failed = 0;
  RuntimeStats render_ms;     // wall time per stereo pair
  RuntimeStats vo_ms;         // wall time per VO frame
  RuntimeStats plan_ms;       // wall time per Plan()
  RuntimeStats map_build_ms;  // wall time per online map rebuild (mesh, planning map)
  int64_t keyframes = 0;      // inserted into the online map
  uint64_t map_rebuilds = 0;
  // Roadmaps built: one for the first map, then one per plan on a map that changed since the
  // last (a rebuilt online map's roadmap waits for the next plan; plan_ms includes it).
  uint64_t roadmap_builds = 0;
  uint64_t map_errors = 0;  // keyframes or rebuilds that failed (the map stays as it was)
  double path_m = 0;        // ground-truth path length flown
  double setup_s = 0;       // map + roadmap (wall)
  int64_t collisions = 0;
  std::vector<std::string> collision_descriptions;
  std::string map_description;
};

class LockstepDriver final : public MissionDriver {
 public:
  // Builds the world of mission.world, the vehicle at mission.start, the renderer, the VO and
  // the planning map and roadmap. InvalidArgument naming the field (options, an unknown
  // world); progress lines go to `progress` (may be null).
  static Result<std::unique_ptr<LockstepDriver>> Create(const dataset::MissionSpec& mission,
                                                        const LockstepOptions& options,
                                                        const ProgressCallback& progress = {});
  ~LockstepDriver() override;

  Result<VehicleView> Advance(double dt_s) override;
  Status Arm() override;
  Status Disarm() override;
  Status GoTo(const Eigen::Vector3d& position, double yaw_rad,
              const control::GoToLimits& limits) override;
  Status Hold(const Eigen::Vector3d& position, double yaw_rad) override;
  Status Follow(const geometry::PolynomialTrajectory& trajectory) override;
  Result<LegPlan> Plan(const Eigen::Vector3d& start, const Eigen::Vector3d& goal,
                       double yaw_rad) override;
  Status CheckPoint(const Eigen::Vector3d& p) override;
  Result<Eigen::Vector3d> LandingSpot(const Eigen::Vector3d& above) override;
  Status SeedLocalization(const geometry::SE3& T_world_body) override;

  const std::vector<FlightSample>& record() const;
  LockstepStats stats() const;
  const control::Autopilot& autopilot() const;
  const sim::World& world() const;
  const planning::PlanningMap& planning_map() const;
  // The map the planner uses now (the online map with its ground prior, or the exact one) as an
  // OctoMap file.
  Status WriteMap(const std::string& path) const;
  // That map against the world's exact occupancy.
  Result<MapQuality> EvaluateMap() const;

 private:
  struct Impl;
  explicit LockstepDriver(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace mav::mission
