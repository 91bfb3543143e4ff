#include "clients/mavctl/mission_driver.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <thread>

#include "mav/v1/control.grpc.pb.h"
#include "mav/v1/localization.grpc.pb.h"
#include "mav/v1/mapping.grpc.pb.h"
#include "mav/v1/planning.grpc.pb.h"
#include "mav/v1/simulator.grpc.pb.h"

#include "clients/common/channel.h"
#include "mav/camera/rectifier.h"
#include "mav/common/time.h"
#include "mav/dataset/occupancy_io.h"
#include "mav/mapping/collision_eval.h"
#include "mav/mapping/keyframes.h"
#include "mav/mapping/observability.h"
#include "mav/planning/planner.h"
#include "mav/planning/planning_map.h"
#include "services/common/grpc_status.h"
#include "services/common/proto_codec.h"
#include "services/control/control_core.h"
#include "services/control/convert.h"

namespace mav::mavctl {

namespace {

using Clock = std::chrono::steady_clock;
double MsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

constexpr size_t kUploadChunkBytes = 1 << 20;
// How often Advance asks whether the simulator reached the tick's end.
constexpr auto kPollPeriod = std::chrono::microseconds(500);

void ToProto(const Eigen::Vector3d& v, v1::Vector3* out) {
  out->set_x(v.x());
  out->set_y(v.y());
  out->set_z(v.z());
}
Eigen::Vector3d FromProto(const v1::Vector3& v) { return {v.x(), v.y(), v.z()}; }
Eigen::Quaterniond FromProto(const v1::Quaternion& q) { return {q.w(), q.x(), q.y(), q.z()}; }

control::FlightMode ModeFromProto(v1::ControlMode mode) {
  switch (mode) {
    case v1::CONTROL_MODE_HOVER:
      return control::FlightMode::kHover;
    case v1::CONTROL_MODE_TRAJECTORY:
      return control::FlightMode::kTrajectory;
    case v1::CONTROL_MODE_FAILSAFE:
      return control::FlightMode::kFailsafe;
    default:
      return control::FlightMode::kDisarmed;
  }
}

v1::LocalizationMethod MethodToProto(localization::Method method) {
  switch (method) {
    case localization::Method::kSparsePixel:
      return v1::LOCALIZATION_METHOD_SPARSE_PIXEL;
    case localization::Method::kSparseSubpixel:
      return v1::LOCALIZATION_METHOD_SPARSE_SUBPIXEL;
    case localization::Method::kDense:
      return v1::LOCALIZATION_METHOD_DENSE;
  }
  return v1::LOCALIZATION_METHOD_UNSPECIFIED;
}

const char* TrackingName(v1::TrackingState state) {
  switch (state) {
    case v1::TRACKING_STATE_INITIALIZING:
      return "initializing";
    case v1::TRACKING_STATE_OK:
      return "ok";
    case v1::TRACKING_STATE_LOST:
      return "lost";
    case v1::TRACKING_STATE_DEGRADED:
      return "degraded";
    default:
      return "starting";
  }
}

RuntimeStats StatsFromProto(const v1::RuntimeStats& s) {
  RuntimeStats out;
  out.count = s.count();
  out.mean_ms = s.mean_ms();
  out.median_ms = s.median_ms();
  out.p95_ms = s.p95_ms();
  out.p99_ms = s.p99_ms();
  out.max_ms = s.max_ms();
  return out;
}

}  // namespace

struct ServiceDriver::Impl {
  dataset::MissionSpec mission;
  ServiceMissionOptions options;
  ServiceAddresses addresses;
  std::unique_ptr<v1::Simulator::Stub> simulator;
  std::unique_ptr<v1::Localization::Stub> localization;
  std::unique_ptr<v1::Control::Stub> control;
  std::unique_ptr<v1::Planning::Stub> planning;
  std::unique_ptr<v1::Mapping::Stub> mapping;
  mission::MissionPlanning plan_options;
  // The online map: the world's exact occupancy (its geometry, and the final map's evaluation),
  // the grid the planner has now, and when to rebuild.
  dataset::OccupancyGrid truth_grid, planning_grid;
  int64_t keyframes_at_build = 0;
  int64_t next_build_ns = 0;
  uint64_t map_version = 0;
  bool planner_current = false;  // mav-planning has map_bt and its roadmap
  uint64_t roadmap_milestones = 0;
  RuntimeWindow map_build_ms{10000};
  geometry::SE3 T_vehicle_rig;
  std::string map_bt;
  std::shared_ptr<const planning::PlanningMap> map;
  std::unique_ptr<mission::FlightRecorder> recorder;
  int64_t t_ns = 0;
  bool running = false;
  ServiceFigures figures;
  RuntimeWindow plan_ms{10000}, advance_ms{100000};
  std::function<void(const std::string&)> progress;

  // The localization's counters restart at each Configure (a seed): what it counted before,
  // and the frames the simulator had published by then.
  uint64_t vo_frames_before = 0, vo_lost_before = 0, frames_published_at_seed = 0;
  uint64_t frames_published = 0;  // by the end of the last tick

  bool vo() const { return options.vehicle.pose_source == mission::PoseSource::kVo; }
  // The localization's status once it has answered every frame published by the end of the
  // tick (the lock-step waits only for the frames due at the IMU's time, so the tick's own
  // frame may still be in the VO): its tracking state is then the tick's last frame's, as in
  // process. Gives up after lockstep_wait_s (a stalled service is not waited for).
  Status SettledLocalizationStatus(v1::LocalizationStatus* loc);
  // Control.GetState and Localization.GetStatus with the quick deadline.
  Status GetControlState(v1::ControlState* state) {
    v1::ControlGetStateRequest request;
    return Unary("mav-control", addresses.control, "GetState",
                 [&](grpc::ClientContext* c) { return control->GetState(c, request, state); });
  }
  Status GetLocalizationStatus(v1::LocalizationStatus* status) {
    v1::LocalizationGetStatusRequest request;
    return Unary(
        "mav-localization", addresses.localization, "GetStatus",
        [&](grpc::ClientContext* c) { return localization->GetStatus(c, request, status); });
  }

  // One unary call with the quick deadline (or `timeout_s`); the error names the service, its
  // address and the RPC.
  template <typename Call>
  Status Unary(const char* service, const std::string& address, const char* rpc, Call&& call,
               double timeout_s = 0) {
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() +
                         std::chrono::milliseconds(static_cast<int64_t>(
                             1000 * (timeout_s > 0 ? timeout_s : options.rpc_timeout_s))));
    return service_common::OutgoingCallStatus(
        call(&context), std::string(service) + " at " + address + ": " + rpc, service);
  }

  Status LoadFlight(const std::string& mission_yaml, v1::FlightStatus* loaded);
  // A server-streamed occupancy answer's bytes.
  Status Download(grpc::ClientReader<v1::OccupancyChunk>* reader, const std::string& what,
                  std::string* bytes);
  Status SetUpPlanning(const std::function<void(const std::string&)>& progress);
  // `bt` becomes the driver's map (the mission's re-checks read it) and mav-planning's: uploaded
  // with its roadmap built now (`planner_now`: the first map) or by the next plan
  // (EnsurePlannerMap). An online map is rebuilt every few seconds; most versions are only
  // re-checked, and a planner map (its distance field) and roadmap (~1 s for 20 000 milestones)
  // for each would mostly go unused.
  Status LoadPlanningMap(std::string bt, const std::string& what, bool planner_now);
  Status EnsurePlannerMap();
  Status StartMapping();
  // The online map from the keyframes so far (BuildMap, GetOccupancy, the ground prior, upload).
  Status RebuildOnlineMap();
  Status ConfigureControl();
  // Configures mav-localization to start at T_world_body; with reset_if_configured a configured
  // one is only Reset there (the in-process driver's re-seed, which keeps the VO's gyro bias).
  Status ConfigureLocalization(const geometry::SE3& T_world_body, bool reset_if_configured = false);
  Status WaitForDataPlane();
  Result<v1::FlightStatus> RunUntil(int64_t until_ns);
};

ServiceDriver::ServiceDriver(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
ServiceDriver::~ServiceDriver() { Stop(); }

Status ServiceDriver::Impl::LoadFlight(const std::string& mission_yaml, v1::FlightStatus* loaded) {
  v1::LoadFlightTaskRequest request;
  v1::MissionFlight* m = request.mutable_mission();
  m->set_yaml(mission_yaml);
  m->set_source_name(mission.source);
  m->set_pose_source(mission::PoseSourceName(options.vehicle.pose_source));
  m->set_camera_pitch_rad(options.vehicle.camera_pitch_rad);
  m->set_camera_rate_hz(options.vehicle.camera_rate_hz);
  m->set_imu_rate_hz(options.vehicle.imu_rate_hz);
  request.set_seed(options.vehicle.seed);
  request.set_lockstep(true);
  request.set_lockstep_timeout_s(options.lockstep_timeout_s);
  return Unary(
      "mav-simulator", addresses.simulator, "LoadFlightTask",
      [&](grpc::ClientContext* c) { return simulator->LoadFlightTask(c, request, loaded); },
      options.setup_timeout_s);
}

Status ServiceDriver::Impl::Download(grpc::ClientReader<v1::OccupancyChunk>* reader,
                                     const std::string& what, std::string* bytes) {
  v1::OccupancyChunk chunk;
  bytes->clear();
  while (reader->Read(&chunk)) {
    if (chunk.chunk().offset() != bytes->size()) {
      return Status::DataLoss(what + ": chunk at offset " + std::to_string(chunk.chunk().offset()) +
                              " after " + std::to_string(bytes->size()) + " bytes");
    }
    *bytes += chunk.chunk().data();
  }
  return service_common::OutgoingCallStatus(reader->Finish(), what, what.substr(0, what.find(' ')));
}

Status ServiceDriver::Impl::SetUpPlanning(const std::function<void(const std::string&)>& progress) {
  // The world's exact occupancy from the simulator, as the in-process driver computes it.
  if (progress) progress("ground-truth occupancy from mav-simulator");
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() +
                       std::chrono::seconds(static_cast<int64_t>(options.setup_timeout_s)));
  v1::GetGroundTruthOccupancyRequest request;
  request.set_resolution_m(plan_options.map_resolution_m);
  request.set_format(options.online_map ? v1::OCCUPANCY_FORMAT_MAVOCC
                                        : v1::OCCUPANCY_FORMAT_OCTOMAP_BT);
  std::string bytes;
  const std::unique_ptr<grpc::ClientReader<v1::OccupancyChunk>> reader =
      simulator->GetGroundTruthOccupancy(&context, request);
  MAV_RETURN_IF_ERROR(
      Download(reader.get(),
               "mav-simulator at " + addresses.simulator + ": GetGroundTruthOccupancy", &bytes));
  if (progress) progress("uploading the map to mav-planning and building its roadmap");
  if (!options.online_map) {
    return LoadPlanningMap(std::move(bytes), "ground-truth occupancy", true);
  }
  // The online map starts as the ground below the take-off (the one thing known before the
  // flight) and everything else unknown.
  MAV_ASSIGN_OR_RETURN(truth_grid, dataset::DecodeMavocc(bytes, "ground-truth occupancy"));
  dataset::OccupancyGrid prior(truth_grid.geometry());
  mission::AddGroundPrior(mission.start.z(), &prior);
  MAV_ASSIGN_OR_RETURN(std::string bt, dataset::EncodeOctomapBt(prior));
  planning_grid = std::move(prior);
  return LoadPlanningMap(std::move(bt), "online map (no keyframe yet)", true);
}

Status ServiceDriver::Impl::LoadPlanningMap(std::string bt, const std::string& what,
                                            bool planner_now) {
  const std::string name = mission.world + " " + what;
  MAV_ASSIGN_OR_RETURN(map, planning::PlanningMap::LoadBytes(bt, name, plan_options.map));
  map_bt = std::move(bt);
  planner_current = false;
  if (planner_now) MAV_RETURN_IF_ERROR(EnsurePlannerMap());
  std::ostringstream description;
  description << what << " of " << mission.world << " at " << plan_options.map_resolution_m
              << " m, robot radius " << plan_options.map.robot_radius_m << " m, "
              << (planner_now ? "" : "up to ")
              << (planner_now ? roadmap_milestones : plan_options.roadmap.max_milestones)
              << " roadmap milestones (mav-planning)";
  figures.map_description = description.str();
  return Status::Ok();
}

Status ServiceDriver::Impl::EnsurePlannerMap() {
  if (planner_current) return Status::Ok();
  const planning::MapOptions& mo = plan_options.map;
  v1::MapOptions map_options;
  map_options.set_robot_radius_m(mo.robot_radius_m);
  map_options.set_unknown_is_free(mo.unknown_space == planning::UnknownSpace::kFree);
  map_options.set_max_distance_m(mo.max_distance_m);
  ToProto(mo.planning_bounds->min, map_options.mutable_bounds()->mutable_min());
  ToProto(mo.planning_bounds->max, map_options.mutable_bounds()->mutable_max());
  v1::MapInfo info;
  MAV_RETURN_IF_ERROR(Unary(
      "mav-planning", addresses.planning, "UploadMap",
      [&](grpc::ClientContext* c) {
        auto writer = planning->UploadMap(c, &info);
        size_t offset = 0;
        do {
          v1::UploadMapRequest message;
          if (offset == 0) *message.mutable_options() = map_options;
          const size_t n = std::min(kUploadChunkBytes, map_bt.size() - offset);
          v1::FileChunk* chunk = message.mutable_chunk();
          chunk->set_offset(offset);
          chunk->set_total_size(map_bt.size());
          chunk->set_data(map_bt.substr(offset, n));
          offset += n;
          chunk->set_last(offset == map_bt.size());
          if (!writer->Write(message)) break;
        } while (offset < map_bt.size());
        writer->WritesDone();
        return writer->Finish();
      },
      options.setup_timeout_s));
  const planning::RoadmapOptions& ro = plan_options.roadmap;
  v1::BuildRoadmapRequest roadmap;
  roadmap.set_time_budget_s(ro.time_budget_s);
  roadmap.set_max_milestones(static_cast<uint32_t>(ro.max_milestones));
  roadmap.set_seed(ro.seed);
  roadmap.set_validity_resolution_m(ro.validity_resolution_m);
  roadmap.set_clearance_margin_m(ro.clearance_margin_m);
  v1::RoadmapInfo roadmap_info;
  MAV_RETURN_IF_ERROR(Unary(
      "mav-planning", addresses.planning, "BuildRoadmap",
      [&](grpc::ClientContext* c) { return planning->BuildRoadmap(c, roadmap, &roadmap_info); },
      options.setup_timeout_s));
  planner_current = true;
  roadmap_milestones = roadmap_info.milestones();
  ++figures.roadmap_builds;
  return Status::Ok();
}

Status ServiceDriver::Impl::StartMapping() {
  // The in-process pipeline's keyframe rule and point depth.
  const mapping::KeyframeOptions keyframes;
  v1::StartSessionRequest request;
  request.mutable_calibration()->set_simulator_address(addresses.simulator);
  request.mutable_keyframes()->set_min_translation_m(keyframes.min_translation_m);
  request.mutable_keyframes()->set_min_rotation_deg(keyframes.min_rotation_rad * 180 / M_PI);
  request.mutable_keyframes()->set_max_depth_m(options.map_max_depth_m);
  request.set_pose_source(v1::POSE_SOURCE_LOCALIZATION);
  request.set_sparse_mesh_only(true);
  v1::MappingStatus status;
  return Unary("mav-mapping", addresses.mapping, "StartSession",
               [&](grpc::ClientContext* c) { return mapping->StartSession(c, request, &status); });
}

Status ServiceDriver::Impl::RebuildOnlineMap() {
  const auto start = Clock::now();
  // A map of a partly seen room: the observed surfaces occupied, the space the lines of sight
  // crossed free, the rest unknown (free for the planner), on the world's grid.
  v1::BuildMapRequest build;
  build.set_method(v1::MAPPING_METHOD_SPARSE_MESH);
  build.set_resolution_m(truth_grid.resolution());
  ToProto(truth_grid.origin(), build.mutable_bounds()->mutable_min());
  ToProto(truth_grid.geometry().max_corner(), build.mutable_bounds()->mutable_max());
  build.set_unknown(v1::UNKNOWN_HANDLING_KEEP_UNKNOWN);
  build.mutable_sparse_mesh()->set_min_visibility(
      static_cast<uint32_t>(options.map_min_visibility));
  build.set_prefer(v1::MAP_PREFERENCE_SAFETY);
  build.set_surfaces_only(true);
  v1::BuildMapResponse built;
  MAV_RETURN_IF_ERROR(Unary(
      "mav-mapping", addresses.mapping, "BuildMap",
      [&](grpc::ClientContext* c) { return mapping->BuildMap(c, build, &built); },
      options.setup_timeout_s));
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() +
                       std::chrono::seconds(static_cast<int64_t>(options.setup_timeout_s)));
  v1::GetOccupancyRequest get;
  get.set_method(v1::MAPPING_METHOD_SPARSE_MESH);
  get.set_format(v1::OCCUPANCY_FORMAT_MAVOCC);
  std::string bytes;
  const std::unique_ptr<grpc::ClientReader<v1::OccupancyChunk>> reader =
      mapping->GetOccupancy(&context, get);
  MAV_RETURN_IF_ERROR(
      Download(reader.get(), "mav-mapping at " + addresses.mapping + ": GetOccupancy", &bytes));
  MAV_ASSIGN_OR_RETURN(const dataset::OccupancyGrid online,
                       dataset::DecodeMavocc(bytes, "the online map"));
  // On the world's grid (the same geometry, voxel for voxel, unless the service rounded it).
  dataset::OccupancyGrid grid(truth_grid.geometry());
  for (int k = 0; k < grid.size().z(); ++k) {
    for (int j = 0; j < grid.size().y(); ++j) {
      for (int i = 0; i < grid.size().x(); ++i) {
        grid[grid.Linear(i, j, k)] = online.StateAt(grid.CenterOf({i, j, k}));
      }
    }
  }
  mission::AddGroundPrior(mission.start.z(), &grid);
  MAV_ASSIGN_OR_RETURN(std::string bt, dataset::EncodeOctomapBt(grid));
  MAV_RETURN_IF_ERROR(LoadPlanningMap(
      std::move(bt), "online map (" + std::to_string(built.keyframes()) + " keyframes)", false));
  planning_grid = std::move(grid);
  keyframes_at_build = built.keyframes();
  ++map_version;
  map_build_ms.Add(MsSince(start));
  return Status::Ok();
}

Status ServiceDriver::Impl::ConfigureControl() {
  control_service::ControlConfig config;
  const dataset::FlightTask task = mission::MissionFlightTask(mission, options.vehicle);
  config.autopilot = mission::MissionAutopilotOptions(task, options.vehicle);
  config.lockstep = true;
  if (vo()) {
    // The localization service's pose of its "body" (the rig), merged at stamp + the modelled
    // latency as the in-process driver merges it.
    config.pose_frames = {"body"};
    control_service::LockstepPoseOptions lockstep;
    lockstep.latency_s = options.vehicle.vo_latency_s;
    lockstep.wait_s = options.lockstep_wait_s;
    config.lockstep_poses = {lockstep};
  } else {
    config.pose_frames = {"pose_sensor0"};
  }
  v1::ControlConfigureRequest request;
  control_service::ToProto(config, &request);
  v1::ControlStatus status;
  v1::DisarmRequest disarm;
  MAV_RETURN_IF_ERROR(
      Unary("mav-control", addresses.control, "Disarm",
            [&](grpc::ClientContext* c) { return control->Disarm(c, disarm, &status); }));
  return Unary("mav-control", addresses.control, "Configure",
               [&](grpc::ClientContext* c) { return control->Configure(c, request, &status); });
}

Status ServiceDriver::Impl::SettledLocalizationStatus(v1::LocalizationStatus* loc) {
  const auto give_up =
      Clock::now() + std::chrono::microseconds(static_cast<int64_t>(1e6 * options.lockstep_wait_s));
  while (true) {
    MAV_RETURN_IF_ERROR(GetLocalizationStatus(loc));
    const uint64_t answered =
        loc->frames_processed() + loc->frames_dropped() + loc->frames_rejected();
    const bool settled = loc->state() == v1::LOCALIZATION_SERVICE_STATE_UNCONFIGURED ||
                         frames_published_at_seed + answered >= frames_published;
    if (settled || Clock::now() >= give_up) return Status::Ok();
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
}

Status ServiceDriver::Impl::ConfigureLocalization(const geometry::SE3& T_world_body,
                                                  bool reset_if_configured) {
  // Keep what the localization counted so far (a reachable, configured one).
  v1::LocalizationStatus before;
  const bool configured = GetLocalizationStatus(&before).ok() &&
                          before.state() != v1::LOCALIZATION_SERVICE_STATE_UNCONFIGURED;
  if (configured) {
    vo_frames_before += before.frames_processed();
    vo_lost_before += before.frames_lost();
  }
  frames_published_at_seed = frames_published;
  if (reset_if_configured && configured) {
    // The running VO restarts at the pose and keeps its learnt gyro bias, as the in-process
    // driver's RigOdometry::Reset does; a restarted (unconfigured) service is configured anew.
    v1::LocalizationResetRequest reset;
    service_common::ToProto(T_world_body * T_vehicle_rig, reset.mutable_initial_pose());
    v1::LocalizationStatus status;
    return Unary("mav-localization", addresses.localization, "Reset",
                 [&](grpc::ClientContext* c) { return localization->Reset(c, reset, &status); });
  }
  v1::LocalizationConfigureRequest request;
  request.set_method(MethodToProto(options.vo_method));
  if (options.vo_method != localization::Method::kDense) {
    request.mutable_sparse()->set_gyro_rotation_sigma_rad(options.vehicle.vo_gyro_sigma_rad);
  }
  request.mutable_calibration()->set_simulator_address(addresses.simulator);
  service_common::ToProto(T_world_body * T_vehicle_rig, request.mutable_initial_pose());
  request.set_output_frame("body");
  // The vehicle's IMU in the rig's frame: the dense VO's gyro, as the in-process driver feeds it.
  service_common::ToProto(T_vehicle_rig.Inverse(), request.mutable_t_body_imu());
  v1::LocalizationStatus status;
  return Unary(
      "mav-localization", addresses.localization, "Configure",
      [&](grpc::ClientContext* c) { return localization->Configure(c, request, &status); });
}

Status ServiceDriver::Impl::WaitForDataPlane() {
  // DDS discovery: the simulator's first step waits for a controller itself; the camera's first
  // frame must find the localization's reader, and its pose mav-control's.
  const auto give_up = Clock::now() + std::chrono::seconds(10);
  while (true) {
    v1::FlightStatus status;
    v1::GetFlightStatusRequest request;
    MAV_RETURN_IF_ERROR(Unary(
        "mav-simulator", addresses.simulator, "GetFlightStatus",
        [&](grpc::ClientContext* c) { return simulator->GetFlightStatus(c, request, &status); }));
    const uint32_t stereo_readers = (vo() ? 1 : 0) + (options.online_map ? 1 : 0);
    if (status.actuator_writers() > 0 && status.stereo_subscribers() >= stereo_readers) break;
    if (Clock::now() > give_up) {
      return Status::Unavailable(
          "DDS: after 10 s mav-simulator sees " + std::to_string(status.actuator_writers()) +
          " actuator writers and " + std::to_string(status.stereo_subscribers()) +
          " stereo readers (mav-control and mav-localization on DDS domain " +
          std::to_string(status.dds_domain()) + "?)");
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  // The localization's pose writer and the controller's reader match in the same round.
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  return Status::Ok();
}

Result<std::unique_ptr<ServiceDriver>> ServiceDriver::Create(
    const dataset::MissionSpec& mission, const std::string& mission_yaml,
    const ServiceMissionOptions& options, const ServiceAddresses& addresses,
    const std::function<void(const std::string&)>& progress) {
  const auto setup_start = Clock::now();
  if (std::string why; !options.vehicle.IsValid(&why)) return Status::InvalidArgument(why);
  if (std::string why; !options.planning.IsValid(&why)) {
    return Status::InvalidArgument("planning." + why);
  }
  auto impl = std::make_unique<Impl>();
  Impl& s = *impl;
  s.mission = mission;
  s.options = options;
  s.addresses = addresses;
  s.progress = progress;
  // mavctl mission run checked the addresses (client::ParseTarget).
  s.simulator = v1::Simulator::NewStub(client::MakeCheckedChannel(addresses.simulator));
  s.control = v1::Control::NewStub(client::MakeCheckedChannel(addresses.control));
  s.planning = v1::Planning::NewStub(client::MakeCheckedChannel(addresses.planning));
  if (s.vo()) {
    s.localization = v1::Localization::NewStub(client::MakeCheckedChannel(addresses.localization));
  }
  if (options.online_map) {
    if (!s.vo()) {
      return Status::InvalidArgument(
          "online map: it is built from the VO's keyframes (pose source vo)");
    }
    s.mapping = v1::Mapping::NewStub(client::MakeCheckedChannel(addresses.mapping));
  }
  s.T_vehicle_rig = mission::VehicleRigMount(options.vehicle.camera_pitch_rad);
  s.recorder = std::make_unique<mission::FlightRecorder>(options.record_rate_hz);
  MAV_ASSIGN_OR_RETURN(mission::MissionWorld world, mission::MakeMissionWorld(mission, 0));
  s.plan_options = mission::MissionPlanningFor(mission, world.preset, options.planning,
                                               options.vehicle.seed, options.online_map);

  if (progress) progress("loading the mission flight into mav-simulator");
  v1::FlightStatus loaded;
  MAV_RETURN_IF_ERROR(s.LoadFlight(mission_yaml, &loaded));
  s.t_ns = loaded.t_ns();
  MAV_RETURN_IF_ERROR(s.SetUpPlanning(progress));
  if (progress) progress("configuring mav-control and mav-localization");
  MAV_RETURN_IF_ERROR(s.ConfigureControl());
  if (s.vo()) {
    MAV_ASSIGN_OR_RETURN(const geometry::SE3 T0,
                         service_common::PoseFromProto(loaded.truth().t_world_body(), "truth"));
    MAV_RETURN_IF_ERROR(s.ConfigureLocalization(T0));
  }
  if (options.online_map) MAV_RETURN_IF_ERROR(s.StartMapping());
  MAV_RETURN_IF_ERROR(s.WaitForDataPlane());
  s.figures.setup_s = MsSince(setup_start) / 1000;
  return std::unique_ptr<ServiceDriver>(new ServiceDriver(std::move(impl)));
}

Result<v1::FlightStatus> ServiceDriver::Impl::RunUntil(int64_t until_ns) {
  v1::FlightStatus status;
  v1::GetFlightStatusRequest get;
  if (until_ns > t_ns) {
    v1::StartFlightRequest start;
    start.set_run_until_s(NsToSeconds(until_ns));
    MAV_RETURN_IF_ERROR(
        Unary("mav-simulator", addresses.simulator, "StartFlight",
              [&](grpc::ClientContext* c) { return simulator->StartFlight(c, start, &status); }));
    running = true;
    while (status.state() == v1::FLIGHT_STATE_RUNNING) {
      std::this_thread::sleep_for(kPollPeriod);
      MAV_RETURN_IF_ERROR(Unary(
          "mav-simulator", addresses.simulator, "GetFlightStatus",
          [&](grpc::ClientContext* c) { return simulator->GetFlightStatus(c, get, &status); }));
    }
    running = false;
  } else {
    MAV_RETURN_IF_ERROR(
        Unary("mav-simulator", addresses.simulator, "GetFlightStatus",
              [&](grpc::ClientContext* c) { return simulator->GetFlightStatus(c, get, &status); }));
  }
  if (status.state() == v1::FLIGHT_STATE_FINISHED) {
    return Status::DeadlineExceeded("the simulation reached its 7200 s limit");
  }
  if (status.state() != v1::FLIGHT_STATE_PAUSED && status.state() != v1::FLIGHT_STATE_LOADED) {
    return Status::FailedPrecondition("mav-simulator: the flight is " +
                                      v1::FlightState_Name(status.state()) + " (" +
                                      status.last_error() + ")");
  }
  if (until_ns > t_ns && status.t_ns() < until_ns) {
    return Status::Unavailable("mav-simulator paused at " +
                               std::to_string(NsToSeconds(status.t_ns())) +
                               " s: " + status.pause_reason() + ": " + status.last_error());
  }
  t_ns = status.t_ns();
  return status;
}

Result<mission::VehicleView> ServiceDriver::Advance(double dt_s) {
  Impl& s = *impl_;
  const auto start = Clock::now();
  MAV_ASSIGN_OR_RETURN(const v1::FlightStatus flight, s.RunUntil(s.t_ns + SecondsToNs(dt_s)));
  if (s.mapping != nullptr && s.t_ns >= s.next_build_ns) {
    // The online map is rebuilt every map_rebuild_s while new keyframes come (the vehicle's
    // clock waits for the build, as in process).
    v1::MappingStatus mapping;
    v1::MappingGetStatusRequest get_mapping;
    const Status reached = s.Unary(
        "mav-mapping", s.addresses.mapping, "GetStatus",
        [&](grpc::ClientContext* c) { return s.mapping->GetStatus(c, get_mapping, &mapping); });
    s.figures.keyframes = reached.ok() ? mapping.keyframes() : s.figures.keyframes;
    if (reached.ok() && mapping.keyframes() > s.keyframes_at_build) {
      s.next_build_ns = s.t_ns + SecondsToNs(s.options.map_rebuild_s);
      if (const Status rebuilt = s.RebuildOnlineMap(); !rebuilt.ok()) {
        ++s.figures.map_errors;
        if (s.progress)
          s.progress("online map rebuild failed (the map stays): " + rebuilt.ToString());
      }
    }
  }
  v1::ControlState state;
  MAV_RETURN_IF_ERROR(s.GetControlState(&state));
  mission::VehicleView v;
  v.t_ns = flight.t_ns();
  v.armed = state.armed();
  const v1::VehicleEstimate& e = state.estimate();
  v.estimator_initialized = e.initialized();
  v.estimator_converged = e.converged();
  v.mode = ModeFromProto(state.mode());
  v.moving = state.moving();
  v.p_est = FromProto(e.t_world_body().position());
  v.v_est = FromProto(e.velocity());
  v.q_est = FromProto(e.t_world_body().orientation());
  const Eigen::Vector3d forward = v.q_est * Eigen::Vector3d::UnitX();
  v.yaw_est_rad = std::atan2(forward.y(), forward.x());
  v.pose_age_s = e.initialized() ? NsToSeconds(v.t_ns - e.last_pose_arrival_t_ns())
                                 : std::numeric_limits<double>::infinity();
  v.poses_rejected = e.poses_gated();
  v.collisions = flight.collisions_size();
  v.map_version = s.map_version;
  v.map_keyframes = s.figures.keyframes;
  const v1::GroundTruthState& truth = flight.truth();
  v.truth = mission::TrueState{FromProto(truth.t_world_body().position()),
                               FromProto(truth.t_world_body().orientation()),
                               FromProto(truth.velocity()), FromProto(truth.angular_velocity())};
  if (s.vo()) {
    // A restarted service is unconfigured: the mission seeds it; an unreachable one is down.
    s.frames_published = flight.frames_published();
    v1::LocalizationStatus loc;
    const Status reached = s.SettledLocalizationStatus(&loc);
    if (!reached.ok()) {
      v.localization_state = "down";
    } else if (loc.state() == v1::LOCALIZATION_SERVICE_STATE_UNCONFIGURED) {
      v.localization_state = "unseeded";
      v.localization_needs_seed = true;
    } else {
      v.localization_state = TrackingName(loc.tracking_state());
      // The last frame was lost: the localization starts its next track at the estimate (as
      // the in-process driver does at the end of its tick), not at its own last pose.
      if (loc.tracking_state() == v1::TRACKING_STATE_LOST && s.options.reseed_after_loss &&
          e.initialized()) {
        MAV_RETURN_IF_ERROR(SeedLocalization(geometry::SE3(v.q_est, v.p_est)));
      }
    }
  } else {
    v.localization_state = mission::PoseSourceName(s.options.vehicle.pose_source);
  }
  s.recorder->Offer(v);
  s.advance_ms.Add(MsSince(start));
  return v;
}

Status ServiceDriver::Arm() {
  Impl& s = *impl_;
  v1::ArmRequest request;
  v1::ControlStatus status;
  return s.Unary("mav-control", s.addresses.control, "Arm",
                 [&](grpc::ClientContext* c) { return s.control->Arm(c, request, &status); });
}

Status ServiceDriver::Disarm() {
  Impl& s = *impl_;
  v1::DisarmRequest request;
  v1::ControlStatus status;
  return s.Unary("mav-control", s.addresses.control, "Disarm",
                 [&](grpc::ClientContext* c) { return s.control->Disarm(c, request, &status); });
}

Status ServiceDriver::GoTo(const Eigen::Vector3d& position, double yaw_rad,
                           const control::GoToLimits& limits) {
  Impl& s = *impl_;
  v1::HoverRequest request;
  ToProto(position, request.mutable_position());
  request.set_yaw_rad(yaw_rad);
  v1::GoToLimits* l = request.mutable_limits();
  l->set_max_speed_mps(limits.max_speed_mps);
  l->set_max_accel_mps2(limits.max_accel_mps2);
  l->set_max_yaw_rate_radps(limits.max_yaw_rate_radps);
  l->set_min_duration_s(limits.min_duration_s);
  v1::ControlStatus status;
  return s.Unary("mav-control", s.addresses.control, "Hover",
                 [&](grpc::ClientContext* c) { return s.control->Hover(c, request, &status); });
}

Status ServiceDriver::Hold(const Eigen::Vector3d& position, double yaw_rad) {
  Impl& s = *impl_;
  v1::HoverRequest request;
  ToProto(position, request.mutable_position());
  request.set_yaw_rad(yaw_rad);
  request.set_immediate(true);
  v1::ControlStatus status;
  return s.Unary("mav-control", s.addresses.control, "Hover",
                 [&](grpc::ClientContext* c) { return s.control->Hover(c, request, &status); });
}

Status ServiceDriver::Follow(const geometry::PolynomialTrajectory& trajectory) {
  Impl& s = *impl_;
  v1::SetTrajectoryRequest request;
  control_service::ToProto(trajectory, request.mutable_trajectory());
  v1::ControlStatus status;
  return s.Unary("mav-control", s.addresses.control, "SetTrajectory", [&](grpc::ClientContext* c) {
    return s.control->SetTrajectory(c, request, &status);
  });
}

Result<mission::LegPlan> ServiceDriver::Plan(const Eigen::Vector3d& start,
                                             const Eigen::Vector3d& goal, double yaw_rad) {
  Impl& s = *impl_;
  const auto plan_start = Clock::now();
  v1::PlanPathRequest request;
  ToProto(start, request.mutable_start());
  ToProto(goal, request.mutable_goal());
  const planning::SpeedLimits& limits = s.plan_options.limits;
  v1::SpeedLimits* l = request.mutable_limits();
  l->set_max_speed_mps(limits.max_speed_mps);
  l->set_max_acceleration_mps2(limits.max_acceleration_mps2);
  l->set_max_lateral_acceleration_mps2(limits.max_lateral_acceleration_mps2);
  l->set_max_jerk_mps3(limits.max_jerk_mps3);
  request.set_seed(s.options.vehicle.seed);
  request.set_start_yaw_rad(yaw_rad);
  v1::PlanPathResponse response;
  Status called = s.EnsurePlannerMap();
  if (called.ok()) {
    called = s.Unary("mav-planning", s.addresses.planning, "PlanPath", [&](grpc::ClientContext* c) {
      return s.planning->PlanPath(c, request, &response);
    });
  }
  s.plan_ms.Add(MsSince(plan_start));
  ++s.figures.plans;
  if (!called.ok()) {
    ++s.figures.plans_failed;
    return called;
  }
  if (response.status() != v1::PLAN_STATUS_SUCCESS) {
    ++s.figures.plans_failed;
    std::string name = v1::PlanStatus_Name(response.status());
    if (name.rfind("PLAN_STATUS_", 0) == 0) name = name.substr(12);
    return Status::FailedPrecondition(name + ": " + response.message());
  }
  mission::LegPlan leg;
  MAV_ASSIGN_OR_RETURN(leg.trajectory,
                       control_service::TrajectoryFromProto(response.trajectory(), "trajectory"));
  for (const v1::Vector3& p : response.shortened_path()) leg.path.push_back(FromProto(p));
  leg.length_m = response.trajectory_length_m();
  leg.duration_s = response.duration_s();
  return leg;
}

Status ServiceDriver::CheckPoint(const Eigen::Vector3d& p) {
  return mission::CheckPointInMap(*impl_->map, p, impl_->figures.map_description);
}

Result<Eigen::Vector3d> ServiceDriver::LandingSpot(const Eigen::Vector3d& above) {
  return mission::LandingSpotInMap(*impl_->map, above, impl_->mission.start.z());
}

Status ServiceDriver::SeedLocalization(const geometry::SE3& T_world_body) {
  Impl& s = *impl_;
  if (!s.vo()) return Status::FailedPrecondition("the pose source is not the VO");
  // The estimator may have corrected the VO's frame (ControlPoseSource.align_tilt_s): the VO
  // restarts in its own frame, where the estimator's correction still applies.
  v1::ControlState state;
  MAV_RETURN_IF_ERROR(s.GetControlState(&state));
  geometry::SE3 frame;
  if (state.estimate().source_frames_size() > 0) {
    MAV_ASSIGN_OR_RETURN(frame, service_common::PoseFromProto(state.estimate().source_frames(0),
                                                              "estimate.source_frames[0]"));
  }
  return s.ConfigureLocalization(frame.Inverse() * T_world_body, /*reset_if_configured=*/true);
}

const std::vector<mission::FlightSample>& ServiceDriver::record() const {
  return impl_->recorder->samples();
}

const planning::PlanningMap& ServiceDriver::planning_map() const { return *impl_->map; }
const std::string& ServiceDriver::map_bt() const { return impl_->map_bt; }

void ServiceDriver::Stop() {
  Impl& s = *impl_;
  if (!s.running) return;
  v1::PauseFlightRequest request;
  v1::FlightStatus status;
  (void)s.Unary("mav-simulator", s.addresses.simulator, "PauseFlight", [&](grpc::ClientContext* c) {
    return s.simulator->PauseFlight(c, request, &status);
  });
  s.running = false;
}

Result<ServiceFigures> ServiceDriver::Figures() {
  Impl& s = *impl_;
  ServiceFigures f = s.figures;
  f.plan_ms = s.plan_ms.Summary();
  f.advance_ms = s.advance_ms.Summary();
  f.map_rebuilds = s.map_version;
  f.map_build_ms = s.map_build_ms.Summary();
  if (s.mapping != nullptr) {
    // The planner's last map against the world's exact occupancy, unknown as the planner takes
    // it (free), over the volume the camera could observe from its true poses along the flight
    // (every 10th record sample: 0.5 s apart; the services do not report their keyframes).
    MAV_ASSIGN_OR_RETURN(const camera::RigRectification rectification,
                         camera::RigRectification::Create(camera::EurocStereoCalibration(),
                                                          /*calibration_rectified=*/false));
    std::vector<geometry::SE3> views;
    const std::vector<mission::FlightSample>& record = s.recorder->samples();
    for (size_t i = 0; i < record.size(); i += 10) {
      views.push_back(geometry::SE3(record[i].q_true, record[i].p_true) * s.T_vehicle_rig *
                      rectification.T_body_rect0);
    }
    std::vector<uint8_t> observable;
    mapping::CollisionEvalOptions eval_options;
    eval_options.computed_unknown_is_occupied = false;
    if (!views.empty()) {
      MAV_ASSIGN_OR_RETURN(observable,
                           mapping::ObservableVoxels(s.truth_grid, views, rectification.rig));
      eval_options.observable = &observable;
    }
    MAV_ASSIGN_OR_RETURN(const mapping::CollisionOutcomes outcomes,
                         mapping::EvaluateCollisions(s.truth_grid, s.planning_grid, eval_options));
    mission::MapQuality q;
    q.mcc = outcomes.Mcc();
    q.missed_percent = outcomes.Percent(outcomes.missed_collision);
    q.false_percent = outcomes.Percent(outcomes.false_collision);
    q.positions = outcomes.total();
    q.observable_only = !views.empty();
    f.map_quality = q;
  }
  v1::FlightStatus flight;
  v1::GetFlightStatusRequest get_flight;
  MAV_RETURN_IF_ERROR(s.Unary("mav-simulator", s.addresses.simulator, "GetFlightStatus",
                              [&](grpc::ClientContext* c) {
                                return s.simulator->GetFlightStatus(c, get_flight, &flight);
                              }));
  f.collisions = flight.collisions_size();
  for (const v1::FlightCollision& c : flight.collisions()) {
    std::ostringstream d;
    d << "t=" << c.t_s() << " s at (" << FromProto(c.position()).transpose() << "): " << c.what();
    f.collision_descriptions.push_back(d.str());
  }
  f.frames_published = flight.frames_published();
  f.render_ms = StatsFromProto(flight.render_ms());
  v1::ControlStatus control;
  v1::ControlGetStatusRequest get_control;
  MAV_RETURN_IF_ERROR(s.Unary(
      "mav-control", s.addresses.control, "GetStatus",
      [&](grpc::ClientContext* c) { return s.control->GetStatus(c, get_control, &control); }));
  f.poses_merged = control.poses();
  f.lockstep_frames_missed = control.lockstep_frames_missed();
  const v1::PoseLatency& latency = control.pose_latency();
  f.pose_latency = {StatsFromProto(latency.total()), StatsFromProto(latency.frame_transport()),
                    StatsFromProto(latency.localization()),
                    StatsFromProto(latency.pose_transport()), StatsFromProto(latency.merge())};
  v1::ControlState state;
  MAV_RETURN_IF_ERROR(s.GetControlState(&state));
  f.poses_gated = state.estimate().poses_gated();
  if (s.vo()) {
    v1::LocalizationStatus loc;
    // A localization that is down at the end leaves its figures at 0.
    if (s.GetLocalizationStatus(&loc).ok()) {
      f.vo_frames = s.vo_frames_before + loc.frames_processed();
      f.vo_lost = s.vo_lost_before + loc.frames_lost();
      f.vo_ms = StatsFromProto(loc.processing_ms());
    }
  }
  return f;
}

}  // namespace mav::mavctl
