#pragma once
// mavctl mission run's MissionDriver (mav/mission/driver.h): the mission flown through the
// running services, the same mission logic (mav/mission/mission.h) as mav-eval mission's
// in-process driver, on the same vehicle, map and roadmap:
//
//   mav-simulator    LoadFlightTask(mission): the vehicle in the mission's world, lock-stepped;
//                    for pose source vo its forward stereo camera on mav/sensors/stereo
//   mav-localization Configure: the sparse VO on that stream, started at the vehicle's true
//                    initial pose; its poses on mav/localization/pose ("body" = the rig)
//   mav-control      Configure: the estimator and controller mav-eval flies
//                    (mission::MissionAutopilotOptions); the VO source lock-stepped with the
//                    modelled latency, so the flight does not depend on the VO's wall time
//   mav-planning     UploadMap(the simulator's ground-truth occupancy) + BuildRoadmap with the
//                    in-process options (mission::MissionPlanningFor); every leg is a PlanPath
//   mav-mapping      (online map only) StartSession on the flight's stereo and the VO's poses
//                    (DDS); every map_rebuild_s of the vehicle's clock while keyframes come,
//                    BuildMap (the sparse mesh, surfaces only) -> GetOccupancy -> the ground
//                    prior -> UploadMap (unknown space free) + BuildRoadmap: the mission re-checks
//                    its leg on each new map version, as in process
//
// Advance(dt) runs the simulator to t + dt (StartFlight run_until_s, then waits for PAUSED) and
// reads the vehicle back (Control.GetState, the simulator's ground truth, the localization's
// state). CheckPoint and LandingSpot are asked of the driver's copy of the map it uploaded (the
// planner's map, bit for bit). A restarted localization (UNCONFIGURED) asks to be seeded;
// SeedLocalization configures it at the estimate's pose.
//
// Not thread-safe (the mission calls it from one thread).

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "mav/common/stats.h"
#include "mav/common/status.h"
#include "mav/dataset/mission_file.h"
#include "mav/localization/odometry.h"
#include "mav/mission/driver.h"
#include "mav/mission/planning_setup.h"
#include "mav/mission/record.h"
#include "mav/mission/report.h"
#include "mav/mission/vehicle.h"

namespace mav::planning {
class PlanningMap;
}

namespace mav::mavctl {

struct ServiceAddresses {
  std::string simulator = "127.0.0.1:50051";
  std::string localization = "127.0.0.1:50052";
  std::string mapping = "127.0.0.1:50053";
  std::string planning = "127.0.0.1:50054";
  std::string control = "127.0.0.1:50055";
};

struct ServiceMissionOptions {
  mission::VehicleOptions vehicle;  // seed, pose source, camera pitch, controller, VO latency
  localization::Method vo_method = localization::Method::kSparseSubpixel;
  mission::PlanningOverrides planning;
  double rpc_timeout_s = 10;       // each quick RPC
  double setup_timeout_s = 300;    // the map and roadmap
  double lockstep_timeout_s = 30;  // the simulator's wait for a command (then the mission aborts)
  double lockstep_wait_s = 2;      // mav-control's wait for a frame's pose
  double record_rate_hz = 20;
  // After a frame the localization lost, it restarts at the estimate at the end of the tick
  // (mission::LockstepOptions::reseed_after_loss; false: from its own last pose).
  bool reseed_after_loss = true;
  // The online map (mav-mapping), as the in-process kOnline map: rebuilt every map_rebuild_s
  // while keyframes come, points up to map_max_depth_m deep seen by map_min_visibility
  // keyframes.
  bool online_map = false;
  double map_rebuild_s = 2.0;
  double map_max_depth_m = 3.5;
  int map_min_visibility = 2;
};

// What the services report at the end (their own counters).
struct ServiceFigures {
  int64_t collisions = 0;
  std::vector<std::string> collision_descriptions;
  uint64_t frames_published = 0;        // simulator: stereo pairs rendered and published
  RuntimeStats render_ms;               // simulator
  uint64_t vo_frames = 0;               // localization: processed
  uint64_t vo_lost = 0;                 // localization: LOST
  RuntimeStats vo_ms;                   // localization: per frame
  uint64_t poses_merged = 0;            // control
  uint64_t poses_gated = 0;             // control: rejected by the estimator's gate
  uint64_t lockstep_frames_missed = 0;  // control: frames the localization did not answer
  mission::MissionFigures::PoseLatency pose_latency;  // control: vision poses, capture -> in
  uint64_t plans = 0, plans_failed = 0;
  // The online map: keyframes mapped, rebuilds (each a new planner map), their wall time
  // (BuildMap + download + upload; the new map's roadmap is built by the next plan and counted
  // in plan_ms), the roadmaps built, and the final map against the world's occupancy
  // over the volume the camera could observe from its true poses along the flight (the
  // in-process driver takes its keyframes' poses: the services do not report them).
  int64_t keyframes = 0;
  uint64_t map_rebuilds = 0, map_errors = 0;
  uint64_t roadmap_builds = 0;  // mav-planning's BuildRoadmap calls
  RuntimeStats map_build_ms;
  std::optional<mission::MapQuality> map_quality;
  RuntimeStats plan_ms;     // the PlanPath round trip
  RuntimeStats advance_ms;  // wall time of one mission tick through the services
  double setup_s = 0;       // loading the flight, the map, the roadmap, configuring
  std::string map_description;
};

class ServiceDriver final : public mission::MissionDriver {
 public:
  // Loads `mission` (its text `mission_yaml`, named `source`) into the simulator, configures the
  // other services and builds the planner's map and roadmap. An error names the service, its
  // address and the RPC. Progress lines go to `progress` (may be null).
  static Result<std::unique_ptr<ServiceDriver>> Create(
      const dataset::MissionSpec& mission, const std::string& mission_yaml,
      const ServiceMissionOptions& options, const ServiceAddresses& addresses,
      const std::function<void(const std::string&)>& progress = {});
  ~ServiceDriver() override;

  Result<mission::VehicleView> Advance(double dt_s) override;
  Status Arm() override;
  Status Disarm() override;
  Status GoTo(const Eigen::Vector3d& position, double yaw_rad,
              const control::GoToLimits& limits) override;
  Status Hold(const Eigen::Vector3d& position, double yaw_rad) override;
  Status Follow(const geometry::PolynomialTrajectory& trajectory) override;
  Result<mission::LegPlan> Plan(const Eigen::Vector3d& start, const Eigen::Vector3d& goal,
                                double yaw_rad) override;
  Status CheckPoint(const Eigen::Vector3d& p) override;
  Result<Eigen::Vector3d> LandingSpot(const Eigen::Vector3d& above) override;
  Status SeedLocalization(const geometry::SE3& T_world_body) override;

  const std::vector<mission::FlightSample>& record() const;
  // Asks the services for their counters (the simulator's collisions, the VO's frames, ...).
  Result<ServiceFigures> Figures();
  const planning::PlanningMap& planning_map() const;
  // The planner's map as uploaded (OctoMap .bt bytes).
  const std::string& map_bt() const;
  // Pauses the flight if it runs (the end of a mission, or an error), best effort.
  void Stop();

 private:
  struct Impl;
  explicit ServiceDriver(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace mav::mavctl
