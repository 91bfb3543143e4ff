#include "services/simulator/simulator_service.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include "mav/common/file.h"
#include "mav/common/log.h"
#include "mav/dataset/occupancy_io.h"
#include "mav/sim/occupancy.h"
#include "mav/transport/grpc_server.h"
#include "services/simulator/convert.h"
#include "services/common/grpc_status.h"

namespace mav::simulator_service {

namespace {

using service_common::ToGrpcStatus;

constexpr double kDefaultResolutionM = 0.05;
constexpr uint32_t kDefaultChunkBytes = 1 << 20;
constexpr uint32_t kMinChunkBytes = 4096;
constexpr uint32_t kMaxChunkBytes = 4 << 20;

// A temporary file path that is removed when the guard goes out of scope.
class TempFile {
 public:
  explicit TempFile(const std::string& suffix) {
    std::string pattern =
        (std::filesystem::temp_directory_path() / ("mav-occupancy-XXXXXX" + suffix)).string();
    const int fd = mkstemps(pattern.data(), static_cast<int>(suffix.size()));
    if (fd >= 0) {
      close(fd);
      path_ = pattern;
    }
  }
  ~TempFile() {
    if (!path_.empty()) std::remove(path_.c_str());
  }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

}  // namespace

bool SimulatorServiceOptions::IsValid(std::string* why) const {
  if (max_occupancy_voxels <= 0) {
    if (why != nullptr) *why = "max_occupancy_voxels: must be > 0";
    return false;
  }
  return true;
}

SimulatorService::SimulatorService(StreamSink* sink, SimulatorServiceOptions options)
    : options_(options), player_(sink) {}

grpc::Status SimulatorService::LoadScenario(grpc::ServerContext*,
                                            const v1::LoadScenarioRequest* request,
                                            v1::LoadScenarioResponse* response) {
  Result<LoadRequest> load = FromProto(*request);
  if (!load.ok()) return ToGrpcStatus(load.status());
  Result<std::unique_ptr<ScenarioSource>> source =
      load->is_preset ? OpenPreset(load->preset) : OpenEuroc(load->euroc_directory);
  if (!source.ok()) {
    MAV_LOG(kWarning) << "LoadScenario: " << source.status().ToString();
    return ToGrpcStatus(source.status());
  }
  std::shared_ptr<const ScenarioSource> shared = std::move(*source);
  player_.Load(shared);
  ToProto(shared->info(), response->mutable_scenario());
  return grpc::Status::OK;
}

grpc::Status SimulatorService::Start(grpc::ServerContext*, const v1::SimulatorStartRequest* request,
                                     v1::SimulatorStatus* response) {
  Result<Pacing> pacing = FromProto(*request);
  if (!pacing.ok()) return ToGrpcStatus(pacing.status());
  Result<PlayerStatus> status = player_.Start(*pacing);
  if (!status.ok()) return ToGrpcStatus(status.status());
  ToProto(*status, response);
  return grpc::Status::OK;
}

grpc::Status SimulatorService::Pause(grpc::ServerContext*, const v1::SimulatorPauseRequest*,
                                     v1::SimulatorStatus* response) {
  Result<PlayerStatus> status = player_.Pause();
  if (!status.ok()) return ToGrpcStatus(status.status());
  ToProto(*status, response);
  return grpc::Status::OK;
}

grpc::Status SimulatorService::Step(grpc::ServerContext*, const v1::SimulatorStepRequest* request,
                                    v1::SimulatorStatus* response) {
  // The state is checked first so that Step(0) with nothing loaded reports the missing scenario.
  if (player_.GetStatus().state == PlayerState::kIdle) {
    return ToGrpcStatus(Status::FailedPrecondition("no scenario loaded: call LoadScenario first"));
  }
  if (request->frames() == 0) {
    return ToGrpcStatus(Status::InvalidArgument("frames: must be >= 1, got 0"));
  }
  Result<PlayerStatus> status = player_.Step(request->frames());
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
  const double resolution =
      request->resolution_m() == 0.0 ? kDefaultResolutionM : request->resolution_m();
  if (!std::isfinite(resolution) || resolution < 0.01 || resolution > 2.0) {
    return ToGrpcStatus(Status::InvalidArgument("resolution_m: must be in [0.01, 2] m, got " +
                                                std::to_string(request->resolution_m())));
  }
  const uint32_t chunk_bytes =
      request->chunk_size() == 0 ? kDefaultChunkBytes : request->chunk_size();
  if (chunk_bytes < kMinChunkBytes || chunk_bytes > kMaxChunkBytes) {
    return ToGrpcStatus(
        Status::InvalidArgument("chunk_size: must be in [4096, 4194304] bytes, got " +
                                std::to_string(request->chunk_size())));
  }
  v1::OccupancyFormat format = request->format();
  if (format == v1::OCCUPANCY_FORMAT_UNSPECIFIED) format = v1::OCCUPANCY_FORMAT_OCTOMAP_BT;
  if (format != v1::OCCUPANCY_FORMAT_OCTOMAP_BT && format != v1::OCCUPANCY_FORMAT_MAVOCC) {
    return ToGrpcStatus(Status::InvalidArgument("format: unknown value " +
                                                std::to_string(static_cast<int>(format))));
  }
  if (!source->info().has_ground_truth_occupancy) {
    return ToGrpcStatus(Status::NotFound("no ground-truth occupancy for " + source->info().name +
                                         " (only rendered presets have one)"));
  }
  const int64_t voxels = source->EstimateVoxels(resolution);
  if (voxels > options_.max_occupancy_voxels) {
    return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                        "resolution_m: " + std::to_string(resolution) + " m gives ~" +
                            std::to_string(voxels) + " voxels, over the server's limit of " +
                            std::to_string(options_.max_occupancy_voxels));
  }
  Result<dataset::OccupancyGrid> grid = source->Occupancy(resolution);
  if (!grid.ok()) return ToGrpcStatus(grid.status());

  Result<std::string> bytes = format == v1::OCCUPANCY_FORMAT_OCTOMAP_BT
                                  ? dataset::EncodeOctomapBt(*grid)
                                  : dataset::EncodeMavocc(*grid);
  if (!bytes.ok()) return ToGrpcStatus(bytes.status());

  const Eigen::Vector3d min = grid->origin();
  const Eigen::Vector3d max = min + grid->size().cast<double>() * grid->resolution();
  const uint64_t total = bytes->size();
  uint64_t offset = 0;
  do {
    if (context->IsCancelled()) return grpc::Status(grpc::StatusCode::CANCELLED, "cancelled");
    const uint64_t n = std::min<uint64_t>(chunk_bytes, total - offset);
    v1::OccupancyChunk chunk;
    chunk.mutable_chunk()->set_offset(offset);
    chunk.mutable_chunk()->set_total_size(total);
    chunk.mutable_chunk()->set_data(bytes->substr(offset, n));
    chunk.mutable_chunk()->set_last(offset + n == total);
    if (offset == 0) {
      chunk.set_format(format);
      chunk.set_resolution_m(grid->resolution());
      v1::Box* box = chunk.mutable_bounds();
      box->mutable_min()->set_x(min.x());
      box->mutable_min()->set_y(min.y());
      box->mutable_min()->set_z(min.z());
      box->mutable_max()->set_x(max.x());
      box->mutable_max()->set_y(max.y());
      box->mutable_max()->set_z(max.z());
    }
    if (!writer->Write(chunk)) {
      return grpc::Status(grpc::StatusCode::CANCELLED, "client went away");
    }
    offset += n;
  } while (offset < total);
  return grpc::Status::OK;
}

}  // namespace mav::simulator_service
