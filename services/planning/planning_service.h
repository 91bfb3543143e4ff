#pragma once
// The gRPC Planning service (protos/mav/v1/planning.proto): a thin adapter from RPCs to the
// PlannerCore (planner_core.h). Status codes follow docs/contracts.md ("Planning"):
// INVALID_ARGUMENT naming the field; FAILED_PRECONDITION without a map (or roadmap, for
// SaveRoadmap); NOT_FOUND for a missing file, map of the mapping service or plan id; DATA_LOSS
// for a corrupt .bt or roadmap file; RESOURCE_EXHAUSTED for too many plans in flight, a long
// operation already running, the map memory, milestone, upload and sample limits;
// DEADLINE_EXCEEDED when the client's deadline stops the work (nothing is stored); UNAVAILABLE
// when the mapping service cannot be reached.
//
// Every handler that changes state (LoadMap, UploadMap, BuildRoadmap, LoadRoadmap, SaveRoadmap,
// PlanPath: it stores the plan) checks the client's deadline first, and PlanPath checks it again
// before the plan is stored: a late call changes nothing.

#include <cstdint>
#include <string>

#include "mav/v1/planning.grpc.pb.h"

#include "mav/common/status.h"
#include "mav/common/termination.h"
#include "services/planning/planner_core.h"

namespace mav::planning_service {

struct PlanningServiceOptions {
  // Largest map UploadMap accepts, bytes (contract: 1 GiB); a larger total_size is refused on
  // the first chunk, before anything is buffered. Validated >= 1.
  uint64_t max_upload_bytes = uint64_t{1} << 30;
  // Deadline of the GetOccupancy call to a mapping service (contract: 30 s), also bounded by the
  // client's. Validated > 0.
  int64_t mapping_timeout_ms = 30000;

  bool IsValid(std::string* why) const;
};

class PlanningService final : public v1::Planning::Service {
 public:
  // `core` (not owned) must outlive the service.
  PlanningService(PlannerCore* core, PlanningServiceOptions options = {});

  grpc::Status LoadMap(grpc::ServerContext* context, const v1::LoadMapRequest* request,
                       v1::MapInfo* response) override;
  grpc::Status UploadMap(grpc::ServerContext* context,
                         grpc::ServerReader<v1::UploadMapRequest>* reader,
                         v1::MapInfo* response) override;
  grpc::Status BuildRoadmap(grpc::ServerContext* context, const v1::BuildRoadmapRequest* request,
                            v1::RoadmapInfo* response) override;
  grpc::Status SaveRoadmap(grpc::ServerContext* context, const v1::SaveRoadmapRequest* request,
                           v1::RoadmapInfo* response) override;
  grpc::Status LoadRoadmap(grpc::ServerContext* context, const v1::LoadRoadmapRequest* request,
                           v1::RoadmapInfo* response) override;
  grpc::Status PlanPath(grpc::ServerContext* context, const v1::PlanPathRequest* request,
                        v1::PlanPathResponse* response) override;
  grpc::Status GetPlan(grpc::ServerContext* context, const v1::GetPlanRequest* request,
                       v1::PlanPathResponse* response) override;
  grpc::Status GetRoadmapStatus(grpc::ServerContext* context,
                                const v1::GetRoadmapStatusRequest* request,
                                v1::PlanningStatus* response) override;
  grpc::Status SampleTrajectory(grpc::ServerContext* context,
                                const v1::SampleTrajectoryRequest* request,
                                v1::SampleTrajectoryResponse* response) override;

 private:
  // The .bt bytes of a mapping service's map (GetOccupancy, chunks checked), under `deadline`.
  Result<std::string> FetchFromMapping(const v1::MapFromMappingService& source,
                                       const Termination& deadline);
  // The reply of a stored or fresh plan, samples every `sample_dt_s` (0 = none).
  Status FillPlanResponse(const PlanOutcome& outcome, double sample_dt_s,
                          v1::PlanPathResponse* response) const;

  PlannerCore* core_;
  PlanningServiceOptions options_;
};

}  // namespace mav::planning_service
