#pragma once
// The gRPC Control service (protos/mav/v1/control.proto): a thin adapter from RPCs to the
// ControlCore (control_core.h). Status codes follow docs/contracts.md: INVALID_ARGUMENT naming the
// field, FAILED_PRECONDITION for calls in the wrong state (not configured, armed, disarmed, not
// converged), NOT_FOUND for an unknown plan id, UNAVAILABLE when the planning service cannot be
// reached. Every state-changing handler validates its request, then checks the client's deadline
// (a call whose deadline passed changes nothing), then changes the state.

#include <cstdint>
#include <string>

#include "mav/v1/control.grpc.pb.h"

#include "mav/common/status.h"
#include "services/control/control_core.h"
#include "services/control/convert.h"
#include "services/control/dds_io.h"

namespace mav::control_service {

struct ControlServiceOptions {
  // Longest a SetTrajectory waits for Planning.GetPlan (the client's deadline, if earlier, wins).
  int64_t planning_timeout_ms = 2000;

  bool IsValid(std::string* why) const;
};

// The spline of a plan held by a Planning service (Planning.GetPlan), converted and validated:
// InvalidArgument "plan.planning_address: empty" / "plan.plan_id: empty"; NotFound for an
// unknown id; Unavailable when the service cannot be reached or does not answer in time;
// FailedPrecondition for a plan that did not succeed; InvalidArgument "plan.trajectory...." for
// a malformed spline.
Result<geometry::PolynomialTrajectory> FetchPlan(const v1::PlanRef& plan,
                                                 const Termination& deadline, int64_t timeout_ms);

class ControlService final : public v1::Control::WithCallbackMethod_GetState<v1::Control::Service> {
 public:
  // `core` (not owned) must outlive the service; `input` (not owned, may be null: no live input,
  // e.g. in tests) is switched on by Configure unless disable_dds_input.
  ControlService(ControlCore* core, InputControl* input, ControlServiceOptions options = {});

  grpc::Status Configure(grpc::ServerContext* context, const v1::ControlConfigureRequest* request,
                         v1::ControlStatus* response) override;
  grpc::Status Arm(grpc::ServerContext* context, const v1::ArmRequest* request,
                   v1::ControlStatus* response) override;
  grpc::Status Disarm(grpc::ServerContext* context, const v1::DisarmRequest* request,
                      v1::ControlStatus* response) override;
  grpc::Status Hover(grpc::ServerContext* context, const v1::HoverRequest* request,
                     v1::ControlStatus* response) override;
  grpc::Status SetTrajectory(grpc::ServerContext* context, const v1::SetTrajectoryRequest* request,
                             v1::ControlStatus* response) override;
  grpc::Status SetGains(grpc::ServerContext* context, const v1::SetGainsRequest* request,
                        v1::ControlStatus* response) override;
  // On gRPC's callback API: answered on the thread that read the call (a copy of the state under
  // the core's lock), without the sync server's hand-off to a worker thread.
  grpc::ServerUnaryReactor* GetState(grpc::CallbackServerContext* context,
                                     const v1::ControlGetStateRequest* request,
                                     v1::ControlState* response) override;
  grpc::Status GetStatus(grpc::ServerContext* context, const v1::ControlGetStatusRequest* request,
                         v1::ControlStatus* response) override;

  // Configure without an RPC (main.cc's start-up flags) or with the call's deadline.
  grpc::Status ApplyConfigure(const v1::ControlConfigureRequest& request,
                              const Termination& deadline, v1::ControlStatus* response);

 private:
  void FillStatus(v1::ControlStatus* response);

  ControlCore* core_;
  InputControl* input_;
  ControlServiceOptions options_;
};

}  // namespace mav::control_service
