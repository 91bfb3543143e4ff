#include "services/localization/localization_service.h"

#include <algorithm>
#include <chrono>
#include <filesystem>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>

#include "mav/v1/simulator.grpc.pb.h"

#include "mav/common/log.h"
#include "mav/dataset/euroc.h"
#include "mav/transport/grpc_server.h"
#include "services/common/call_watch.h"
#include "services/common/grpc_status.h"

namespace mav::localization_service {

namespace {

using service_common::CallWatch;
using service_common::CheckDeadline;
using service_common::ToGrpcStatus;

constexpr uint32_t kDefaultPosesPerChunk = 10000;
constexpr uint32_t kMaxPosesPerChunk = 100000;

}  // namespace

bool LocalizationServiceOptions::IsValid(std::string* why) const {
  if (calibration_timeout_ms <= 0 || process_timeout_ms <= 0) {
    if (why != nullptr) *why = "calibration_timeout_ms/process_timeout_ms: must be > 0";
    return false;
  }
  return true;
}

LocalizationService::LocalizationService(Localizer* localizer, InputControl* input,
                                         LocalizationServiceOptions options)
    : localizer_(localizer), input_(input), options_(options) {}

void LocalizationService::FillStatus(v1::LocalizationStatus* response) {
  const LocalizerStatus status = localizer_->GetStatus();
  ToProto(status, input_ != nullptr && input_->input_enabled(), response);
}

grpc::Status LocalizationService::ApplyConfigure(const v1::LocalizationConfigureRequest& request,
                                                 const Termination& deadline,
                                                 v1::LocalizationStatus* response) {
  Result<LocalizerConfig> config = ConfigFromProto(request);
  if (!config.ok()) return ToGrpcStatus(config.status());
  Result<RigCalibration> rig =
      ResolveCalibration(request.calibration(), options_.calibration_timeout_ms);
  if (!rig.ok()) {
    MAV_LOG(kWarning) << "Configure: " << rig.status().ToString();
    return ToGrpcStatus(rig.status());
  }
  config->odometry.calibration = rig->calibration;
  config->odometry.calibration_rectified = rig->rectified;
  if (Status s = localizer_->Configure(*config, deadline); !s.ok()) return ToGrpcStatus(s);
  if (input_ != nullptr) {
    const Status input = input_->SetInput(!request.disable_dds_input());
    if (!input.ok()) return ToGrpcStatus(input);
  }
  FillStatus(response);
  return grpc::Status::OK;
}

grpc::Status LocalizationService::Configure(grpc::ServerContext* context,
                                            const v1::LocalizationConfigureRequest* request,
                                            v1::LocalizationStatus* response) {
  if (Status s = CheckDeadline(*context, "Configure"); !s.ok()) return ToGrpcStatus(s);
  return ApplyConfigure(*request, CallWatch(context).termination(), response);
}

grpc::Status LocalizationService::Reset(grpc::ServerContext* context,
                                        const v1::LocalizationResetRequest* request,
                                        v1::LocalizationStatus* response) {
  std::optional<geometry::SE3> initial;
  if (request->has_initial_pose()) {
    Result<geometry::SE3> pose = PoseFromProto(request->initial_pose(), "initial_pose");
    if (!pose.ok()) return ToGrpcStatus(pose.status());
    initial = *pose;
  }
  if (Status s = CheckDeadline(*context, "Reset"); !s.ok()) return ToGrpcStatus(s);
  if (localizer_->configured()) {
    if (Status s = localizer_->Reset(initial, CallWatch(context).termination()); !s.ok()) {
      return ToGrpcStatus(s);
    }
  }
  FillStatus(response);
  return grpc::Status::OK;
}

grpc::Status LocalizationService::GetStatus(grpc::ServerContext*,
                                            const v1::LocalizationGetStatusRequest*,
                                            v1::LocalizationStatus* response) {
  FillStatus(response);
  return grpc::Status::OK;
}

grpc::Status LocalizationService::GetTrajectory(grpc::ServerContext* context,
                                                const v1::GetTrajectoryRequest* request,
                                                grpc::ServerWriter<v1::TrajectoryChunk>* writer) {
  if (request->start_t_ns() != 0 && request->end_t_ns() != 0 &&
      request->start_t_ns() > request->end_t_ns()) {
    return ToGrpcStatus(
        Status::InvalidArgument("start_t_ns: " + std::to_string(request->start_t_ns()) +
                                " > end_t_ns " + std::to_string(request->end_t_ns())));
  }
  if (request->max_poses_per_chunk() > kMaxPosesPerChunk) {
    return ToGrpcStatus(Status::InvalidArgument(
        "max_poses_per_chunk: must be <= " + std::to_string(kMaxPosesPerChunk) + ", got " +
        std::to_string(request->max_poses_per_chunk())));
  }
  const size_t per_chunk =
      request->max_poses_per_chunk() == 0 ? kDefaultPosesPerChunk : request->max_poses_per_chunk();
  const std::vector<RigPose> poses =
      localizer_->Trajectory(request->start_t_ns(), request->end_t_ns());
  size_t next = 0;
  do {
    if (context->IsCancelled()) return ToGrpcStatus(Status::Cancelled("GetTrajectory: cancelled"));
    v1::TrajectoryChunk chunk;
    const size_t end = std::min(poses.size(), next + per_chunk);
    for (; next < end; ++next) ToProto(poses[next], chunk.add_points());
    chunk.set_last(next == poses.size());
    if (!writer->Write(chunk)) {
      return ToGrpcStatus(Status::Cancelled("GetTrajectory: the client went away"));
    }
  } while (next < poses.size());
  return grpc::Status::OK;
}

grpc::Status LocalizationService::ProcessStereoPair(grpc::ServerContext* context,
                                                    const v1::ProcessStereoPairRequest* request,
                                                    v1::ProcessStereoPairResponse* response) {
  if (!localizer_->configured()) {
    return ToGrpcStatus(Status::FailedPrecondition("not configured: call Configure first"));
  }
  if (!request->has_stereo()) {
    return ToGrpcStatus(Status::InvalidArgument("stereo: not set"));
  }
  Result<dataset::StereoPair> pair = StereoFromProto(request->stereo(), "stereo");
  if (!pair.ok()) return ToGrpcStatus(pair.status());
  StereoInput input(std::move(*pair));
  input.publish = !request->skip_publish();
  // The client's deadline, or process_timeout_ms when it set none.
  const CallWatch call(context);
  const Termination deadline = call.termination().WithDeadlineNs(
      Termination::AfterMs(static_cast<double>(options_.process_timeout_ms)).deadline_ns());
  Result<RigPose> result = localizer_->Process(std::move(input), deadline);
  if (!result.ok()) return ToGrpcStatus(result.status());
  ToProto(*result, response);
  return grpc::Status::OK;
}

}  // namespace mav::localization_service
