#include "services/planning/planning_service.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <utility>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>

#include "mav/v1/mapping.grpc.pb.h"

#include "mav/common/log.h"
#include "mav/common/text.h"
#include "mav/common/time.h"
#include "services/common/call_watch.h"
#include "services/common/grpc_status.h"
#include "services/planning/convert.h"

namespace mav::planning_service {

namespace {

using service_common::CallWatch;
using service_common::CheckDeadline;
using service_common::ToGrpcStatus;

// The longest an echoed path may be in a message.
constexpr size_t kEchoBytes = 256;

// The call's deadline and its cancellation (by the client, or by the server at the end of a
// shutdown's grace period), for the core.
std::string Echo(const std::string& s) {
  return s.size() <= kEchoBytes ? s : s.substr(0, kEchoBytes) + "...";
}

// Appends a chunk to `bytes`: the offsets must follow each other and the total stay the same.
Status AppendChunk(const v1::FileChunk& chunk, const std::string& field, uint64_t* total,
                   std::string* bytes) {
  if (chunk.offset() != bytes->size()) {
    return Status::InvalidArgument(field + ".offset: " + std::to_string(chunk.offset()) +
                                   ", expected " + std::to_string(bytes->size()) +
                                   " (chunks must follow each other)");
  }
  if (bytes->empty() && *total == 0) *total = chunk.total_size();
  if (chunk.total_size() != *total) {
    return Status::InvalidArgument(field + ".total_size: " + std::to_string(chunk.total_size()) +
                                   " differs from the first chunk's " + std::to_string(*total));
  }
  if (bytes->size() + chunk.data().size() > *total) {
    return Status::InvalidArgument(field + ".data: the chunks exceed total_size " +
                                   std::to_string(*total));
  }
  bytes->append(chunk.data());
  return Status::Ok();
}

Status SizeComplete(const std::string& bytes, uint64_t total, const std::string& what) {
  if (bytes.size() != total) {
    return Status::InvalidArgument(what + ": " + std::to_string(bytes.size()) +
                                   " bytes received, total_size announced " +
                                   std::to_string(total));
  }
  return Status::Ok();
}

}  // namespace

bool PlanningServiceOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why != nullptr) *why = m;
    return false;
  };
  if (max_upload_bytes < 1) return fail("max_upload_bytes: must be > 0");
  if (mapping_timeout_ms <= 0) return fail("mapping_timeout_ms: must be > 0");
  return true;
}

PlanningService::PlanningService(PlannerCore* core, PlanningServiceOptions options)
    : core_(core), options_(options) {}

Result<std::string> PlanningService::FetchFromMapping(const v1::MapFromMappingService& source,
                                                      const Termination& deadline) {
  const std::string what = "mapping@" + Echo(source.address()) + " GetOccupancy";
  v1::GetOccupancyRequest request;
  MAV_ASSIGN_OR_RETURN(const v1::MappingMethod method,
                       kMappingMethodRefCodec.FromProto(source.method(), "mapping.method"));
  request.set_method(method);
  request.set_format(v1::OCCUPANCY_FORMAT_OCTOMAP_BT);
  auto stub = v1::Mapping::NewStub(
      grpc::CreateChannel(source.address(), grpc::InsecureChannelCredentials()));
  grpc::ClientContext context;
  const int64_t budget_ns =
      std::min<int64_t>(deadline.RemainingNs(), options_.mapping_timeout_ms * 1'000'000);
  context.set_deadline(std::chrono::system_clock::now() +
                       std::chrono::nanoseconds(std::max<int64_t>(budget_ns, 0)));
  std::unique_ptr<grpc::ClientReader<v1::OccupancyChunk>> reader =
      stub->GetOccupancy(&context, request);
  std::string bytes;
  uint64_t total = 0;
  Status broken;
  v1::OccupancyChunk message;
  while (reader->Read(&message)) {
    if (!broken.ok()) continue;
    if (message.chunk().total_size() > options_.max_upload_bytes) {
      broken = Status::ResourceExhausted(
          what + ": the map has " + std::to_string(message.chunk().total_size()) +
          " bytes, more than the server's limit of " + std::to_string(options_.max_upload_bytes));
      context.TryCancel();
      continue;
    }
    broken = AppendChunk(message.chunk(), "chunk", &total, &bytes);
    if (!broken.ok()) broken = Status::DataLoss(what + ": " + broken.message());
    if (total > 0)
      core_->SetProgress("fetching map",
                         static_cast<double>(bytes.size()) / static_cast<double>(total));
  }
  const grpc::Status status = reader->Finish();
  if (!broken.ok()) return broken;
  if (!status.ok()) {
    return service_common::OutgoingCallStatus(status, what, "a mav.v1.Mapping service");
  }
  if (Status s = SizeComplete(bytes, total, what); !s.ok()) return Status::DataLoss(s.message());
  return bytes;
}

grpc::Status PlanningService::LoadMap(grpc::ServerContext* context,
                                      const v1::LoadMapRequest* request, v1::MapInfo* response) {
  Result<planning::MapOptions> options = MapOptionsFromProto(request->options(), "options");
  if (!options.ok()) return ToGrpcStatus(options.status());
  if (request->source_case() == v1::LoadMapRequest::SOURCE_NOT_SET) {
    return ToGrpcStatus(Status::InvalidArgument("source: not set (give file or mapping)"));
  }
  if (request->has_file() && request->file().path().empty()) {
    return ToGrpcStatus(Status::InvalidArgument("file.path: empty"));
  }
  if (request->has_mapping() && request->mapping().address().empty()) {
    return ToGrpcStatus(Status::InvalidArgument("mapping.address: empty"));
  }
  if (Status s = CheckDeadline(*context, "LoadMap"); !s.ok()) return ToGrpcStatus(s);
  const CallWatch call(context);
  const Termination& stop = call.termination();
  Result<planning::MapInfo> info = Status::Internal("unreachable");
  if (request->has_file()) {
    info = core_->LoadMapFile(request->file().path(), *options, stop);
  } else {
    Result<PlannerCore::Slot> slot = core_->Reserve("LoadMap");
    if (!slot.ok()) return ToGrpcStatus(slot.status());
    core_->SetProgress("fetching map", 0);
    Result<std::string> bytes = FetchFromMapping(request->mapping(), stop);
    if (!bytes.ok()) {
      MAV_LOG(kWarning) << "LoadMap: " << bytes.status().ToString();
      return ToGrpcStatus(bytes.status());
    }
    info = core_->LoadMapBytes(*slot, std::move(*bytes),
                               "mapping@" + Echo(request->mapping().address()), *options, stop);
  }
  if (!info.ok()) return ToGrpcStatus(info.status());
  ToProto(*info, *options, response);
  return grpc::Status::OK;
}

grpc::Status PlanningService::UploadMap(grpc::ServerContext* context,
                                        grpc::ServerReader<v1::UploadMapRequest>* reader,
                                        v1::MapInfo* response) {
  if (Status s = CheckDeadline(*context, "UploadMap"); !s.ok()) return ToGrpcStatus(s);
  v1::UploadMapRequest message;
  if (!reader->Read(&message)) {
    return ToGrpcStatus(Status::InvalidArgument("options: the stream is empty"));
  }
  if (!message.has_options()) {
    return ToGrpcStatus(Status::InvalidArgument("options: not set in the first message"));
  }
  Result<planning::MapOptions> options = MapOptionsFromProto(message.options(), "options");
  if (!options.ok()) return ToGrpcStatus(options.status());
  if (message.chunk().total_size() > options_.max_upload_bytes) {
    return ToGrpcStatus(Status::ResourceExhausted(
        "chunk.total_size: " + std::to_string(message.chunk().total_size()) +
        " bytes, more than the server's upload limit of " +
        std::to_string(options_.max_upload_bytes)));
  }
  // Held while the bytes arrive: a second upload is refused before it buffers anything.
  Result<PlannerCore::Slot> slot = core_->Reserve("UploadMap");
  if (!slot.ok()) return ToGrpcStatus(slot.status());
  std::string bytes;
  uint64_t total = 0;
  int index = 0;
  do {
    if (index > 0 && message.has_options()) {
      return ToGrpcStatus(Status::InvalidArgument("options: only allowed in the first message"));
    }
    const std::string field = index == 0 ? "chunk" : "chunk[" + std::to_string(index) + "]";
    if (Status s = AppendChunk(message.chunk(), field, &total, &bytes); !s.ok()) {
      return ToGrpcStatus(s);
    }
    if (total > 0)
      core_->SetProgress("upload", static_cast<double>(bytes.size()) / static_cast<double>(total));
    ++index;
    if (message.chunk().last()) break;
  } while (reader->Read(&message));
  if (Status s = SizeComplete(bytes, total, "chunk"); !s.ok()) return ToGrpcStatus(s);
  if (Status s = CheckDeadline(*context, "UploadMap"); !s.ok()) return ToGrpcStatus(s);
  Result<planning::MapInfo> info = core_->LoadMapBytes(*slot, std::move(bytes), "upload", *options,
                                                       CallWatch(context).termination());
  if (!info.ok()) return ToGrpcStatus(info.status());
  ToProto(*info, *options, response);
  return grpc::Status::OK;
}

grpc::Status PlanningService::BuildRoadmap(grpc::ServerContext* context,
                                           const v1::BuildRoadmapRequest* request,
                                           v1::RoadmapInfo* response) {
  Result<planning::RoadmapOptions> options = RoadmapOptionsFromProto(*request);
  if (!options.ok()) return ToGrpcStatus(options.status());
  if (Status s = CheckDeadline(*context, "BuildRoadmap"); !s.ok()) return ToGrpcStatus(s);
  Result<planning::RoadmapInfo> info =
      core_->BuildRoadmap(*options, CallWatch(context).termination());
  if (!info.ok()) return ToGrpcStatus(info.status());
  ToProto(*info, "built", response);
  return grpc::Status::OK;
}

grpc::Status PlanningService::SaveRoadmap(grpc::ServerContext* context,
                                          const v1::SaveRoadmapRequest* request,
                                          v1::RoadmapInfo* response) {
  if (request->path().empty()) return ToGrpcStatus(Status::InvalidArgument("path: empty"));
  if (Status s = CheckDeadline(*context, "SaveRoadmap"); !s.ok()) return ToGrpcStatus(s);
  Result<planning::RoadmapInfo> info =
      core_->SaveRoadmap(request->path(), CallWatch(context).termination());
  if (!info.ok()) return ToGrpcStatus(info.status());
  ToProto(*info, request->path(), response);
  return grpc::Status::OK;
}

grpc::Status PlanningService::LoadRoadmap(grpc::ServerContext* context,
                                          const v1::LoadRoadmapRequest* request,
                                          v1::RoadmapInfo* response) {
  if (request->path().empty()) return ToGrpcStatus(Status::InvalidArgument("path: empty"));
  if (Status s = CheckDeadline(*context, "LoadRoadmap"); !s.ok()) return ToGrpcStatus(s);
  Result<planning::RoadmapInfo> info =
      core_->LoadRoadmap(request->path(), CallWatch(context).termination());
  if (!info.ok()) return ToGrpcStatus(info.status());
  ToProto(*info, request->path(), response);
  return grpc::Status::OK;
}

Status PlanningService::FillPlanResponse(const PlanOutcome& outcome, double sample_dt_s,
                                         v1::PlanPathResponse* response) const {
  ToProto(outcome, response);
  if (sample_dt_s > 0 && outcome.result.ok()) {
    MAV_RETURN_IF_ERROR(AppendSamples(outcome.result.trajectory, sample_dt_s, "sample_dt_s",
                                      response->mutable_samples()));
  }
  return Status::Ok();
}

grpc::Status PlanningService::PlanPath(grpc::ServerContext* context,
                                       const v1::PlanPathRequest* request,
                                       v1::PlanPathResponse* response) {
  const int64_t start_ns = MonotonicNowNs();
  Result<planning::PlanRequest> plan_request = PlanRequestFromProto(*request);
  Status failure = plan_request.status();
  if (failure.ok()) failure = CheckDeadline(*context, "PlanPath");
  if (!failure.ok()) {
    core_->RecordFailed();
    return ToGrpcStatus(failure);
  }
  Result<PlanOutcome> outcome = core_->Plan(*plan_request, CallWatch(context).termination());
  if (!outcome.ok()) return ToGrpcStatus(outcome.status());
  failure = FillPlanResponse(*outcome, request->sample_dt_s(), response);
  // Stored only when the client still waits for it: a late plan changes nothing.
  if (failure.ok() && outcome->result.ok()) failure = CheckDeadline(*context, "PlanPath");
  if (!failure.ok()) {
    core_->RecordFailed();
    response->Clear();
    return ToGrpcStatus(failure);
  }
  if (outcome->result.ok()) {
    response->set_plan_id(core_->StorePlan(*outcome, request->sample_dt_s()));
  }
  core_->RecordAnswered(outcome->result.ok(), MsSince(start_ns));
  return grpc::Status::OK;
}

grpc::Status PlanningService::GetPlan(grpc::ServerContext*, const v1::GetPlanRequest* request,
                                      v1::PlanPathResponse* response) {
  if (request->plan_id().empty()) return ToGrpcStatus(Status::InvalidArgument("plan_id: empty"));
  std::shared_ptr<const StoredPlan> plan = core_->FindPlan(request->plan_id());
  if (plan == nullptr) {
    return ToGrpcStatus(Status::NotFound(
        "plan_id: no plan " + QuoteForError(request->plan_id()) + " (the server keeps the last " +
        std::to_string(PlannerCore::kPlanHistory) + " successful plans)"));
  }
  if (Status s = FillPlanResponse(plan->outcome, plan->sample_dt_s, response); !s.ok()) {
    return ToGrpcStatus(s);
  }
  response->set_plan_id(plan->id);
  return grpc::Status::OK;
}

grpc::Status PlanningService::GetRoadmapStatus(grpc::ServerContext*,
                                               const v1::GetRoadmapStatusRequest*,
                                               v1::PlanningStatus* response) {
  ToProto(core_->GetStatus(), response);
  return grpc::Status::OK;
}

grpc::Status PlanningService::SampleTrajectory(grpc::ServerContext*,
                                               const v1::SampleTrajectoryRequest* request,
                                               v1::SampleTrajectoryResponse* response) {
  std::shared_ptr<const StoredPlan> plan;
  geometry::PolynomialTrajectory given;
  const geometry::PolynomialTrajectory* trajectory = nullptr;
  switch (request->trajectory_source_case()) {
    case v1::SampleTrajectoryRequest::kPlanId: {
      if (request->plan_id().empty()) {
        return ToGrpcStatus(Status::InvalidArgument("plan_id: empty"));
      }
      plan = core_->FindPlan(request->plan_id());
      if (plan == nullptr) {
        return ToGrpcStatus(
            Status::NotFound("plan_id: no plan " + QuoteForError(request->plan_id()) +
                             " (the server keeps the last " +
                             std::to_string(PlannerCore::kPlanHistory) + " successful plans)"));
      }
      trajectory = &plan->outcome.result.trajectory;
      break;
    }
    case v1::SampleTrajectoryRequest::kTrajectory: {
      Result<geometry::PolynomialTrajectory> t =
          TrajectoryFromProto(request->trajectory(), "trajectory");
      if (!t.ok()) return ToGrpcStatus(t.status());
      given = std::move(*t);
      trajectory = &given;
      break;
    }
    default:
      return ToGrpcStatus(
          Status::InvalidArgument("trajectory_source: not set (give plan_id or trajectory)"));
  }
  const double duration = trajectory->duration_s();
  response->set_duration_s(duration);
  if (request->times_s_size() > 0) {
    if (static_cast<size_t>(request->times_s_size()) > kMaxSamples) {
      return ToGrpcStatus(Status::ResourceExhausted(
          "times_s: " + std::to_string(request->times_s_size()) + " times, more than " +
          std::to_string(kMaxSamples) + " (the reply must fit gRPC's 4 MiB limit)"));
    }
    for (int i = 0; i < request->times_s_size(); ++i) {
      const double t = request->times_s(i);
      if (!std::isfinite(t) || t < 0 || t > duration) {
        return ToGrpcStatus(Status::InvalidArgument("times_s[" + std::to_string(i) +
                                                    "]: " + std::to_string(t) + " is outside [0, " +
                                                    std::to_string(duration) + "] s"));
      }
    }
    for (double t : request->times_s()) ToProto(trajectory->Evaluate(t), response->add_samples());
    return grpc::Status::OK;
  }
  if (!(request->dt_s() > 0) || !std::isfinite(request->dt_s())) {
    return ToGrpcStatus(Status::InvalidArgument(
        "dt_s: must be > 0 and finite (or give times_s), got " + std::to_string(request->dt_s())));
  }
  return ToGrpcStatus(
      AppendSamples(*trajectory, request->dt_s(), "dt_s", response->mutable_samples()));
}

}  // namespace mav::planning_service
