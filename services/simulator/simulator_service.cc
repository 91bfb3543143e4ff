#include "services/simulator/simulator_service.h"

#include <algorithm>
#include <cmath>

#include "mav/common/log.h"
#include "services/common/file_stream.h"
#include "services/common/grpc_status.h"
#include "services/simulator/convert.h"

namespace mav::simulator_service {

namespace {

using service_common::CallTermination;
using service_common::CheckDeadline;
using service_common::ChunkSize;
using service_common::OccupancyFormatFromProto;
using service_common::StreamOccupancy;
using service_common::ToGrpcStatus;

constexpr double kDefaultResolutionM = 0.05;

}  // namespace

bool SimulatorServiceOptions::IsValid(std::string* why) const {
  if (max_occupancy_memory_mb <= 0) {
    if (why != nullptr) *why = "max_occupancy_memory_mb: must be > 0";
    return false;
  }
  return true;
}

SimulatorService::SimulatorService(StreamSink* sink, SimulatorServiceOptions options)
    : options_(options), player_(sink) {}

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
  if (Status s = player_.Load(shared, CallTermination(*context)); !s.ok()) return ToGrpcStatus(s);
  ToProto(shared->info(), response->mutable_scenario());
  return grpc::Status::OK;
}

grpc::Status SimulatorService::Start(grpc::ServerContext* context,
                                     const v1::SimulatorStartRequest* request,
                                     v1::SimulatorStatus* response) {
  Result<Pacing> pacing = FromProto(*request);
  if (!pacing.ok()) return ToGrpcStatus(pacing.status());
  if (Status s = CheckDeadline(*context, "Start"); !s.ok()) return ToGrpcStatus(s);
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
  Result<PlayerStatus> status = player_.Step(request->frames(), CallTermination(*context));
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
  std::shared_ptr<const ScenarioSource> source = player_.source();
  if (source == nullptr) {
    return ToGrpcStatus(Status::FailedPrecondition("no scenario loaded: call LoadScenario first"));
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
  std::shared_ptr<const ScenarioSource> source = player_.source();
  if (source == nullptr) {
    return ToGrpcStatus(Status::FailedPrecondition("no scenario loaded: call LoadScenario first"));
  }
  const sim::ScenarioInfo& info = source->info();
  double resolution = request->resolution_m();
  if (resolution == 0.0) {
    resolution =
        info.occupancy_resolution_m > 0 ? info.occupancy_resolution_m : kDefaultResolutionM;
  }
  if (!std::isfinite(resolution) || resolution < 0.01 || resolution > 2.0) {
    return ToGrpcStatus(Status::InvalidArgument("resolution_m: must be in [0.01, 2] m, got " +
                                                std::to_string(request->resolution_m())));
  }
  Result<uint32_t> chunk_bytes = ChunkSize(request->chunk_size());
  if (!chunk_bytes.ok()) return ToGrpcStatus(chunk_bytes.status());
  Result<v1::OccupancyFormat> format = OccupancyFormatFromProto(request->format());
  if (!format.ok()) return ToGrpcStatus(format.status());
  if (!info.has_ground_truth_occupancy) {
    return ToGrpcStatus(Status::NotFound("no ground-truth occupancy for " + info.name +
                                         " (a preset, or a data set written by mav-sim generate "
                                         "with ground_truth/occupancy.mavocc)"));
  }
  Result<dataset::GridGeometry> geometry = source->OccupancyGeometry(resolution);
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
  Result<dataset::OccupancyGrid> grid = source->Occupancy(resolution, CallTermination(*context));
  if (!grid.ok()) return ToGrpcStatus(grid.status());
  if (Status s = CheckDeadline(*context, "GetGroundTruthOccupancy"); !s.ok()) {
    return ToGrpcStatus(s);
  }
  return StreamOccupancy(context, *grid, *format, *chunk_bytes, writer);
}

}  // namespace mav::simulator_service
