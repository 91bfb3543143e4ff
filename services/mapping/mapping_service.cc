#include "services/mapping/mapping_service.h"

#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <functional>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>

#include "mav/v1/simulator.grpc.pb.h"

#include "mav/common/file.h"
#include "mav/common/log.h"
#include "mav/common/time.h"
#include "mav/dataset/euroc.h"
#include "mav/dataset/occupancy_io.h"
#include "mav/mapping/mesh.h"
#include "mav/transport/grpc_server.h"
#include "services/common/grpc_status.h"

namespace mav::mapping_service {

namespace {

using service_common::ToGrpcStatus;

constexpr uint32_t kDefaultChunkBytes = 1 << 20;
constexpr uint32_t kMinChunkBytes = 4096;
constexpr uint32_t kMaxChunkBytes = 4 << 20;
constexpr int kMaxBoxes = 100000;

grpc::Status Refused(const Status& status, Refusal refusal) {
  switch (refusal) {
    case Refusal::kResourceExhausted:
      return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED, status.message());
    case Refusal::kDeadlineExceeded:
      return grpc::Status(grpc::StatusCode::DEADLINE_EXCEEDED, status.message());
    case Refusal::kNone:
      break;
  }
  return ToGrpcStatus(status);
}

// The client's deadline as a monotonic time; 0 when it set none.
int64_t MonotonicDeadline(const grpc::ServerContext* context) {
  const auto deadline = context->deadline();
  if (deadline == std::chrono::system_clock::time_point::max()) return 0;
  const auto left = std::chrono::duration_cast<std::chrono::nanoseconds>(
      deadline - std::chrono::system_clock::now());
  return MonotonicNowNs() + std::max<int64_t>(1, left.count());
}

Result<uint32_t> ChunkSize(uint32_t requested) {
  const uint32_t bytes = requested == 0 ? kDefaultChunkBytes : requested;
  if (bytes < kMinChunkBytes || bytes > kMaxChunkBytes) {
    return Status::InvalidArgument("chunk_size: must be in [4096, 4194304] bytes, got " +
                                   std::to_string(requested));
  }
  return bytes;
}

// A file in the temporary directory, removed on destruction.
class TempFile {
 public:
  explicit TempFile(const std::string& suffix) {
    std::string pattern =
        (std::filesystem::temp_directory_path() / ("mav-mapping-XXXXXX" + suffix)).string();
    const int fd = mkstemps(pattern.data(), static_cast<int>(suffix.size()));
    if (fd >= 0) {
      close(fd);
      path_ = pattern;
    }
  }
  ~TempFile() {
    if (!path_.empty()) std::filesystem::remove(path_);
  }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

Result<std::string> EncodeOccupancy(const dataset::OccupancyGrid& grid,
                                    v1::OccupancyFormat format) {
  if (format == v1::OCCUPANCY_FORMAT_OCTOMAP_BT) return dataset::EncodeOctomapBt(grid);
  return dataset::EncodeMavocc(grid);
}

// Streams `bytes` as FileChunks; `send` fills in the per-message wrapper and writes it.
grpc::Status StreamChunks(grpc::ServerContext* context, const std::string& bytes,
                          uint32_t chunk_bytes,
                          const std::function<bool(v1::FileChunk&&, bool first)>& send) {
  const uint64_t total = bytes.size();
  uint64_t offset = 0;
  do {
    if (context->IsCancelled()) return grpc::Status(grpc::StatusCode::CANCELLED, "cancelled");
    const uint64_t n = std::min<uint64_t>(chunk_bytes, total - offset);
    v1::FileChunk chunk;
    chunk.set_offset(offset);
    chunk.set_total_size(total);
    chunk.set_data(bytes.substr(offset, n));
    chunk.set_last(offset + n == total);
    if (!send(std::move(chunk), offset == 0)) {
      return grpc::Status(grpc::StatusCode::CANCELLED, "client went away");
    }
    offset += n;
  } while (offset < total);
  return grpc::Status::OK;
}

}  // namespace

bool MappingServiceOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why != nullptr) *why = m;
    return false;
  };
  if (calibration_timeout_ms <= 0) return fail("calibration_timeout_ms: must be > 0");
  if (queue_length < 1 || queue_length > 1000) return fail("queue_length: must be in [1, 1000]");
  if (pose_wait_ms <= 0) return fail("pose_wait_ms: must be > 0");
  if (max_voxels < 1) return fail("max_voxels: must be > 0");
  return true;
}

MappingService::MappingService(Mapper* mapper, InputControl* input, MappingServiceOptions options)
    : mapper_(mapper), input_(input), options_(options) {
  mapper_->set_max_voxels(options_.max_voxels);
}

grpc::Status MappingService::ApplyStartSession(const v1::StartSessionRequest& request,
                                               v1::MappingStatus* response) {
  SessionConfig defaults;
  defaults.queue_length = static_cast<int>(options_.queue_length);
  defaults.pose_wait_ms = options_.pose_wait_ms;
  Result<SessionConfig> config = SessionFromProto(request, defaults);
  if (!config.ok()) return ToGrpcStatus(config.status());
  Result<RigCalibration> rig =
      ResolveCalibration(request.calibration(), options_.calibration_timeout_ms);
  if (!rig.ok()) {
    MAV_LOG(kWarning) << "StartSession: " << rig.status().ToString();
    return ToGrpcStatus(rig.status());
  }
  config->calibration = rig->calibration;
  config->calibration_rectified = rig->rectified;
  const Status started = mapper_->StartSession(*config);
  if (!started.ok()) return ToGrpcStatus(started);
  if (input_ != nullptr) {
    const bool dds = !request.disable_dds_input() && config->pose_source != PoseSource::kNone;
    const Status input = input_->SetInput(dds, config->pose_source);
    if (!input.ok()) return ToGrpcStatus(input);
  }
  ToProto(mapper_->GetStatus(), response);
  return grpc::Status::OK;
}

grpc::Status MappingService::StartSession(grpc::ServerContext*,
                                          const v1::StartSessionRequest* request,
                                          v1::MappingStatus* response) {
  return ApplyStartSession(*request, response);
}

grpc::Status MappingService::Reset(grpc::ServerContext*, const v1::MappingResetRequest*,
                                   v1::MappingStatus* response) {
  const Status reset = mapper_->Reset();
  if (!reset.ok()) return ToGrpcStatus(reset);
  ToProto(mapper_->GetStatus(), response);
  return grpc::Status::OK;
}

grpc::Status MappingService::GetStatus(grpc::ServerContext*, const v1::MappingGetStatusRequest*,
                                       v1::MappingStatus* response) {
  ToProto(mapper_->GetStatus(), response);
  return grpc::Status::OK;
}

grpc::Status MappingService::InsertKeyframe(grpc::ServerContext* context,
                                            const v1::InsertKeyframeRequest* request,
                                            v1::InsertKeyframeResponse* response) {
  if (!mapper_->session_active()) {
    return ToGrpcStatus(Status::FailedPrecondition("no session: call StartSession first"));
  }
  if (!request->has_stereo()) return ToGrpcStatus(Status::InvalidArgument("stereo: not set"));
  if (!request->has_t_world_body()) {
    return ToGrpcStatus(Status::InvalidArgument("t_world_body: not set"));
  }
  Result<FrameInput> frame = StereoFromProto(request->stereo(), "stereo");
  if (!frame.ok()) return ToGrpcStatus(frame.status());
  Result<geometry::SE3> pose = PoseFromProto(request->t_world_body(), "t_world_body");
  if (!pose.ok()) return ToGrpcStatus(pose.status());
  Refusal refusal = Refusal::kNone;
  Result<KeyframeResult> result = mapper_->SubmitKeyframeAndWait(
      std::move(*frame), *pose, request->force(), MonotonicDeadline(context), &refusal);
  if (!result.ok()) return Refused(result.status(), refusal);
  ToProto(*result, response);
  return grpc::Status::OK;
}

grpc::Status MappingService::BuildMap(grpc::ServerContext* context,
                                      const v1::BuildMapRequest* request,
                                      v1::BuildMapResponse* response) {
  Result<BuildRequest> build = BuildFromProto(*request);
  if (!build.ok()) return ToGrpcStatus(build.status());
  build->deadline_monotonic_ns = MonotonicDeadline(context);
  Refusal refusal = Refusal::kNone;
  Result<MapStats> stats = mapper_->BuildAndWait(*build, &refusal);
  if (!stats.ok()) return Refused(stats.status(), refusal);
  ToProto(*stats, response);
  return grpc::Status::OK;
}

grpc::Status MappingService::GetOccupancy(grpc::ServerContext* context,
                                          const v1::GetOccupancyRequest* request,
                                          grpc::ServerWriter<v1::OccupancyChunk>* writer) {
  Result<std::optional<MappingMethod>> method = MethodFromProto(request->method(), "method", true);
  if (!method.ok()) return ToGrpcStatus(method.status());
  Result<uint32_t> chunk_bytes = ChunkSize(request->chunk_size());
  if (!chunk_bytes.ok()) return ToGrpcStatus(chunk_bytes.status());
  v1::OccupancyFormat format = request->format();
  if (format == v1::OCCUPANCY_FORMAT_UNSPECIFIED) format = v1::OCCUPANCY_FORMAT_OCTOMAP_BT;
  if (format != v1::OCCUPANCY_FORMAT_OCTOMAP_BT && format != v1::OCCUPANCY_FORMAT_MAVOCC) {
    return ToGrpcStatus(Status::InvalidArgument("format: unknown value " +
                                                std::to_string(static_cast<int>(format))));
  }
  std::shared_ptr<const BuiltMap> map = mapper_->Map(*method);
  if (map == nullptr) {
    return ToGrpcStatus(Status::NotFound(
        std::string("no ") +
        (method->has_value() ? mapping::MappingMethodName(**method) + std::string(" ") : "") +
        "map has been built: call BuildMap first"));
  }
  Result<std::string> bytes = EncodeOccupancy(map->grid, format);
  if (!bytes.ok()) return ToGrpcStatus(bytes.status());
  const dataset::GridGeometry& g = map->grid.geometry();
  return StreamChunks(context, *bytes, *chunk_bytes, [&](v1::FileChunk&& chunk, bool first) {
    v1::OccupancyChunk message;
    *message.mutable_chunk() = std::move(chunk);
    if (first) {
      message.set_format(format);
      message.set_resolution_m(g.resolution);
      ToProto(Eigen::AlignedBox3d(g.origin, g.origin + g.size.cast<double>() * g.resolution),
              message.mutable_bounds());
    }
    return writer->Write(message);
  });
}

grpc::Status MappingService::QueryCollision(grpc::ServerContext*,
                                            const v1::QueryCollisionRequest* request,
                                            v1::QueryCollisionResponse* response) {
  Result<std::optional<MappingMethod>> method = MethodFromProto(request->method(), "method", true);
  if (!method.ok()) return ToGrpcStatus(method.status());
  if (request->boxes_size() == 0) {
    return ToGrpcStatus(Status::InvalidArgument("boxes: no boxes given"));
  }
  if (request->boxes_size() > kMaxBoxes) {
    return ToGrpcStatus(Status::InvalidArgument("boxes: " + std::to_string(request->boxes_size()) +
                                                " boxes, at most 100000 per call"));
  }
  std::vector<Eigen::AlignedBox3d> boxes;
  boxes.reserve(request->boxes_size());
  for (int i = 0; i < request->boxes_size(); ++i) {
    Result<Eigen::AlignedBox3d> box =
        BoxFromProto(request->boxes(i), "boxes[" + std::to_string(i) + "]");
    if (!box.ok()) return ToGrpcStatus(box.status());
    boxes.push_back(*box);
  }
  std::shared_ptr<const BuiltMap> map = mapper_->Map(*method);
  if (map == nullptr) {
    return ToGrpcStatus(Status::NotFound(
        std::string("no ") +
        (method->has_value() ? mapping::MappingMethodName(**method) + std::string(" ") : "") +
        "map has been built: call BuildMap first"));
  }
  uint32_t collisions = 0, free = 0, unknown = 0;
  for (const Eigen::AlignedBox3d& box : boxes) {
    const v1::CollisionState state =
        ToProto(map->query->Query(box.min(), box.max()), request->unknown_is_collision());
    response->add_states(state);
    collisions += state == v1::COLLISION_STATE_COLLISION;
    free += state == v1::COLLISION_STATE_FREE;
    unknown += state == v1::COLLISION_STATE_UNKNOWN;
  }
  response->set_collisions(collisions);
  response->set_free(free);
  response->set_unknown(unknown);
  return grpc::Status::OK;
}

grpc::Status MappingService::ExportMesh(grpc::ServerContext* context,
                                        const v1::ExportMeshRequest* request,
                                        grpc::ServerWriter<v1::FileChunk>* writer) {
  Result<uint32_t> chunk_bytes = ChunkSize(request->chunk_size());
  if (!chunk_bytes.ok()) return ToGrpcStatus(chunk_bytes.status());
  mapping::PlyEncoding encoding = mapping::PlyEncoding::kBinaryLittleEndian;
  switch (request->format()) {
    case v1::MESH_FORMAT_UNSPECIFIED:
    case v1::MESH_FORMAT_PLY_BINARY:
      break;
    case v1::MESH_FORMAT_PLY_ASCII:
      encoding = mapping::PlyEncoding::kAscii;
      break;
    default:
      return ToGrpcStatus(Status::InvalidArgument(
          "format: unknown value " + std::to_string(static_cast<int>(request->format()))));
  }
  std::shared_ptr<const BuiltMap> map = mapper_->Map(MappingMethod::kSparseMesh);
  if (map == nullptr) {
    return ToGrpcStatus(Status::NotFound(
        "no sparse-mesh map has been built: call BuildMap with SPARSE_MESH first"));
  }
  const std::string bytes = mapping::EncodePly(map->mesh, encoding);
  return StreamChunks(context, bytes, *chunk_bytes,
                      [&](v1::FileChunk&& chunk, bool) { return writer->Write(chunk); });
}

}  // namespace mav::mapping_service
