#include "services/simulator/simulator_service.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <thread>

#include "mav/camera/stereo.h"
#include "mav/common/log.h"
#include "mav/dataset/flight_task_io.h"
#include "mav/sim/flight_task.h"
#include "mav/sim/occupancy.h"
#include "services/common/call_watch.h"
#include "services/common/file_stream.h"
#include "services/common/grpc_status.h"
#include "services/simulator/convert.h"

namespace mav::simulator_service {

namespace {

using service_common::CallWatch;
using service_common::CheckDeadline;
using service_common::ChunkSize;
using service_common::OccupancyFormatFromProto;
using service_common::StreamOccupancy;
using service_common::ToGrpcStatus;

constexpr double kDefaultResolutionM = 0.05;
// The base of a task file without `base:`.
constexpr char kDefaultTaskBase[] = "t3_1";

// The flight mode without a data plane: publishes nowhere, receives nothing.
class NullFlightIo : public FlightIo {
 public:
  Status PublishFlightImu(uint64_t, const dataset::ImuSample&) override { return Status::Ok(); }
  Status PublishFlightPose(uint64_t, const sim::PoseSample&, const std::string&, double,
                           double) override {
    return Status::Ok();
  }
  Status PublishFlightGroundTruth(uint64_t, const dataset::GroundTruthState&) override {
    return Status::Ok();
  }
  Status PublishFlightStereo(const sim::RenderedFrame&) override { return Status::Ok(); }
  uint32_t StereoReaders() override { return 0; }
  void DiscardCommands() override {}
  std::optional<ActuatorInput> WaitForCommand(int64_t, int64_t, int64_t timeout_ns,
                                              uint64_t*) override {
    // Nothing ever arrives; sleep like a reader would, so a lock-step wait still times out.
    if (timeout_ns > 0) std::this_thread::sleep_for(std::chrono::nanoseconds(timeout_ns));
    return std::nullopt;
  }
  uint32_t ActuatorWriters() override { return 0; }
  uint32_t ImuReaders() override { return 0; }
  uint32_t domain() const override { return 0; }
};

}  // namespace

bool SimulatorServiceOptions::IsValid(std::string* why) const {
  if (max_occupancy_memory_mb <= 0) {
    if (why != nullptr) *why = "max_occupancy_memory_mb: must be > 0";
    return false;
  }
  return true;
}

SimulatorService::SimulatorService(StreamSink* sink, SimulatorServiceOptions options,
                                   FlightIo* flight_io)
    : options_(std::move(options)), player_(sink, options_.render_priority) {
  if (flight_io == nullptr) {
    null_flight_io_ = std::make_unique<NullFlightIo>();
    flight_io = null_flight_io_.get();
  }
  flight_ = std::make_unique<Flight>(flight_io);
}

void SimulatorService::Shutdown() {
  flight_->Shutdown();
  player_.Shutdown();
}

grpc::Status SimulatorService::LoadScenario(grpc::ServerContext* context,
                                            const v1::LoadScenarioRequest* request,
                                            v1::LoadScenarioResponse* response) {
  Result<LoadRequest> load = FromProto(*request);
  if (!load.ok()) return ToGrpcStatus(load.status());
  Result<std::unique_ptr<ScenarioSource>> source =
      load->is_preset ? sim::OpenPreset(load->preset) : sim::OpenEuroc(load->euroc_directory);
  if (!source.ok()) {
    MAV_LOG(kWarning) << "LoadScenario: " << source.status().ToString();
    return ToGrpcStatus(source.status());
  }
  // Opening a preset takes a while: a client that gave up meanwhile must not replace the scenario.
  if (Status s = CheckDeadline(*context, "LoadScenario"); !s.ok()) return ToGrpcStatus(s);
  std::shared_ptr<const ScenarioSource> shared = std::move(*source);
  if (Status s = player_.Load(shared, CallWatch(context).termination()); !s.ok())
    return ToGrpcStatus(s);
  set_mission_scene(nullptr);  // GetCalibration / GetGroundTruthOccupancy answer for the scenario
  ToProto(shared->info(), response->mutable_scenario());
  return grpc::Status::OK;
}

grpc::Status SimulatorService::Start(grpc::ServerContext* context,
                                     const v1::SimulatorStartRequest* request,
                                     v1::SimulatorStatus* response) {
  Result<Pacing> pacing = FromProto(*request);
  if (!pacing.ok()) return ToGrpcStatus(pacing.status());
  if (Status s = CheckDeadline(*context, "Start"); !s.ok()) return ToGrpcStatus(s);
  if (flight_->running()) (void)flight_->Pause("the replay was started (Start)");
  Result<PlayerStatus> status = player_.Start(*pacing);
  if (!status.ok()) return ToGrpcStatus(status.status());
  ToProto(*status, response);
  return grpc::Status::OK;
}

grpc::Status SimulatorService::Pause(grpc::ServerContext* context, const v1::SimulatorPauseRequest*,
                                     v1::SimulatorStatus* response) {
  if (Status s = CheckDeadline(*context, "Pause"); !s.ok()) return ToGrpcStatus(s);
  Result<PlayerStatus> status = player_.Pause();
  if (!status.ok()) return ToGrpcStatus(status.status());
  ToProto(*status, response);
  return grpc::Status::OK;
}

grpc::Status SimulatorService::Step(grpc::ServerContext* context,
                                    const v1::SimulatorStepRequest* request,
                                    v1::SimulatorStatus* response) {
  // The state is checked first so that Step(0) with nothing loaded reports the missing scenario.
  if (player_.GetStatus().state == PlayerState::kIdle) {
    return ToGrpcStatus(Status::FailedPrecondition("no scenario loaded: call LoadScenario first"));
  }
  if (request->frames() == 0) {
    return ToGrpcStatus(Status::InvalidArgument("frames: must be >= 1, got 0"));
  }
  if (Status s = CheckDeadline(*context, "Step"); !s.ok()) return ToGrpcStatus(s);
  Result<PlayerStatus> status = player_.Step(request->frames(), CallWatch(context).termination());
  if (!status.ok()) return ToGrpcStatus(status.status());
  ToProto(*status, response);
  return grpc::Status::OK;
}

grpc::Status SimulatorService::GetStatus(grpc::ServerContext*, const v1::SimulatorGetStatusRequest*,
                                         v1::SimulatorStatus* response) {
  ToProto(player_.GetStatus(), response);
  return grpc::Status::OK;
}

grpc::Status SimulatorService::GetCalibration(grpc::ServerContext*,
                                              const v1::GetCalibrationRequest*,
                                              v1::GetCalibrationResponse* response) {
  if (std::shared_ptr<const MissionScene> mission = mission_scene(); mission != nullptr) {
    // The mission's camera: the EuRoC raw rig on the vehicle; its IMU is the vehicle's.
    const mission::VehicleOptions& v = mission->vehicle;
    const dataset::FlightImuSpec imu = mission::MissionFlightTask({}, v).imu;
    dataset::ImuNoise noise;
    noise.gyroscope_noise_density = imu.gyro_noise_sigma / std::sqrt(imu.rate_hz);
    noise.accelerometer_noise_density = imu.accel_noise_sigma / std::sqrt(imu.rate_hz);
    noise.gyroscope_random_walk = imu.gyro_drift_sigma / std::sqrt(imu.drift_horizon_s);
    noise.accelerometer_random_walk = imu.accel_drift_sigma / std::sqrt(imu.drift_horizon_s);
    ToProto(camera::EurocStereoCalibration(), v.camera_rate_hz, /*rectified=*/false,
            response->mutable_stereo());
    ToProto(noise, v.imu_rate_hz, response->mutable_imu());
    ToProto(mission::VehicleRigMount(v.camera_pitch_rad).Inverse(), response->mutable_t_body_imu());
    return grpc::Status::OK;
  }
  std::shared_ptr<const ScenarioSource> source = player_.source();
  if (source == nullptr) {
    return ToGrpcStatus(Status::FailedPrecondition(
        "no scenario or mission flight loaded: call LoadScenario or LoadFlightTask first"));
  }
  const ScenarioInfo& info = source->info();
  ToProto(source->calibration(), info.camera_rate_hz, info.rectified, response->mutable_stereo());
  ToProto(source->imu_noise(), info.imu_rate_hz, response->mutable_imu());
  ToProto(geometry::SE3::Identity(), response->mutable_t_body_imu());
  return grpc::Status::OK;
}

grpc::Status SimulatorService::GetGroundTruthOccupancy(
    grpc::ServerContext* context, const v1::GetGroundTruthOccupancyRequest* request,
    grpc::ServerWriter<v1::OccupancyChunk>* writer) {
  // The loaded mission flight's world, else the scenario's.
  std::shared_ptr<const MissionScene> mission = mission_scene();
  std::shared_ptr<const ScenarioSource> source = player_.source();
  if (mission == nullptr && source == nullptr) {
    return ToGrpcStatus(Status::FailedPrecondition(
        "no scenario or mission flight loaded: call LoadScenario or LoadFlightTask first"));
  }
  std::optional<sim::ScenarioInfo> info;
  if (mission == nullptr) info = source->info();
  double resolution = request->resolution_m();
  if (resolution == 0.0) {
    resolution = info && info->occupancy_resolution_m > 0 ? info->occupancy_resolution_m
                                                          : kDefaultResolutionM;
  }
  if (!std::isfinite(resolution) || resolution < 0.01 || resolution > 2.0) {
    return ToGrpcStatus(Status::InvalidArgument("resolution_m: must be in [0.01, 2] m, got " +
                                                std::to_string(request->resolution_m())));
  }
  Result<uint32_t> chunk_bytes = ChunkSize(request->chunk_size());
  if (!chunk_bytes.ok()) return ToGrpcStatus(chunk_bytes.status());
  Result<v1::OccupancyFormat> format = OccupancyFormatFromProto(request->format());
  if (!format.ok()) return ToGrpcStatus(format.status());
  if (info && !info->has_ground_truth_occupancy) {
    return ToGrpcStatus(Status::NotFound("no ground-truth occupancy for " + info->name +
                                         " (a preset, or a data set written by mav-sim generate "
                                         "with ground_truth/occupancy.mavocc)"));
  }
  Result<dataset::GridGeometry> geometry =
      mission ? sim::OccupancyGeometry(*mission->preset.world, resolution)
              : source->OccupancyGeometry(resolution);
  if (!geometry.ok()) return ToGrpcStatus(geometry.status());

  // Refuse before allocating: the grid, and for a .bt answer OctoMap's tree of every known voxel.
  const double voxels = static_cast<double>(geometry->num_voxels());
  const double per_voxel = *format == v1::OCCUPANCY_FORMAT_OCTOMAP_BT
                               ? 1.0 + SimulatorServiceOptions::kOctomapBytesPerVoxel
                               : 1.0;
  const double need = voxels * per_voxel;
  const double limit = static_cast<double>(options_.max_occupancy_memory_mb) * 1024 * 1024;
  {
    std::lock_guard<std::mutex> lock(occupancy_mutex_);
    if (need + static_cast<double>(occupancy_reserved_bytes_) > limit) {
      return ToGrpcStatus(Status::ResourceExhausted(
          "resolution_m: " + std::to_string(resolution) + " m gives " +
          std::to_string(geometry->num_voxels()) + " voxels, ~" +
          std::to_string(static_cast<int64_t>(need / (1024 * 1024))) + " MiB to answer in " +
          v1::OccupancyFormat_Name(*format) + "; the server allows " +
          std::to_string(options_.max_occupancy_memory_mb) + " MiB (" +
          std::to_string(occupancy_reserved_bytes_ / (1024 * 1024)) +
          " MiB in use by other calls): choose a coarser resolution or OCCUPANCY_FORMAT_MAVOCC"));
    }
    occupancy_reserved_bytes_ += static_cast<int64_t>(need);
  }
  struct Release {
    SimulatorService* self;
    int64_t bytes;
    ~Release() {
      std::lock_guard<std::mutex> lock(self->occupancy_mutex_);
      self->occupancy_reserved_bytes_ -= bytes;
    }
  } release{this, static_cast<int64_t>(need)};
  Result<dataset::OccupancyGrid> grid =
      mission ? sim::ComputeOccupancy(*mission->preset.world, resolution,
                                      CallWatch(context).termination())
              : source->Occupancy(resolution, CallWatch(context).termination());
  if (!grid.ok()) return ToGrpcStatus(grid.status());
  if (Status s = CheckDeadline(*context, "GetGroundTruthOccupancy"); !s.ok()) {
    return ToGrpcStatus(s);
  }
  return StreamOccupancy(context, *grid, *format, *chunk_bytes, writer);
}

// ---- Flight mode ------------------------------------------------------------------------------

Result<dataset::FlightTask> SimulatorService::ResolveFlightTask(
    const FlightLoadRequest& load) const {
  const std::string plant_map = options_.plant_map_path;
  const dataset::FlightTaskResolver resolve = [plant_map](const std::string& name) {
    return sim::BuiltinFlightTask(name, plant_map);
  };
  Result<dataset::FlightTask> task = Status::Internal("unresolved");
  switch (load.source) {
    case FlightLoadRequest::Source::kBuiltin:
      task = resolve(load.value);
      // An unknown name is a bad request, not a missing resource.
      if (!task.ok()) return Status::InvalidArgument("builtin: " + task.status().message());
      break;
    case FlightLoadRequest::Source::kYaml:
      task = dataset::ParseFlightTaskYaml(load.value, "yaml", resolve, kDefaultTaskBase);
      if (!task.ok()) return task.status();  // "yaml: <key>: ..."
      break;
    case FlightLoadRequest::Source::kPath:
      task = dataset::ReadFlightTaskFile(load.value, resolve, kDefaultTaskBase);
      if (!task.ok()) {
        if (task.status().code() == StatusCode::kInvalidArgument) {
          return Status::InvalidArgument("path: " + task.status().message());
        }
        return task.status();
      }
      break;
    case FlightLoadRequest::Source::kMission:
      task = load.config.task;  // MissionFlightTask's, built by FromProto
      break;
  }
  if (!load.map_path.empty()) task->map_path = load.map_path;
  return task;
}

Result<std::shared_ptr<const sim::CollisionWorld>> SimulatorService::WorldFor(
    const std::string& map_path) {
  if (map_path.empty()) return std::shared_ptr<const sim::CollisionWorld>();
  std::lock_guard<std::mutex> lock(world_mutex_);
  if (world_ != nullptr && world_path_ == map_path) return world_;
  Result<std::unique_ptr<sim::CollisionWorld>> loaded = sim::LoadOctomapCollisionWorld(map_path);
  if (!loaded.ok()) return loaded.status().WithContext("map " + map_path);
  world_ = std::shared_ptr<const sim::CollisionWorld>(std::move(*loaded));
  world_path_ = map_path;
  return world_;
}

std::shared_ptr<const MissionScene> SimulatorService::mission_scene() const {
  std::lock_guard<std::mutex> lock(mission_mutex_);
  return mission_;
}

void SimulatorService::set_mission_scene(std::shared_ptr<const MissionScene> scene) {
  std::lock_guard<std::mutex> lock(mission_mutex_);
  mission_ = std::move(scene);
}

grpc::Status SimulatorService::ApplyLoadFlightTask(const v1::LoadFlightTaskRequest& request,
                                                   const Termination& deadline,
                                                   v1::FlightStatus* response) {
  Result<FlightLoadRequest> load = FromProto(request);
  if (!load.ok()) return ToGrpcStatus(load.status());
  Result<dataset::FlightTask> task = ResolveFlightTask(*load);
  if (!task.ok()) {
    MAV_LOG(kWarning) << "LoadFlightTask: " << task.status().ToString();
    return ToGrpcStatus(task.status());
  }
  load->config.task = std::move(*task);
  if (load->source == FlightLoadRequest::Source::kMission) {
    Result<mission::MissionWorld> world =
        mission::MakeMissionWorld(load->mission, load->config.seed);
    if (!world.ok()) return ToGrpcStatus(world.status());
    auto scene = std::make_shared<MissionScene>();
    scene->preset = std::move(world->preset);
    scene->vehicle = load->vehicle;
    if (Status s = flight_->Load(load->config, world->collision, deadline, scene); !s.ok()) {
      return ToGrpcStatus(s);
    }
    set_mission_scene(std::move(scene));
    ToProto(flight_->GetStatus(), response);
    return grpc::Status::OK;
  }
  Result<std::shared_ptr<const sim::CollisionWorld>> world = WorldFor(load->config.task.map_path);
  if (!world.ok()) return ToGrpcStatus(world.status());
  if (Status s = flight_->Load(load->config, *world, deadline); !s.ok()) return ToGrpcStatus(s);
  set_mission_scene(nullptr);
  ToProto(flight_->GetStatus(), response);
  return grpc::Status::OK;
}

grpc::Status SimulatorService::LoadFlightTask(grpc::ServerContext* context,
                                              const v1::LoadFlightTaskRequest* request,
                                              v1::FlightStatus* response) {
  if (Status s = CheckDeadline(*context, "LoadFlightTask"); !s.ok()) return ToGrpcStatus(s);
  return ApplyLoadFlightTask(*request, CallWatch(context).termination(), response);
}

grpc::Status SimulatorService::StartFlight(grpc::ServerContext* context,
                                           const v1::StartFlightRequest* request,
                                           v1::FlightStatus* response) {
  Result<FlightRun> run = FromProto(*request);
  if (!run.ok()) return ToGrpcStatus(run.status());
  if (Status s = CheckDeadline(*context, "StartFlight"); !s.ok()) return ToGrpcStatus(s);
  if (player_.GetStatus().state == PlayerState::kRunning) (void)player_.Pause();
  Result<FlightStatus> status = flight_->Start(*run);
  if (!status.ok()) return ToGrpcStatus(status.status());
  ToProto(*status, response);
  return grpc::Status::OK;
}

grpc::Status SimulatorService::PauseFlight(grpc::ServerContext* context,
                                           const v1::PauseFlightRequest*,
                                           v1::FlightStatus* response) {
  if (Status s = CheckDeadline(*context, "PauseFlight"); !s.ok()) return ToGrpcStatus(s);
  Result<FlightStatus> status = flight_->Pause();
  if (!status.ok()) return ToGrpcStatus(status.status());
  ToProto(*status, response);
  return grpc::Status::OK;
}

grpc::Status SimulatorService::GetFlightStatus(grpc::ServerContext*,
                                               const v1::GetFlightStatusRequest*,
                                               v1::FlightStatus* response) {
  ToProto(flight_->GetStatus(), response);
  return grpc::Status::OK;
}

}  // namespace mav::simulator_service
