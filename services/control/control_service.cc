#include "services/control/control_service.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>

#include "mav/v1/planning.grpc.pb.h"

#include "mav/common/log.h"
#include "mav/common/text.h"
#include "mav/common/time.h"
#include "services/common/call_watch.h"
#include "services/common/grpc_status.h"

namespace mav::control_service {

namespace {

using service_common::CallWatch;
using service_common::CheckDeadline;
using service_common::OutgoingCallStatus;
using service_common::ToGrpcStatus;

}  // namespace

bool ControlServiceOptions::IsValid(std::string* why) const {
  if (planning_timeout_ms <= 0) {
    if (why != nullptr) *why = "planning_timeout_ms: must be > 0";
    return false;
  }
  return true;
}

Result<geometry::PolynomialTrajectory> FetchPlan(const v1::PlanRef& plan,
                                                 const Termination& deadline, int64_t timeout_ms) {
  if (plan.planning_address().empty()) {
    return Status::InvalidArgument("plan.planning_address: empty (host:port of mav-planning)");
  }
  if (plan.plan_id().empty()) return Status::InvalidArgument("plan.plan_id: empty");
  auto stub = v1::Planning::NewStub(
      grpc::CreateChannel(plan.planning_address(), grpc::InsecureChannelCredentials()));
  const int64_t budget_ns = std::min<int64_t>(timeout_ms * 1'000'000, deadline.RemainingNs());
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::nanoseconds(budget_ns));
  v1::GetPlanRequest request;
  request.set_plan_id(plan.plan_id());
  v1::PlanPathResponse response;
  const grpc::Status rpc = stub->GetPlan(&context, request, &response);
  const std::string what = "plan: Planning.GetPlan at " + plan.planning_address();
  if (!rpc.ok()) {
    Status s = OutgoingCallStatus(rpc, what, "mav-planning");
    switch (s.code()) {
      case StatusCode::kNotFound:
        return Status::NotFound("plan.plan_id: " + QuoteForError(plan.plan_id()) + " unknown to " +
                                QuoteForError(plan.planning_address()) + " (" +
                                rpc.error_message() + ")");
      case StatusCode::kDeadlineExceeded:
        if (deadline.ShouldStop()) return s;  // the client's own deadline
        return Status::Unavailable(what + ": no answer within " + std::to_string(timeout_ms) +
                                   " ms");
      case StatusCode::kInvalidArgument:
        // The plan id as the planning service sees it; our request is otherwise well-formed.
        return Status::InvalidArgument("plan.plan_id: " + rpc.error_message());
      default:
        return s;
    }
  }
  if (response.status() != v1::PLAN_STATUS_SUCCESS) {
    return Status::FailedPrecondition(
        "plan.plan_id: " + QuoteForError(plan.plan_id()) + " is " +
        v1::PlanStatus_Name(response.status()) +
        (response.message().empty() ? "" : ": " + response.message()));
  }
  return TrajectoryFromProto(response.trajectory(), "plan.trajectory");
}

ControlService::ControlService(ControlCore* core, InputControl* input,
                               ControlServiceOptions options)
    : core_(core), input_(input), options_(options) {}

void ControlService::FillStatus(v1::ControlStatus* response) {
  ToProto(core_->GetStatus(), input_ != nullptr && input_->input_enabled(), response);
}

grpc::Status ControlService::ApplyConfigure(const v1::ControlConfigureRequest& request,
                                            const Termination& deadline,
                                            v1::ControlStatus* response) {
  Result<ControlConfig> config = ConfigFromProto(request);
  if (!config.ok()) return ToGrpcStatus(config.status());
  if (Status s = core_->Configure(*config, deadline); !s.ok()) return ToGrpcStatus(s);
  if (input_ != nullptr) {
    if (Status s = input_->SetInput(!request.disable_dds_input()); !s.ok()) return ToGrpcStatus(s);
  }
  FillStatus(response);
  return grpc::Status::OK;
}

grpc::Status ControlService::Configure(grpc::ServerContext* context,
                                       const v1::ControlConfigureRequest* request,
                                       v1::ControlStatus* response) {
  if (Status s = CheckDeadline(*context, "Configure"); !s.ok()) return ToGrpcStatus(s);
  return ApplyConfigure(*request, CallWatch(context).termination(), response);
}

grpc::Status ControlService::Arm(grpc::ServerContext* context, const v1::ArmRequest* request,
                                 v1::ControlStatus* response) {
  if (Status s = CheckDeadline(*context, "Arm"); !s.ok()) return ToGrpcStatus(s);
  if (Status s = core_->Arm(request->in_air()); !s.ok()) return ToGrpcStatus(s);
  FillStatus(response);
  return grpc::Status::OK;
}

grpc::Status ControlService::Disarm(grpc::ServerContext* context, const v1::DisarmRequest*,
                                    v1::ControlStatus* response) {
  // Always succeeds, but a late call still changes nothing (a retry must not disarm twice).
  if (Status s = CheckDeadline(*context, "Disarm"); !s.ok()) return ToGrpcStatus(s);
  core_->Disarm();
  FillStatus(response);
  return grpc::Status::OK;
}

grpc::Status ControlService::Hover(grpc::ServerContext* context, const v1::HoverRequest* request,
                                   v1::ControlStatus* response) {
  if (!request->has_position()) {
    return ToGrpcStatus(Status::InvalidArgument("position: not set"));
  }
  Result<Eigen::Vector3d> position = VectorFromProto(request->position(), "position");
  if (!position.ok()) return ToGrpcStatus(position.status());
  if (!std::isfinite(request->yaw_rad())) {
    return ToGrpcStatus(Status::InvalidArgument("yaw_rad: not finite"));
  }
  std::optional<control::GoToLimits> limits;
  if (request->has_limits()) {
    Result<control::GoToLimits> parsed = LimitsFromProto(request->limits(), "limits");
    if (!parsed.ok()) return ToGrpcStatus(parsed.status());
    limits = *parsed;
  }
  if (Status s = CheckDeadline(*context, "Hover"); !s.ok()) return ToGrpcStatus(s);
  if (Status s = core_->Hover(*position, request->yaw_rad(), limits, request->immediate());
      !s.ok()) {
    return ToGrpcStatus(s);
  }
  FillStatus(response);
  return grpc::Status::OK;
}

grpc::Status ControlService::SetTrajectory(grpc::ServerContext* context,
                                           const v1::SetTrajectoryRequest* request,
                                           v1::ControlStatus* response) {
  if (request->start_t_ns() < 0) {
    return ToGrpcStatus(Status::InvalidArgument("start_t_ns: must be >= 0 (0 = now), got " +
                                                std::to_string(request->start_t_ns())));
  }
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  if (request->has_offset()) {
    Result<Eigen::Vector3d> parsed = VectorFromProto(request->offset(), "offset");
    if (!parsed.ok()) return ToGrpcStatus(parsed.status());
    offset = *parsed;
  }
  Result<geometry::PolynomialTrajectory> trajectory = Status::Internal("no trajectory");
  switch (request->source_case()) {
    case v1::SetTrajectoryRequest::kTrajectory:
      trajectory = TrajectoryFromProto(request->trajectory(), "trajectory");
      break;
    case v1::SetTrajectoryRequest::kPlan:
      if (!core_->configured()) {
        // Fail before a network call that could not be used anyway.
        return ToGrpcStatus(Status::FailedPrecondition("not configured: call Configure first"));
      }
      trajectory = FetchPlan(request->plan(), CallWatch(context).termination(),
                             options_.planning_timeout_ms);
      break;
    case v1::SetTrajectoryRequest::SOURCE_NOT_SET:
      trajectory = Status::InvalidArgument("trajectory: set trajectory or plan");
      break;
  }
  if (!trajectory.ok()) {
    MAV_LOG(kWarning) << "SetTrajectory: " << trajectory.status().ToString();
    return ToGrpcStatus(trajectory.status());
  }
  if (Status s = CheckDeadline(*context, "SetTrajectory"); !s.ok()) return ToGrpcStatus(s);
  if (Status s =
          core_->SetTrajectory(*trajectory, request->start_t_ns(), offset, request->allow_jump());
      !s.ok()) {
    return ToGrpcStatus(s);
  }
  FillStatus(response);
  return grpc::Status::OK;
}

grpc::Status ControlService::SetGains(grpc::ServerContext* context,
                                      const v1::SetGainsRequest* request,
                                      v1::ControlStatus* response) {
  if (request->has_gains() == request->has_lee_gains()) {
    return ToGrpcStatus(
        Status::InvalidArgument("gains: set exactly one of gains (paper controller) or lee_gains"));
  }
  Status applied;
  if (request->has_gains()) {
    Result<control::PaperControllerGains> gains = PaperGainsFromProto(request->gains(), "gains");
    if (!gains.ok()) return ToGrpcStatus(gains.status());
    if (Status s = CheckDeadline(*context, "SetGains"); !s.ok()) return ToGrpcStatus(s);
    applied = core_->SetPaperGains(*gains);
  } else {
    Result<control::LeeControllerGains> gains =
        LeeGainsFromProto(request->lee_gains(), "lee_gains");
    if (!gains.ok()) return ToGrpcStatus(gains.status());
    if (Status s = CheckDeadline(*context, "SetGains"); !s.ok()) return ToGrpcStatus(s);
    applied = core_->SetLeeGains(*gains);
  }
  if (!applied.ok()) return ToGrpcStatus(applied);
  FillStatus(response);
  return grpc::Status::OK;
}

grpc::ServerUnaryReactor* ControlService::GetState(grpc::CallbackServerContext* context,
                                                   const v1::ControlGetStateRequest*,
                                                   v1::ControlState* response) {
  ToProto(core_->GetState(), response);
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
  reactor->Finish(grpc::Status::OK);
  return reactor;
}

grpc::Status ControlService::GetStatus(grpc::ServerContext*, const v1::ControlGetStatusRequest*,
                                       v1::ControlStatus* response) {
  FillStatus(response);
  return grpc::Status::OK;
}

}  // namespace mav::control_service
