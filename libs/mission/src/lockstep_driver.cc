#include "mav/mission/lockstep_driver.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <sstream>

#include <opencv2/core.hpp>

#include "mav/camera/stereo.h"
#include "mav/common/text.h"
#include "mav/common/time.h"
#include "mav/dataset/occupancy_io.h"
#include "mav/eval/flight_mission.h"
#include "mav/localization/rig_odometry.h"
#include "mav/mapping/collision_eval.h"
#include "mav/mapping/observability.h"
#include "mav/mapping/pipeline.h"
#include "mav/planning/planner.h"
#include "mav/planning/planning_map.h"
#include "mav/planning/roadmap.h"
#include "mav/sim/collision_world.h"
#include "mav/sim/flight_simulation.h"
#include "mav/sim/occupancy.h"
#include "mav/sim/presets.h"
#include "mav/sim/stereo_rig.h"
#include "mav/sim/world.h"

namespace mav::mission {

const char* PoseSourceName(PoseSource source) {
  switch (source) {
    case PoseSource::kContest:
      return "contest";
    case PoseSource::kVo:
      return "vo";
    case PoseSource::kTruth:
      return "truth";
  }
  return "?";
}

std::optional<PoseSource> ParsePoseSource(std::string_view name) {
  for (PoseSource s : {PoseSource::kContest, PoseSource::kVo, PoseSource::kTruth}) {
    if (name == PoseSourceName(s)) return s;
  }
  return std::nullopt;
}

const char* MapSourceName(MapSource source) {
  return source == MapSource::kOnline ? "online" : "truth";
}

std::optional<MapSource> ParseMapSource(std::string_view name) {
  for (MapSource s : {MapSource::kGroundTruth, MapSource::kOnline}) {
    if (name == MapSourceName(s)) return s;
  }
  return std::nullopt;
}

bool LockstepOptions::IsValid(std::string* why) const {
  std::ostringstream msg;
  auto check = [&](bool ok, const char* what) {
    if (msg.str().empty() && !ok) msg << what;
  };
  check(vo_latency_s >= 0 && vo_latency_s <= 0.5, "vo_latency_s: must be in [0, 0.5]");
  check(vo_position_sigma_m > 0 && vo_orientation_sigma_rad > 0,
        "vo_position_sigma_m / vo_orientation_sigma_rad: must be positive");
  check(imu_rate_hz >= 50 && imu_rate_hz <= 1000, "imu_rate_hz: must be in [50, 1000]");
  check(camera_rate_hz > 0 && camera_rate_hz <= imu_rate_hz,
        "camera_rate_hz: must be in (0, imu_rate_hz]");
  check(camera_pitch_rad >= 0 && camera_pitch_rad <= 1.2,
        "camera_pitch_rad: must be in [0, 1.2] (0 = level, looking forward)");
  check(pose_gate_m >= 0 && pose_gate_rad >= 0, "pose_gate_m / pose_gate_rad: must be >= 0");
  check(map_resolution_m == 0 || (map_resolution_m >= 0.02 && map_resolution_m <= 1),
        "map_resolution_m: must be 0 (the world's default) or in [0.02, 1]");
  check(robot_radius_m == 0 || (robot_radius_m > 0.1 && robot_radius_m <= 3),
        "robot_radius_m: must be 0 (the world's default) or in (0.1, 3]");
  check(roadmap_milestones <= 1'000'000, "roadmap_milestones: at most 1000000");
  check(map_source == MapSource::kGroundTruth || pose_source == PoseSource::kVo,
        "map_source: the online map is built from the VO's keyframes (pose_source vo)");
  check(map_rebuild_s > 0 && map_rebuild_s <= 60, "map_rebuild_s: must be in (0, 60]");
  check(map_max_depth_m >= 1 && map_max_depth_m <= 50, "map_max_depth_m: must be in [1, 50]");
  check(record_rate_hz > 0 && record_rate_hz <= imu_rate_hz,
        "record_rate_hz: must be in (0, imu_rate_hz]");
  std::string limits_why;
  if (msg.str().empty() && limits && !limits->IsValid(&limits_why)) {
    msg << "limits." << limits_why;
  }
  for (size_t i = 0; i < outages.size() && msg.str().empty(); ++i) {
    if (!(outages[i].start_s >= 0 && outages[i].duration_s > 0 &&
          std::isfinite(outages[i].start_s + outages[i].duration_s))) {
      msg << "outages[" << i << "]: need start_s >= 0 and duration_s > 0";
    }
  }
  if (msg.str().empty()) return true;
  if (why) *why = msg.str();
  return false;
}

double EstimateRmsError(const std::vector<FlightSample>& record) {
  double sum = 0;
  size_t n = 0;
  for (const FlightSample& s : record) {
    if (!s.armed) continue;
    sum += (s.p_est - s.p_true).squaredNorm();
    ++n;
  }
  return n ? std::sqrt(sum / static_cast<double>(n)) : std::nan("");
}

eval::WindowRms ScoreHover(const std::vector<FlightSample>& record, const GoalReport& goal,
                           double settle_s) {
  if (!goal.visited) return {};
  std::vector<eval::FlightTraceSample> trace;
  trace.reserve(record.size());
  for (const FlightSample& s : record) {
    trace.push_back({s.t_s, s.p_true, s.v_true, s.omega_true, s.p_est});
  }
  return eval::RmsOverWindow(trace, goal.hover_start_s + settle_s, goal.reached_at_s, goal.goal);
}

geometry::SE3 LockstepDriver::VehicleRigMount(double pitch_down_rad) {
  // Rig body axes in the vehicle's: x (up) = vehicle z, z (forward) = vehicle x, y = -vehicle y;
  // then pitched down about the vehicle's y axis.
  Eigen::Matrix3d R;
  R.col(0) = Eigen::Vector3d::UnitZ();
  R.col(1) = -Eigen::Vector3d::UnitY();
  R.col(2) = Eigen::Vector3d::UnitX();
  const Eigen::Matrix3d pitch(Eigen::AngleAxisd(pitch_down_rad, Eigen::Vector3d::UnitY()));
  return geometry::SE3(Eigen::Quaterniond(pitch * R), Eigen::Vector3d(0.12, 0.0, 0.02));
}

namespace {

using Clock = std::chrono::steady_clock;
double MsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

bool IsRoom(const std::string& world) { return world.rfind("room-", 0) == 0; }

struct TruthAt {
  int64_t t_ns = 0;
  geometry::SE3 T_world_body;
};

struct PendingPose {
  int64_t arrival_ns = 0;
  control::PoseMeasurement pose;
};

// The vehicle, its IMU and (for `contest` / `truth`) its pose sensor for a mission; a `vo`
// mission's sensor never delivers (the VO is the pose source).
dataset::FlightTask MissionFlightTask(const dataset::MissionSpec& mission,
                                      const LockstepOptions& options) {
  dataset::FlightTask task;
  task.name = "mission " + mission.source;
  task.kind = dataset::FlightTaskKind::kWaypoints;
  task.duration_s = 7200;
  task.spawn_position = mission.start + Eigen::Vector3d(0, 0, 0.08);
  task.ground_z_m = mission.start.z();
  task.takeoff_position = mission.start + Eigen::Vector3d(0, 0, mission.altitude_m);
  task.goals = {dataset::FlightGoal{0.0, task.takeoff_position, 0.0}};
  task.imu.rate_hz = options.imu_rate_hz;
  task.vehicle_radius_m = 0.35;
  dataset::FlightPoseSensorSpec sensor;  // the contest's by default
  if (options.pose_source == PoseSource::kTruth) {
    sensor.rate_hz = options.camera_rate_hz;
    sensor.delay_s = 0;
    sensor.position_sigma_m = 0;
    sensor.orientation_sigma_rad = 0;
    sensor.mount_xyz_m.setZero();
    sensor.mount_rpy_rad.setZero();
  } else if (options.pose_source == PoseSource::kVo) {
    sensor.active_from_s = task.duration_s - 1;  // never within a mission
  }
  task.pose_sensors = {sensor};
  return task;
}

// The flight software for the task, its estimator fed by the mission's pose source.
control::AutopilotOptions MissionAutopilotOptions(const dataset::FlightTask& task,
                                                  const LockstepOptions& options,
                                                  const geometry::SE3& T_vehicle_rig) {
  control::AutopilotOptions ap = eval::AutopilotOptionsForTask(task, options.controller);
  if (options.pose_source == PoseSource::kVo) {
    control::PoseSourceOptions vo;
    vo.rate_hz = options.camera_rate_hz;
    vo.position_sigma_m = options.vo_position_sigma_m;
    vo.orientation_sigma_rad = options.vo_orientation_sigma_rad;
    vo.T_body_sensor = T_vehicle_rig;
    ap.estimator.sources = {vo};
    ap.estimator.buffer_s = std::max(1.0, 2 * options.vo_latency_s + 0.2);
  }
  ap.estimator.pose_gate_m = options.pose_gate_m;
  ap.estimator.pose_gate_rad = options.pose_gate_rad;
  // The mission's health logic holds at 1 s and lands at 3 s (at a free column, on the IMU);
  // the autopilot's own failsafe (a level descent where it is) is the last resort behind it,
  // for a mission that stopped commanding.
  ap.pose_timeout_s = 20.0;
  return ap;
}

planning::SpeedLimits WorldSpeedLimits(bool room) {
  planning::SpeedLimits limits;
  limits.max_speed_mps = room ? 1.0 : 3.0;
  limits.max_acceleration_mps2 = room ? 1.0 : 2.0;
  limits.max_lateral_acceleration_mps2 = room ? 1.0 : 2.0;
  limits.max_jerk_mps3 = room ? 3.0 : 5.0;
  return limits;
}

}  // namespace

struct LockstepDriver::Impl {
  dataset::MissionSpec mission;
  LockstepOptions options;
  sim::Preset preset;
  std::shared_ptr<const sim::World> world;
  std::unique_ptr<sim::FlightSimulation> sim;
  std::unique_ptr<control::Autopilot> ap;
  std::unique_ptr<sim::StereoRigRenderer> rig;
  std::unique_ptr<localization::RigOdometry> vo;
  geometry::SE3 T_vehicle_rig;
  Eigen::Matrix3d R_rig_vehicle;
  std::shared_ptr<const planning::PlanningMap> map;
  dataset::OccupancyGrid truth_grid;     // the world's exact occupancy (also the map's geometry)
  dataset::OccupancyGrid planning_grid;  // what `map` was built from
  // The online map (MapSource::kOnline).
  std::unique_ptr<mapping::MappingPipeline> mapper;
  std::vector<geometry::SE3> keyframe_truth;  // true T_world_rect0 of every keyframe
  int64_t keyframes_at_build = 0;
  int64_t next_build_ns = 0;
  uint64_t map_version = 0;
  std::shared_ptr<const planning::Roadmap> roadmap;
  planning::SpeedLimits limits;

  const sim::FlightStep* out = nullptr;
  std::deque<TruthAt> truth;  // the last ~0.2 s, for the shutter's poses
  std::deque<PendingPose> pending;
  int64_t frame_period_ns = 0;
  int64_t next_frame = 0;  // index of the next frame to capture
  bool vo_down = false;
  bool vo_restarts = false;  // the current outage ends with a restarted localization
  bool vo_needs_seed = false;
  std::string vo_state = "starting";
  int64_t next_record_ns = 0;
  int64_t record_period_ns = 0;
  std::vector<FlightSample> record;
  Eigen::Vector3d last_p = Eigen::Vector3d::Zero();
  LockstepStats stats;
  RuntimeWindow render_ms{100000}, vo_ms{100000}, plan_ms{10000}, map_build_ms{10000};

  // The planning map (the world's exact occupancy, or the online map's prior), its roadmap and
  // the speed limits.
  Status BuildPlanning(const ProgressCallback& progress);
  // Replaces the planning map and its roadmap by `grid`'s.
  Status LoadPlanningMap(const dataset::OccupancyGrid& grid, const std::string& what,
                         const ProgressCallback& progress);
  // The voxels below the take-off's ground are occupied.
  void AddGroundPrior(dataset::OccupancyGrid* grid) const;
  // The online map from the keyframes so far (the sparse mesh of libs/mapping).
  Status RebuildOnlineMap();
  // Offers a tracked frame (the VO's rig pose; the true one for the map's evaluation) to the
  // online map's keyframe selection.
  Status MapFrame(const cv::Mat& left, const cv::Mat& right, const geometry::SE3& T_world_rig,
                  const geometry::SE3& T_world_rig_true);
  void StepOnce();
  void Capture(int64_t frame);
  bool InOutage(int64_t t_ns, bool* restart) const;
  geometry::SE3 TruthBetween(int64_t t_ns) const;
};

LockstepDriver::LockstepDriver(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
LockstepDriver::~LockstepDriver() = default;

Status LockstepDriver::Impl::BuildPlanning(const ProgressCallback& progress) {
  const bool room = IsRoom(mission.world);
  const double resolution =
      options.map_resolution_m > 0 ? options.map_resolution_m : (room ? 0.05 : 0.25);
  limits = options.limits.value_or(WorldSpeedLimits(room));
  if (progress) progress("ground-truth map", 0.0);
  truth_grid = sim::ComputeOccupancy(*world, resolution);
  if (options.map_source == MapSource::kGroundTruth) {
    return LoadPlanningMap(truth_grid, "ground-truth occupancy", progress);
  }
  // The online map starts as the ground below the take-off (the one thing known before the
  // flight) and everything else unknown.
  dataset::OccupancyGrid prior(truth_grid.geometry());
  AddGroundPrior(&prior);
  return LoadPlanningMap(prior, "online map (no keyframe yet)", progress);
}

void LockstepDriver::Impl::AddGroundPrior(dataset::OccupancyGrid* grid) const {
  const double ground = mission.start.z();
  for (int k = 0; k < grid->size().z(); ++k) {
    if (grid->CenterOf({0, 0, k}).z() >= ground) break;
    for (int j = 0; j < grid->size().y(); ++j) {
      for (int i = 0; i < grid->size().x(); ++i) {
        (*grid)[grid->Linear(i, j, k)] = dataset::VoxelState::kOccupied;
      }
    }
  }
}

Status LockstepDriver::Impl::LoadPlanningMap(const dataset::OccupancyGrid& grid,
                                             const std::string& what,
                                             const ProgressCallback& progress) {
  const bool room = IsRoom(mission.world);
  MAV_ASSIGN_OR_RETURN(std::string bt, dataset::EncodeOctomapBt(grid));
  planning::MapOptions map_options;
  map_options.robot_radius_m =
      options.robot_radius_m > 0 ? options.robot_radius_m : (room ? 0.4 : 0.8);
  // Unknown space: an obstacle in the exact map (there is none inside the world); free in the
  // online map, where the forward camera has not seen most of the volume yet: legs are planned
  // through it and re-checked, and re-planned, as the map fills in (mission.h).
  map_options.unknown_space = options.map_source == MapSource::kOnline
                                  ? planning::UnknownSpace::kFree
                                  : planning::UnknownSpace::kObstacle;
  // The preset's flight volume down to the ground (landings descend through it).
  Eigen::Vector3d volume_min = preset.flight_bounds.min();
  volume_min.z() = std::min(volume_min.z(), mission.start.z());
  map_options.planning_bounds = planning::Box{volume_min, preset.flight_bounds.max()};
  MAV_ASSIGN_OR_RETURN(map, planning::PlanningMap::LoadBytes(bt, mission.world + " " + what,
                                                             map_options, {}, progress));
  planning::RoadmapOptions roadmap_options;
  roadmap_options.max_milestones =
      options.roadmap_milestones > 0 ? options.roadmap_milestones : (room ? 20'000 : 60'000);
  roadmap_options.seed = options.seed;
  roadmap_options.validity_resolution_m = std::min(grid.resolution(), 0.05);
  MAV_ASSIGN_OR_RETURN(roadmap, planning::Roadmap::Build(*map, roadmap_options, {}, progress));
  planning_grid = grid;
  std::ostringstream description;
  description << what << " of " << mission.world << " at " << grid.resolution()
              << " m, robot radius " << map_options.robot_radius_m << " m, "
              << roadmap->info().milestones << " roadmap milestones";
  stats.map_description = description.str();
  return Status::Ok();
}

Status LockstepDriver::Impl::RebuildOnlineMap() {
  const auto start = Clock::now();
  // A map of a partly seen room: the observed surfaces occupied, the space the lines of sight
  // crossed free, the rest (the graph cut's inside of unexplored space too) unknown.
  mapping::BuildOptions build = mapping::BuildOptions::For(mapping::MapPreference::kSafety);
  build.mesh_to_grid->occupy_inside_cells = false;
  build.mesh_to_grid->occupy_surface_voxels = true;
  build.min_visibility = options.map_min_visibility;
  MAV_ASSIGN_OR_RETURN(mapping::MethodMap built, mapper->Build(mapping::MappingMethod::kSparseMesh,
                                                               truth_grid.geometry(), build));
  AddGroundPrior(&built.grid);
  MAV_RETURN_IF_ERROR(LoadPlanningMap(
      built.grid, "online map (" + std::to_string(built.keyframes) + " keyframes)", {}));
  keyframes_at_build = built.keyframes;
  ++map_version;
  map_build_ms.Add(MsSince(start));
  return Status::Ok();
}

Result<std::unique_ptr<LockstepDriver>> LockstepDriver::Create(const dataset::MissionSpec& mission,
                                                               const LockstepOptions& options,
                                                               const ProgressCallback& progress) {
  const auto setup_start = Clock::now();
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument(why);
  if (!mission.IsValid(&why)) return Status::InvalidArgument(mission.source + ": " + why);
  auto impl = std::make_unique<Impl>();
  Impl& s = *impl;
  s.mission = mission;
  s.options = options;
  Result<sim::Preset> preset = sim::MakePreset(mission.world);
  if (!preset.ok()) {
    return Status::InvalidArgument(mission.source + ": world: " + preset.status().message());
  }
  s.preset = *std::move(preset);
  s.preset.world->BuildTextures(options.seed);
  s.world = s.preset.world;

  // The vehicle and its flight software.
  const dataset::FlightTask task = MissionFlightTask(mission, options);
  MAV_ASSIGN_OR_RETURN(
      sim::FlightSimulation flight,
      sim::FlightSimulation::Create(
          task, options.seed, {},
          std::shared_ptr<const sim::CollisionWorld>(
              sim::MakePrimitiveCollisionWorldAboveGround(*s.world, mission.start.z()))));
  s.sim = std::make_unique<sim::FlightSimulation>(std::move(flight));
  s.out = &s.sim->Initial();
  s.last_p = s.out->truth.p_world;
  s.T_vehicle_rig = VehicleRigMount(options.camera_pitch_rad);
  s.R_rig_vehicle = s.T_vehicle_rig.Rotation().toRotationMatrix().transpose();
  MAV_ASSIGN_OR_RETURN(
      control::Autopilot autopilot,
      control::Autopilot::Create(MissionAutopilotOptions(task, options, s.T_vehicle_rig)));
  s.ap = std::make_unique<control::Autopilot>(std::move(autopilot));

  // Vision in the loop.
  if (options.pose_source == PoseSource::kVo) {
    const camera::StereoCalibration calibration = camera::EurocStereoCalibration();
    s.rig = std::make_unique<sim::StereoRigRenderer>(s.world, calibration, s.preset.effects,
                                                     options.seed, s.preset.min_clearance);
    localization::RigOdometryOptions vo;
    vo.method = options.vo_method;
    vo.calibration = calibration;
    const sim::MulticopterState& x0 = s.out->truth;
    vo.T_world_body0 = geometry::SE3(x0.q_world_body, x0.p_world) * s.T_vehicle_rig;
    MAV_ASSIGN_OR_RETURN(s.vo, localization::RigOdometry::Create(vo));
  }
  if (options.map_source == MapSource::kOnline) {
    mapping::MappingPipelineOptions mapping_options;
    mapping_options.run_octomap = false;
    mapping_options.sparse.max_depth_m = options.map_max_depth_m;
    MAV_ASSIGN_OR_RETURN(mapping::MappingPipeline mapper,
                         mapping::MappingPipeline::Create(s.vo->rig(), mapping_options));
    s.mapper = std::make_unique<mapping::MappingPipeline>(std::move(mapper));
  }
  s.frame_period_ns = PeriodNs(options.camera_rate_hz);
  s.record_period_ns = PeriodNs(options.record_rate_hz);

  MAV_RETURN_IF_ERROR(s.BuildPlanning(progress));
  s.stats.setup_s = MsSince(setup_start) / 1000.0;
  return std::unique_ptr<LockstepDriver>(new LockstepDriver(std::move(impl)));
}

bool LockstepDriver::Impl::InOutage(int64_t t_ns, bool* restart) const {
  const double t_s = NsToSeconds(t_ns);
  for (const LocalizationOutage& o : options.outages) {
    if (t_s >= o.start_s && t_s < o.start_s + o.duration_s) {
      *restart = o.restart;
      return true;
    }
  }
  return false;
}

geometry::SE3 LockstepDriver::Impl::TruthBetween(int64_t t_ns) const {
  // The two recorded states around t_ns (the deque is in time order), interpolated.
  const TruthAt* a = &truth.front();
  const TruthAt* b = &truth.back();
  for (size_t i = 1; i < truth.size(); ++i) {
    if (truth[i].t_ns >= t_ns) {
      a = &truth[i - 1];
      b = &truth[i];
      break;
    }
  }
  if (t_ns <= a->t_ns || b->t_ns == a->t_ns) return a->T_world_body;
  if (t_ns >= b->t_ns) return b->T_world_body;
  const double u = static_cast<double>(t_ns - a->t_ns) / static_cast<double>(b->t_ns - a->t_ns);
  const Eigen::Vector3d p =
      (1 - u) * a->T_world_body.Translation() + u * b->T_world_body.Translation();
  const Eigen::Quaterniond q = a->T_world_body.Rotation().slerp(u, b->T_world_body.Rotation());
  return geometry::SE3(q, p);
}

void LockstepDriver::Impl::Capture(int64_t frame) {
  const int64_t t_ns = frame * frame_period_ns;
  bool restart = false;
  if (InOutage(t_ns, &restart)) {
    if (!vo_down) {
      vo_down = true;
      vo_restarts = restart;
      vo_state = "down";
    }
    ++stats.vo_skipped;
    return;
  }
  if (vo_down) {
    vo_down = false;
    if (vo_restarts) {
      vo->Reset();
      vo_needs_seed = true;
      vo_state = "unseeded";
    }
  }
  if (vo_needs_seed) {
    ++stats.vo_skipped;
    return;
  }
  cv::Mat left, right;
  const auto render_start = Clock::now();
  rig->Render(
      frame, NsToSeconds(t_ns),
      [&](double dt_s) { return TruthBetween(t_ns + SecondsToNs(dt_s)) * T_vehicle_rig; }, &left,
      &right);
  render_ms.Add(MsSince(render_start));
  ++stats.frames;
  const auto vo_start = Clock::now();
  Result<localization::RigPose> pose = vo->Process(t_ns, left, right, /*rectified=*/false);
  vo_ms.Add(MsSince(vo_start));
  if (!pose.ok() || pose->state == localization::ReportedState::kLost) {
    ++stats.vo_lost;
    vo_state = "lost (" + (pose.ok() ? pose->lost_reason : pose.status().message()) + ")";
    // The VO starts its next track where the estimator (IMU-propagated over the lost frames)
    // puts the vehicle, not at its own last pose: the motion while it was lost is not lost.
    if (options.reseed_after_loss && ap->estimator().initialized()) {
      const control::EstimatorState& e = ap->estimator().state();
      vo->Reset(geometry::SE3(e.q_world_body, e.p_world) * T_vehicle_rig);
    }
    return;
  }
  ++stats.vo_tracked;
  vo_state = localization::ReportedStateName(pose->state);
  if (mapper && pose->state == localization::ReportedState::kOk) {
    const geometry::SE3 T_world_rig_true = TruthBetween(t_ns) * T_vehicle_rig;
    if (!MapFrame(left, right, pose->T_world_out, T_world_rig_true).ok()) ++stats.map_errors;
  }
  PendingPose p;
  p.arrival_ns = t_ns + SecondsToNs(options.vo_latency_s);
  p.pose = control::PoseMeasurement{t_ns, 0, pose->T_world_out};
  pending.push_back(p);
}

Status LockstepDriver::Impl::MapFrame(const cv::Mat& left, const cv::Mat& right,
                                      const geometry::SE3& T_world_rig,
                                      const geometry::SE3& T_world_rig_true) {
  const geometry::SE3 T_world_rect0 = T_world_rig * vo->T_body_rect0();
  MAV_ASSIGN_OR_RETURN(const bool keyframe, mapper->ConsiderFrame(T_world_rect0));
  if (!keyframe) return Status::Ok();
  cv::Mat rect_left, rect_right;
  MAV_RETURN_IF_ERROR(vo->Rectify(left, right, /*rectified=*/false, &rect_left, &rect_right));
  MAV_RETURN_IF_ERROR(mapper->InsertKeyframe(rect_left, rect_right, T_world_rect0));
  keyframe_truth.push_back(T_world_rig_true * vo->T_body_rect0());
  return Status::Ok();
}

void LockstepDriver::Impl::StepOnce() {
  // Poses delivered by now, then the IMU sample, then one step with the command.
  for (const sim::PoseSample& p : out->poses) {
    ++stats.poses_fed;
    (void)ap->FeedPose(control::PoseMeasurement{p.t_ns, p.sensor, p.T_world_sensor});
  }
  while (!pending.empty() && pending.front().arrival_ns <= out->t_ns) {
    ++stats.poses_fed;
    (void)ap->FeedPose(pending.front().pose);
    pending.pop_front();
  }
  const control::ImuMeasurement imu{out->imu.t_ns, out->imu.gyro, out->imu.accel};
  if (vo) vo->AddGyro(imu.t_ns, R_rig_vehicle * imu.gyro);
  const control::RotorVector& command = ap->FeedImu(imu);
  if (out->t_ns >= next_record_ns && ap->estimator().initialized()) {
    next_record_ns = (out->t_ns / record_period_ns + 1) * record_period_ns;
    FlightSample r;
    r.t_s = NsToSeconds(out->t_ns);
    r.p_true = out->truth.p_world;
    r.q_true = out->truth.q_world_body;
    r.v_true = out->truth.v_world;
    r.omega_true = out->truth.omega_body;
    const control::EstimatorState& e = ap->estimator().state();
    r.p_est = e.p_world;
    r.q_est = e.q_world_body;
    r.armed = ap->armed();
    record.push_back(r);
  }
  out = &sim->Step(command);  // control:: and sim::RotorVector are one Eigen type
  stats.path_m += (out->truth.p_world - last_p).norm();
  last_p = out->truth.p_world;
  truth.push_back({out->t_ns, geometry::SE3(out->truth.q_world_body, out->truth.p_world)});
  while (truth.size() > 64) truth.pop_front();
  // A frame is rendered once the state over its shutter is known (one step after capture).
  if (vo) {
    const int64_t shutter_half_ns =
        SecondsToNs(std::max(0.0, rig->effects().shutter_s) / 2) + sim->step_ns() / 2;
    while (next_frame * frame_period_ns + shutter_half_ns <= out->t_ns) Capture(next_frame++);
  }
  // The online map is rebuilt every map_rebuild_s while new keyframes come (in the vehicle's
  // time: the build's wall time is measured, the lock-step clock waits for it).
  if (mapper && mapper->num_keyframes() > keyframes_at_build && out->t_ns >= next_build_ns) {
    next_build_ns = out->t_ns + SecondsToNs(options.map_rebuild_s);
    if (!RebuildOnlineMap().ok()) ++stats.map_errors;
  }
}

Result<VehicleView> LockstepDriver::Advance(double dt_s) {
  Impl& s = *impl_;
  if (s.truth.empty()) {
    s.truth.push_back(
        {s.out->t_ns, geometry::SE3(s.out->truth.q_world_body, s.out->truth.p_world)});
  }
  const int64_t until = s.out->t_ns + SecondsToNs(dt_s);
  while (s.out->t_ns < until) {
    if (s.sim->done()) return Status::DeadlineExceeded("the simulation reached its 7200 s limit");
    s.StepOnce();
  }
  VehicleView v;
  v.t_ns = s.out->t_ns;
  v.armed = s.ap->armed();
  v.estimator_converged = s.ap->estimator().converged();
  v.mode = s.ap->mode();
  v.moving = s.ap->moving();
  const control::EstimatorState& e = s.ap->estimator().state();
  v.p_est = e.p_world;
  v.v_est = e.v_world;
  v.q_est = e.q_world_body;
  const Eigen::Vector3d forward = e.q_world_body * Eigen::Vector3d::UnitX();
  v.yaw_est_rad = std::atan2(forward.y(), forward.x());
  const int64_t last = s.ap->last_pose_arrival_ns();
  v.pose_age_s = s.ap->estimator().initialized() ? NsToSeconds(s.out->t_ns - last)
                                                 : std::numeric_limits<double>::infinity();
  v.localization_needs_seed = s.vo_needs_seed;
  v.localization_state = s.vo ? s.vo_state : PoseSourceName(s.options.pose_source);
  v.poses_rejected = s.ap->estimator().counters().poses_rejected;
  v.collisions = s.sim->collision_count();
  v.map_version = s.map_version;
  v.p_true = s.out->truth.p_world;
  return v;
}

Status LockstepDriver::Arm() { return impl_->ap->Arm(); }

Status LockstepDriver::Disarm() {
  impl_->ap->Disarm();
  return Status::Ok();
}

Status LockstepDriver::GoTo(const Eigen::Vector3d& position, double yaw_rad,
                            const control::GoToLimits& limits) {
  return impl_->ap->Hover(position, yaw_rad, &limits);
}

Status LockstepDriver::Hold(const Eigen::Vector3d& position, double yaw_rad) {
  return impl_->ap->HoldPosition(position, yaw_rad);
}

Status LockstepDriver::Follow(const geometry::PolynomialTrajectory& trajectory) {
  return impl_->ap->SetTrajectory(trajectory, 0, Eigen::Vector3d::Zero(), /*allow_jump=*/false);
}

Result<LegPlan> LockstepDriver::Plan(const Eigen::Vector3d& start, const Eigen::Vector3d& goal,
                                     double yaw_rad) {
  Impl& s = *impl_;
  const auto plan_start = Clock::now();
  planning::PlanRequest request;
  request.start = start;
  request.goal = goal;
  request.limits = s.limits;
  request.start_yaw_rad = yaw_rad;
  request.seed = s.options.seed;
  Result<planning::PlanResult> result = planning::PlanPath(*s.map, s.roadmap.get(), request);
  s.plan_ms.Add(MsSince(plan_start));
  ++s.stats.plans;
  if (!result.ok()) {
    ++s.stats.plans_failed;
    return result.status();
  }
  if (!result->ok()) {
    ++s.stats.plans_failed;
    return Status::FailedPrecondition(std::string(planning::PlanStatusName(result->status)) + ": " +
                                      result->message);
  }
  LegPlan leg;
  leg.trajectory = std::move(result->trajectory);
  leg.path = std::move(result->shortened_path);
  leg.length_m = result->trajectory_length_m;
  leg.duration_s = result->duration_s;
  return leg;
}

Status LockstepDriver::CheckPoint(const Eigen::Vector3d& p) {
  const planning::PlanningMap& map = *impl_->map;
  char why[200];
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
                  map.Clearance(p), map.robot_radius(), impl_->stats.map_description.c_str());
    return Status::InvalidArgument(why);
  }
  return Status::Ok();
}

Result<Eigen::Vector3d> LockstepDriver::LandingSpot(const Eigen::Vector3d& above) {
  const planning::PlanningMap& map = *impl_->map;
  // The robot radius plus room for the estimate's drift on the IMU alone.
  const double radius = map.robot_radius() + 0.1;
  const double lowest = impl_->mission.start.z() + radius + 0.05;
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

Status LockstepDriver::SeedLocalization(const geometry::SE3& T_world_body) {
  Impl& s = *impl_;
  if (!s.vo) return Status::FailedPrecondition("the pose source is not the VO");
  s.vo->Reset(T_world_body * s.T_vehicle_rig);
  s.vo_needs_seed = false;
  s.vo_state = "seeded";
  return Status::Ok();
}

const std::vector<FlightSample>& LockstepDriver::record() const { return impl_->record; }

LockstepStats LockstepDriver::stats() const {
  LockstepStats st = impl_->stats;
  st.render_ms = impl_->render_ms.Summary();
  st.vo_ms = impl_->vo_ms.Summary();
  st.plan_ms = impl_->plan_ms.Summary();
  st.map_build_ms = impl_->map_build_ms.Summary();
  st.keyframes = impl_->mapper ? impl_->mapper->num_keyframes() : 0;
  st.map_rebuilds = impl_->map_version;
  st.poses_rejected = impl_->ap->estimator().counters().poses_rejected;
  st.collisions = impl_->sim->collision_count();
  for (const sim::Collision& c : impl_->sim->collisions()) {
    std::ostringstream d;
    d << "t=" << NsToSeconds(c.t_ns) << " s at (" << c.p_world.transpose() << "): " << c.what;
    st.collision_descriptions.push_back(d.str());
  }
  return st;
}

const control::Autopilot& LockstepDriver::autopilot() const { return *impl_->ap; }
const sim::World& LockstepDriver::world() const { return *impl_->world; }
const planning::PlanningMap& LockstepDriver::planning_map() const { return *impl_->map; }

Status LockstepDriver::WriteMap(const std::string& path) const {
  return dataset::WriteOctomapBt(impl_->planning_grid, path);
}

Result<MapQuality> LockstepDriver::EvaluateMap() const {
  const Impl& s = *impl_;
  MapQuality q;
  mapping::CollisionEvalOptions eval_options;
  // Unknown counts as the planner counts it (free in the online map).
  eval_options.computed_unknown_is_occupied = s.options.map_source == MapSource::kGroundTruth;
  std::vector<uint8_t> observable;
  if (!s.keyframe_truth.empty()) {
    MAV_ASSIGN_OR_RETURN(observable,
                         mapping::ObservableVoxels(s.truth_grid, s.keyframe_truth, s.vo->rig()));
    eval_options.observable = &observable;
    q.observable_only = true;
  }
  MAV_ASSIGN_OR_RETURN(const mapping::CollisionOutcomes outcomes,
                       mapping::EvaluateCollisions(s.truth_grid, s.planning_grid, eval_options));
  q.mcc = outcomes.Mcc();
  q.missed_percent = outcomes.Percent(outcomes.missed_collision);
  q.false_percent = outcomes.Percent(outcomes.false_collision);
  q.positions = outcomes.total();
  return q;
}

}  // namespace mav::mission
