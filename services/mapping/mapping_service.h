#pragma once
// The gRPC Mapping service (protos/mav/v1/mapping.proto): a thin adapter from RPCs to the Mapper
// (mapper.h). Status codes follow docs/contracts.md ("Mapping"): INVALID_ARGUMENT naming the
// field; FAILED_PRECONDITION without a session or with no keyframes ("empty map");
// NOT_FOUND for queries/downloads of a map that was never built; RESOURCE_EXHAUSTED when a build
// is running, a limit is reached or the grid would exceed the voxel limit; DEADLINE_EXCEEDED when
// a build outlives the client's deadline; NOT_FOUND / UNAVAILABLE / FAILED_PRECONDITION from the
// calibration source.

#include <cstdint>
#include <string>

#include "mav/v1/mapping.grpc.pb.h"

#include "mav/common/status.h"
#include "services/common/calibration_source.h"
#include "services/mapping/convert.h"
#include "services/mapping/dds_io.h"
#include "services/mapping/mapper.h"

namespace mav::mapping_service {

struct MappingServiceOptions {
  // Deadline of the GetCalibration call to a simulator calibration source (contract: 2 s).
  int64_t calibration_timeout_ms = 2000;
  // Server-side settings of every session (not in StartSessionRequest).
  int64_t queue_length = 16;    // live keyframes waiting for the worker
  int64_t pose_wait_ms = 2000;  // longest a live frame waits for its pose
  int64_t max_voxels = 50'000'000;

  bool IsValid(std::string* why) const;
};

using service_common::ResolveCalibration;  // services/common/calibration_source.h

class MappingService final
    : public v1::Mapping::WithCallbackMethod_QueryCollision<v1::Mapping::Service> {
 public:
  // `mapper` (not owned) must outlive the service; `input` (not owned, may be null: no live input,
  // e.g. in contract tests) is switched on by StartSession for a DDS pose source unless
  // disable_dds_input.
  MappingService(Mapper* mapper, InputControl* input, MappingServiceOptions options = {});

  grpc::Status StartSession(grpc::ServerContext* context, const v1::StartSessionRequest* request,
                            v1::MappingStatus* response) override;
  grpc::Status Reset(grpc::ServerContext* context, const v1::MappingResetRequest* request,
                     v1::MappingStatus* response) override;
  grpc::Status InsertKeyframe(grpc::ServerContext* context,
                              const v1::InsertKeyframeRequest* request,
                              v1::InsertKeyframeResponse* response) override;
  grpc::Status BuildMap(grpc::ServerContext* context, const v1::BuildMapRequest* request,
                        v1::BuildMapResponse* response) override;
  grpc::Status GetOccupancy(grpc::ServerContext* context, const v1::GetOccupancyRequest* request,
                            grpc::ServerWriter<v1::OccupancyChunk>* writer) override;
  // On gRPC's callback API: answered on the thread that read the call, without the sync server's
  // hand-off to a worker thread (half the server CPU of a one-box call; docs/benchmarks.md). It
  // never waits for a lock held by a build (the map is an immutable snapshot); the largest call,
  // 50 000 boxes, holds that thread for about 30 ms.
  grpc::ServerUnaryReactor* QueryCollision(grpc::CallbackServerContext* context,
                                           const v1::QueryCollisionRequest* request,
                                           v1::QueryCollisionResponse* response) override;
  grpc::Status ExportMesh(grpc::ServerContext* context, const v1::ExportMeshRequest* request,
                          grpc::ServerWriter<v1::FileChunk>* writer) override;
  grpc::Status GetStatus(grpc::ServerContext* context, const v1::MappingGetStatusRequest* request,
                         v1::MappingStatus* response) override;

  // StartSession without an RPC (main.cc's start-up flags) or with the call's deadline.
  grpc::Status ApplyStartSession(const v1::StartSessionRequest& request,
                                 const Termination& deadline, v1::MappingStatus* response);

 private:
  grpc::Status AnswerQueryCollision(const v1::QueryCollisionRequest* request,
                                    v1::QueryCollisionResponse* response);

  Mapper* mapper_;
  InputControl* input_;
  MappingServiceOptions options_;
};

}  // namespace mav::mapping_service
