#include "services/mapping/mapping_service.h"

#include <chrono>
#include <cstdlib>
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
#include "services/common/call_watch.h"
#include "services/common/file_stream.h"
#include "services/common/grpc_status.h"

namespace mav::mapping_service {

namespace {

using service_common::CallWatch;
using service_common::CheckDeadline;
using service_common::ChunkSize;
using service_common::OccupancyFormatFromProto;
using service_common::StreamChunks;
using service_common::StreamOccupancy;
using service_common::ToGrpcStatus;

// Longest an InsertKeyframe waits for its keyframe when the client set no deadline.
constexpr double kDefaultWaitMs = 30'000;
// ~60 bytes per box on the wire: 50 000 boxes stay well inside gRPC's 4 MiB message limit.
constexpr int kMaxBoxes = 50000;

Status NoMap(const std::optional<MappingMethod>& method) {
  return Status::NotFound(
      std::string("no ") +
      (method.has_value() ? mapping::MappingMethodName(*method) + std::string(" ") : "") +
      "map has been built: call BuildMap first");
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
                                               const Termination& deadline,
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
  const Status started = mapper_->StartSession(*config, deadline);
  if (!started.ok()) return ToGrpcStatus(started);
  if (input_ != nullptr) {
    const bool dds = !request.disable_dds_input() && config->pose_source != PoseSource::kNone;
    const Status input = input_->SetInput(dds);
    if (!input.ok()) return ToGrpcStatus(input);
  }
  ToProto(mapper_->GetStatus(), response);
  return grpc::Status::OK;
}

grpc::Status MappingService::StartSession(grpc::ServerContext* context,
                                          const v1::StartSessionRequest* request,
                                          v1::MappingStatus* response) {
  if (Status s = CheckDeadline(*context, "StartSession"); !s.ok()) return ToGrpcStatus(s);
  return ApplyStartSession(*request, CallWatch(context).termination(), response);
}

grpc::Status MappingService::Reset(grpc::ServerContext* context, const v1::MappingResetRequest*,
                                   v1::MappingStatus* response) {
  if (Status s = CheckDeadline(*context, "Reset"); !s.ok()) return ToGrpcStatus(s);
  const Status reset = mapper_->Reset(CallWatch(context).termination());
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
  if (Status s = CheckDeadline(*context, "InsertKeyframe"); !s.ok()) return ToGrpcStatus(s);
  const CallWatch call(context);
  Result<KeyframeResult> result = mapper_->InsertKeyframe(
      std::move(*frame), *pose, request->force(),
      call.termination().WithDeadlineNs(Termination::AfterMs(kDefaultWaitMs).deadline_ns()));
  if (!result.ok()) return ToGrpcStatus(result.status());
  ToProto(*result, response);
  return grpc::Status::OK;
}

grpc::Status MappingService::BuildMap(grpc::ServerContext* context,
                                      const v1::BuildMapRequest* request,
                                      v1::BuildMapResponse* response) {
  Result<BuildRequest> build = BuildFromProto(*request);
  if (!build.ok()) return ToGrpcStatus(build.status());
  if (Status s = CheckDeadline(*context, "BuildMap"); !s.ok()) return ToGrpcStatus(s);
  Result<MapStats> stats = mapper_->Build(*build, CallWatch(context).termination());
  if (!stats.ok()) return ToGrpcStatus(stats.status());
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
  Result<v1::OccupancyFormat> format = OccupancyFormatFromProto(request->format());
  if (!format.ok()) return ToGrpcStatus(format.status());
  std::shared_ptr<const BuiltMap> map = mapper_->Map(*method);
  if (map == nullptr) return ToGrpcStatus(NoMap(*method));
  return StreamOccupancy(context, map->grid, *format, *chunk_bytes, writer);
}

grpc::ServerUnaryReactor* MappingService::QueryCollision(grpc::CallbackServerContext* context,
                                                         const v1::QueryCollisionRequest* request,
                                                         v1::QueryCollisionResponse* response) {
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
  reactor->Finish(AnswerQueryCollision(request, response));
  return reactor;
}

grpc::Status MappingService::AnswerQueryCollision(const v1::QueryCollisionRequest* request,
                                                  v1::QueryCollisionResponse* response) {
  Result<std::optional<MappingMethod>> method = MethodFromProto(request->method(), "method", true);
  if (!method.ok()) return ToGrpcStatus(method.status());
  if (request->boxes_size() == 0) {
    return ToGrpcStatus(Status::InvalidArgument("boxes: no boxes given"));
  }
  if (request->boxes_size() > kMaxBoxes) {
    return ToGrpcStatus(Status::InvalidArgument("boxes: " + std::to_string(request->boxes_size()) +
                                                " boxes, at most " + std::to_string(kMaxBoxes) +
                                                " per call (split larger queries)"));
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
  if (map == nullptr) return ToGrpcStatus(NoMap(*method));
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
  Result<mapping::PlyEncoding> encoding = kMeshFormatCodec.FromProto(request->format(), "format");
  if (!encoding.ok()) return ToGrpcStatus(encoding.status());
  std::shared_ptr<const BuiltMap> map = mapper_->Map(MappingMethod::kSparseMesh);
  if (map == nullptr) {
    return ToGrpcStatus(Status::NotFound(
        "no sparse-mesh map has been built: call BuildMap with SPARSE_MESH first"));
  }
  const std::string bytes = mapping::EncodePly(map->mesh, *encoding);
  return StreamChunks(context, bytes, *chunk_bytes,
                      [&](v1::FileChunk&& chunk, bool) { return writer->Write(chunk); });
}

}  // namespace mav::mapping_service
