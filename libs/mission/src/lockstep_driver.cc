#include "mav/mission/lockstep_driver.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <sstream>

#include <opencv2/core.hpp>

#include "mav/camera/stereo.h"
#include "mav/common/check.h"
#include "mav/common/text.h"
#include "mav/common/time.h"
#include "mav/dataset/occupancy_io.h"
#include "mav/eval/flight_mission.h"
#include "mav/localization/rig_odometry.h"
#include "mav/mapping/collision_eval.h"
#include "mav/mapping/observability.h"
#include "mav/mapping/pipeline.h"
#include "mav/mission/planning_setup.h"
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
  if (std::string vehicle_why; !vehicle.IsValid(&vehicle_why)) msg << vehicle_why;
  if (std::string planning_why; msg.str().empty() && !planning.IsValid(&planning_why)) {
    msg << "planning." << planning_why;
  }
  check(map_source == MapSource::kGroundTruth || vehicle.pose_source == PoseSource::kVo,
        "map_source: the online map is built from the VO's keyframes (pose_source vo)");
  check(map_rebuild_s > 0 && map_rebuild_s <= 60, "map_rebuild_s: must be in (0, 60]");
  check(map_max_depth_m >= 1 && map_max_depth_m <= 50, "map_max_depth_m: must be in [1, 50]");
  check(record_rate_hz > 0 && record_rate_hz <= vehicle.imu_rate_hz,
        "record_rate_hz: must be in (0, vehicle.imu_rate_hz]");
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

namespace {

using Clock = std::chrono::steady_clock;
double MsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

struct PendingPose {
  int64_t arrival_ns = 0;
  control::PoseMeasurement pose;
};

}  // namespace

struct LockstepDriver::Impl {
  dataset::MissionSpec mission;
  LockstepOptions options;
  sim::Preset preset;
  std::shared_ptr<const sim::World> world;
  std::unique_ptr<sim::FlightSimulation> sim;
  std::unique_ptr<control::Autopilot> ap;
  std::unique_ptr<VehicleCamera> camera;  // vision in the loop (pose source vo)
  std::unique_ptr<localization::RigOdometry> vo;
  geometry::SE3 T_vehicle_rig;
  // The vehicle IMU's rotation into the rig's frame, as mav-localization applies it (its
  // t_body_imu, a quaternion): the same arithmetic, so the two drivers' gyro agree to the bit.
  Eigen::Quaterniond q_rig_vehicle;
  std::shared_ptr<const planning::PlanningMap> map;
  dataset::OccupancyGrid truth_grid;     // the world's exact occupancy (also the map's geometry)
  dataset::OccupancyGrid planning_grid;  // what `map` was built from
  // The online map (MapSource::kOnline).
  std::unique_ptr<mapping::MappingPipeline> mapper;
  std::vector<geometry::SE3> keyframe_truth;  // true T_world_rect0 of every keyframe
  int64_t keyframes_at_build = 0;
  int64_t next_build_ns = 0;
  uint64_t map_version = 0;
  // The roadmap of `map`, or null until the next plan needs it (the map was replaced since).
  std::shared_ptr<const planning::Roadmap> roadmap;
  uint64_t roadmap_builds = 0;
  MissionPlanning planning;

  const sim::FlightStep* out = nullptr;
  std::deque<PendingPose> pending;
  localization::RigOdometryOptions vo_options;  // what `vo` was created from
  bool vo_down = false;
  bool vo_restarts = false;  // the current outage ends with a restarted localization
  bool vo_needs_seed = false;
  bool vo_reseed_pending = false;  // a frame was lost: seed the VO at the estimate (Advance)
  std::string vo_state = "starting";
  std::unique_ptr<FlightRecorder> recorder;
  Eigen::Vector3d last_p = Eigen::Vector3d::Zero();
  LockstepStats stats;
  RuntimeWindow render_ms{100000}, vo_ms{100000}, plan_ms{10000}, map_build_ms{10000};

  // The planning map (the world's exact occupancy, or the online map's prior), its roadmap and
  // the speed limits.
  Status BuildPlanning(const ProgressCallback& progress);
  // Replaces the planning map by `grid`'s; its roadmap is built now (`roadmap_now`: the first
  // map) or by the next plan (EnsureRoadmap): an online map is rebuilt every few seconds, and a
  // roadmap (~1 s for 20 000 milestones) for each version would mostly go unused.
  Status LoadPlanningMap(const dataset::OccupancyGrid& grid, const std::string& what,
                         const ProgressCallback& progress, bool roadmap_now);
  Status EnsureRoadmap(const ProgressCallback& progress);
  // The online map from the keyframes so far (the sparse mesh of libs/mapping).
  Status RebuildOnlineMap();
  // Offers a tracked frame (the VO's rig pose; the true one for the map's evaluation) to the
  // online map's keyframe selection.
  Status MapFrame(const cv::Mat& left, const cv::Mat& right, const geometry::SE3& T_world_rig,
                  const geometry::SE3& T_world_rig_true);
  void StepOnce();
  void Capture(int64_t frame);
  // The VO's pose (in its own, possibly tilt-corrected frame: Estimator::source_frame) for the
  // vehicle at T_world_body: where a restarted VO starts.
  geometry::SE3 VoPoseAt(const geometry::SE3& T_world_body) const {
    return ap->estimator().source_frame(0).Inverse() * T_world_body * T_vehicle_rig;
  }
  bool InOutage(int64_t t_ns, bool* restart) const;
};

LockstepDriver::LockstepDriver(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
LockstepDriver::~LockstepDriver() = default;

Status LockstepDriver::Impl::BuildPlanning(const ProgressCallback& progress) {
  planning = MissionPlanningFor(mission, preset, options.planning, options.vehicle.seed,
                                /*unknown_is_free=*/options.map_source == MapSource::kOnline);
  if (progress) progress("ground-truth map", 0.0);
  truth_grid = sim::ComputeOccupancy(*world, planning.map_resolution_m);
  if (options.map_source == MapSource::kGroundTruth) {
    return LoadPlanningMap(truth_grid, "ground-truth occupancy", progress, true);
  }
  // The online map starts as the ground below the take-off (the one thing known before the
  // flight) and everything else unknown.
  dataset::OccupancyGrid prior(truth_grid.geometry());
  AddGroundPrior(mission.start.z(), &prior);
  return LoadPlanningMap(prior, "online map (no keyframe yet)", progress, true);
}

Status LockstepDriver::Impl::LoadPlanningMap(const dataset::OccupancyGrid& grid,
                                             const std::string& what,
                                             const ProgressCallback& progress, bool roadmap_now) {
  MAV_ASSIGN_OR_RETURN(std::string bt, dataset::EncodeOctomapBt(grid));
  MAV_ASSIGN_OR_RETURN(map, planning::PlanningMap::LoadBytes(bt, mission.world + " " + what,
                                                             planning.map, {}, progress));
  roadmap.reset();
  if (roadmap_now) MAV_RETURN_IF_ERROR(EnsureRoadmap(progress));
  planning_grid = grid;
  std::ostringstream description;
  description << what << " of " << mission.world << " at " << grid.resolution()
              << " m, robot radius " << planning.map.robot_radius_m << " m, "
              << (roadmap != nullptr ? "" : "up to ")
              << (roadmap != nullptr ? roadmap->info().milestones : planning.roadmap.max_milestones)
              << " roadmap milestones";
  stats.map_description = description.str();
  return Status::Ok();
}

Status LockstepDriver::Impl::EnsureRoadmap(const ProgressCallback& progress) {
  if (roadmap != nullptr) return Status::Ok();
  MAV_ASSIGN_OR_RETURN(roadmap, planning::Roadmap::Build(*map, planning.roadmap, {}, progress));
  ++roadmap_builds;
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
  AddGroundPrior(mission.start.z(), &built.grid);
  MAV_RETURN_IF_ERROR(LoadPlanningMap(
      built.grid, "online map (" + std::to_string(built.keyframes) + " keyframes)", {}, false));
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
  MAV_ASSIGN_OR_RETURN(MissionWorld mission_world, MakeMissionWorld(mission, options.vehicle.seed));
  s.preset = std::move(mission_world.preset);
  s.world = s.preset.world;

  // The vehicle and its flight software.
  const VehicleOptions& vehicle = options.vehicle;
  const dataset::FlightTask task = MissionFlightTask(mission, vehicle);
  MAV_ASSIGN_OR_RETURN(sim::FlightSimulation flight,
                       sim::FlightSimulation::Create(task, options.vehicle.seed, {},
                                                     std::move(mission_world.collision)));
  s.sim = std::make_unique<sim::FlightSimulation>(std::move(flight));
  s.out = &s.sim->Initial();
  s.last_p = s.out->truth.p_world;
  s.T_vehicle_rig = VehicleRigMount(options.vehicle.camera_pitch_rad);
  s.q_rig_vehicle = s.T_vehicle_rig.Inverse().Rotation();
  MAV_ASSIGN_OR_RETURN(control::Autopilot autopilot,
                       control::Autopilot::Create(MissionAutopilotOptions(task, vehicle)));
  s.ap = std::make_unique<control::Autopilot>(std::move(autopilot));

  // Vision in the loop.
  if (options.vehicle.pose_source == PoseSource::kVo) {
    const sim::MulticopterState& x0 = s.out->truth;
    s.camera = std::make_unique<VehicleCamera>(s.preset, vehicle, s.sim->step_ns(), s.out->t_ns,
                                               geometry::SE3(x0.q_world_body, x0.p_world));
    localization::RigOdometryOptions vo;
    vo.method = options.vo_method;
    vo.calibration = s.camera->calibration();
    vo.T_world_body0 = geometry::SE3(x0.q_world_body, x0.p_world) * s.T_vehicle_rig;
    vo.odometry.sparse.gyro_rotation_sigma_rad = vehicle.vo_gyro_sigma_rad;
    MAV_ASSIGN_OR_RETURN(s.vo, localization::RigOdometry::Create(vo));
    s.vo_options = vo;
  }
  if (options.map_source == MapSource::kOnline) {
    mapping::MappingPipelineOptions mapping_options;
    mapping_options.run_octomap = false;
    mapping_options.sparse.max_depth_m = options.map_max_depth_m;
    MAV_ASSIGN_OR_RETURN(mapping::MappingPipeline mapper,
                         mapping::MappingPipeline::Create(s.vo->rig(), mapping_options));
    s.mapper = std::make_unique<mapping::MappingPipeline>(std::move(mapper));
  }
  s.recorder = std::make_unique<FlightRecorder>(options.record_rate_hz);

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

void LockstepDriver::Impl::Capture(int64_t frame) {
  const int64_t t_ns = camera->FrameTimeNs(frame);
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
      // A restarted process knows nothing, its gyro bias included: a new odometry.
      Result<std::unique_ptr<localization::RigOdometry>> restarted =
          localization::RigOdometry::Create(vo_options);
      MAV_CHECK(restarted.ok()) << restarted.status().ToString();  // created from these before
      vo = std::move(*restarted);
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
  camera->Render(frame, &left, &right);
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
    // Seeded at the end of the tick (Advance), as the services driver can: with one frame per
    // tick that is just before the next frame, so the seed is the estimate at its capture.
    vo_reseed_pending = options.reseed_after_loss;
    return;
  }
  ++stats.vo_tracked;
  vo_state = localization::ReportedStateName(pose->state);
  if (mapper && pose->state == localization::ReportedState::kOk) {
    const geometry::SE3 T_world_rig_true = camera->TrueRigPose(t_ns);
    if (!MapFrame(left, right, pose->T_world_out, T_world_rig_true).ok()) ++stats.map_errors;
  }
  PendingPose p;
  p.arrival_ns = t_ns + SecondsToNs(options.vehicle.vo_latency_s);
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
  if (vo) vo->AddGyro(imu.t_ns, q_rig_vehicle * imu.gyro);
  const control::RotorVector& command = ap->FeedImu(imu);
  out = &sim->Step(command);  // control:: and sim::RotorVector are one Eigen type
  stats.path_m += (out->truth.p_world - last_p).norm();
  last_p = out->truth.p_world;
  // A frame is rendered once the state over its shutter is known (one step after capture).
  if (camera) {
    camera->Observe(out->t_ns, geometry::SE3(out->truth.q_world_body, out->truth.p_world));
    for (const int64_t frame : camera->DueFrames()) Capture(frame);
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
  const int64_t until = s.out->t_ns + SecondsToNs(dt_s);
  while (s.out->t_ns < until) {
    if (s.sim->done()) return Status::DeadlineExceeded("the simulation reached its 7200 s limit");
    s.StepOnce();
  }
  if (s.vo_reseed_pending && s.ap->estimator().initialized()) {
    const control::EstimatorState& e = s.ap->estimator().state();
    s.vo->Reset(s.VoPoseAt(geometry::SE3(e.q_world_body, e.p_world)));
  }
  s.vo_reseed_pending = false;
  VehicleView v;
  v.t_ns = s.out->t_ns;
  v.armed = s.ap->armed();
  v.estimator_initialized = s.ap->estimator().initialized();
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
  v.localization_state = s.vo ? s.vo_state : PoseSourceName(s.options.vehicle.pose_source);
  v.poses_rejected = s.ap->estimator().counters().poses_rejected;
  v.collisions = s.sim->collision_count();
  v.map_version = s.map_version;
  v.map_keyframes = s.mapper ? s.mapper->num_keyframes() : 0;
  v.truth = TrueState{s.out->truth.p_world, s.out->truth.q_world_body, s.out->truth.v_world,
                      s.out->truth.omega_body};
  s.recorder->Offer(v);
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
  request.limits = s.planning.limits;
  request.start_yaw_rad = yaw_rad;
  request.seed = s.options.vehicle.seed;
  if (const Status built = s.EnsureRoadmap({}); !built.ok()) {
    s.plan_ms.Add(MsSince(plan_start));
    ++s.stats.plans;
    ++s.stats.plans_failed;
    return built;
  }
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
  return CheckPointInMap(*impl_->map, p, impl_->stats.map_description);
}

Result<Eigen::Vector3d> LockstepDriver::LandingSpot(const Eigen::Vector3d& above) {
  return LandingSpotInMap(*impl_->map, above, impl_->mission.start.z());
}

Status LockstepDriver::SeedLocalization(const geometry::SE3& T_world_body) {
  Impl& s = *impl_;
  if (!s.vo) return Status::FailedPrecondition("the pose source is not the VO");
  s.vo->Reset(s.VoPoseAt(T_world_body));
  s.vo_needs_seed = false;
  s.vo_state = "seeded";
  return Status::Ok();
}

const std::vector<FlightSample>& LockstepDriver::record() const {
  return impl_->recorder->samples();
}

LockstepStats LockstepDriver::stats() const {
  LockstepStats st = impl_->stats;
  st.render_ms = impl_->render_ms.Summary();
  st.vo_ms = impl_->vo_ms.Summary();
  st.plan_ms = impl_->plan_ms.Summary();
  st.map_build_ms = impl_->map_build_ms.Summary();
  st.keyframes = impl_->mapper ? impl_->mapper->num_keyframes() : 0;
  st.map_rebuilds = impl_->map_version;
  st.roadmap_builds = impl_->roadmap_builds;
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
