// mav-load control: mav.v1.Control/GetState back to back (no setup: it always succeeds, before
// the configuration too). Replies are tallied by the state's mode (DISARMED, HOVER, TRAJECTORY,
// FAILSAFE), UNCONFIGURED when the service has no configuration. The cheapest RPC of the stack:
// what its figures show is the gRPC path and the service's state lock, not an algorithm.

#include <memory>
#include <string>
#include <vector>

#include "mav/v1/control.grpc.pb.h"

#include "clients/mav-load/commands.h"
#include "clients/mav-load/load.h"

namespace mav::load {

namespace {

constexpr char kUsage[] =
    "mav-load control [--address HOST:PORT|TARGET] --concurrency C --duration S\n"
    "                        [--deadline-ms D] [--fail-on-errors] [--max-p99-ms X]\n"
    "                        [--json FILE] [--cpu-pid PID]\n\n"
    "Calls mav.v1.Control/GetState back to back; replies by the state's mode (UNCONFIGURED\n"
    "before Configure).";

std::string ModeName(const v1::ControlState& state) {
  if (!state.configured()) return "UNCONFIGURED";
  return WithoutPrefix(v1::ControlMode_Name(state.mode()), "CONTROL_MODE_");
}

}  // namespace

int RunControl(const std::vector<std::string>& args) {
  CommonOptions options;
  FlagParser flags(kUsage);
  AddCommonFlags(&flags, &options, 50055);
  if (std::optional<int> done = ParseFlags(&flags, args, options)) return *done;
  Result<std::shared_ptr<grpc::Channel>> channel = Connect(options, "mav.v1.Control");
  if (!channel.ok()) return Fail(channel.status().message());
  std::shared_ptr<v1::Control::Stub> stub = v1::Control::NewStub(*channel);
  LoadRun run;
  run.command = "control";
  run.what = "GetState";
  run.channel = *channel;
  run.call = [stub](grpc::ClientContext* context, Reply* reply) {
    v1::ControlState state;
    grpc::Status status = stub->GetState(context, v1::ControlGetStateRequest(), &state);
    if (status.ok()) reply->name = ModeName(state);
    return status;
  };
  run.async_call = [stub](grpc::ClientContext* context, Reply* reply, DoneFunction done) {
    static const v1::ControlGetStateRequest kRequest;
    auto state = std::make_shared<v1::ControlState>();
    stub->async()->GetState(context, &kRequest, state.get(),
                            [state, reply, done = std::move(done)](const grpc::Status& status) {
                              if (status.ok()) reply->name = ModeName(*state);
                              done(status);
                            });
  };
  return RunLoad(options, run);
}

}  // namespace mav::load
