#pragma once
// The gRPC Localization service (protos/mav/v1/localization.proto): a thin adapter from RPCs to
// the Localizer (pipeline.h). Status codes follow docs/contracts.md: INVALID_ARGUMENT naming the
// field (unknown method, options out of range, bad calibration, malformed images), NOT_FOUND for
// a missing EuRoC calibration, UNAVAILABLE / FAILED_PRECONDITION from a simulator calibration
// source, FAILED_PRECONDITION for ProcessStereoPair before Configure, RESOURCE_EXHAUSTED when the
// input queue is full.

#include <cstdint>
#include <string>

#include "mav/v1/localization.grpc.pb.h"

#include "mav/common/status.h"
#include "services/common/calibration_source.h"
#include "services/localization/convert.h"
#include "services/localization/dds_io.h"
#include "services/localization/localizer.h"

namespace mav::localization_service {

struct LocalizationServiceOptions {
  // Deadline of the GetCalibration call to a simulator calibration source (contract: 2 s).
  int64_t calibration_timeout_ms = 2000;
  // Longest a ProcessStereoPair waits for its frame when the client set no deadline (it is then
  // withdrawn if it had not started).
  int64_t process_timeout_ms = 30000;

  bool IsValid(std::string* why) const;
};

using service_common::ResolveCalibration;  // services/common/calibration_source.h

class LocalizationService final : public v1::Localization::Service {
 public:
  // `localizer` (not owned) must outlive the service; `input` (not owned, may be null: no live
  // input, e.g. in tests) is switched on by Configure unless disable_dds_input.
  LocalizationService(Localizer* localizer, InputControl* input,
                      LocalizationServiceOptions options = {});

  grpc::Status Configure(grpc::ServerContext* context,
                         const v1::LocalizationConfigureRequest* request,
                         v1::LocalizationStatus* response) override;
  grpc::Status Reset(grpc::ServerContext* context, const v1::LocalizationResetRequest* request,
                     v1::LocalizationStatus* response) override;
  grpc::Status GetStatus(grpc::ServerContext* context,
                         const v1::LocalizationGetStatusRequest* request,
                         v1::LocalizationStatus* response) override;
  grpc::Status GetTrajectory(grpc::ServerContext* context, const v1::GetTrajectoryRequest* request,
                             grpc::ServerWriter<v1::TrajectoryChunk>* writer) override;
  grpc::Status ProcessStereoPair(grpc::ServerContext* context,
                                 const v1::ProcessStereoPairRequest* request,
                                 v1::ProcessStereoPairResponse* response) override;

  // Configure without an RPC (main.cc's start-up flags) or with the call's deadline.
  grpc::Status ApplyConfigure(const v1::LocalizationConfigureRequest& request,
                              const Termination& deadline, v1::LocalizationStatus* response);

 private:
  void FillStatus(v1::LocalizationStatus* response);

  Localizer* localizer_;
  InputControl* input_;
  LocalizationServiceOptions options_;
};

}  // namespace mav::localization_service
