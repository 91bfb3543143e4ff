// The services as processes under abuse: bursts of concurrent calls, kill -9 and a restart on the
// same port, a second server on a busy port. What a probe with an independent client checks.

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <map>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "mav/v1/localization.grpc.pb.h"
#include "mav/v1/mapping.grpc.pb.h"
#include "mav/v1/simulator.grpc.pb.h"
#include "tests/common/build_paths.h"
#include "tests/common/stack_fixture.h"

namespace mav {
namespace {

using ::mav::test_support::Child;
using ::mav::test_support::Stack;
using ::mav::test_support::WaitServing;

// Sends `n` calls at once on one channel (async, one completion queue) and counts the codes.
template <typename Stub, typename Request, typename Response>
std::map<grpc::StatusCode, int> Burst(Stub* stub, int n,
                                      std::unique_ptr<grpc::ClientAsyncResponseReader<Response>> (
                                          Stub::*start)(grpc::ClientContext*, const Request&,
                                                        grpc::CompletionQueue*),
                                      const Request& request) {
  grpc::CompletionQueue queue;
  struct Call {
    grpc::ClientContext context;
    Response response;
    grpc::Status status;
    std::unique_ptr<grpc::ClientAsyncResponseReader<Response>> reader;
  };
  std::vector<std::unique_ptr<Call>> calls;
  for (int i = 0; i < n; ++i) {
    auto call = std::make_unique<Call>();
    call->context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
    call->reader = (stub->*start)(&call->context, request, &queue);
    call->reader->Finish(&call->response, &call->status, call.get());
    calls.push_back(std::move(call));
  }
  std::map<grpc::StatusCode, int> codes;
  for (int i = 0; i < n; ++i) {
    void* tag = nullptr;
    bool ok = false;
    EXPECT_TRUE(queue.Next(&tag, &ok));
    ++codes[static_cast<Call*>(tag)->status.error_code()];
  }
  return codes;
}

TEST(RobustnessTest, BurstsKillAndRestartAndABusyPort) {
  Stack stack(/*domain_key=*/71);
  const std::string sim = stack.Start("mav-simulator", "mav.v1.Simulator");
  ASSERT_FALSE(sim.empty()) << stack.Log("mav-simulator");
  const std::string loc = stack.Start("mav-localization", "mav.v1.Localization");
  ASSERT_FALSE(loc.empty()) << stack.Log("mav-localization");
  const std::string map = stack.Start("mav-mapping", "mav.v1.Mapping");
  ASSERT_FALSE(map.empty()) << stack.Log("mav-mapping");

  // 500 concurrent calls to each service: every one answered, none lost or failed.
  auto sim_stub = v1::Simulator::NewStub(stack.Channel("mav-simulator"));
  auto loc_stub = v1::Localization::NewStub(stack.Channel("mav-localization"));
  auto map_stub = v1::Mapping::NewStub(stack.Channel("mav-mapping"));
  const auto sim_codes = Burst(sim_stub.get(), 500, &v1::Simulator::Stub::AsyncGetStatus,
                               v1::SimulatorGetStatusRequest());
  const auto loc_codes = Burst(loc_stub.get(), 500, &v1::Localization::Stub::AsyncGetStatus,
                               v1::LocalizationGetStatusRequest());
  const auto map_codes =
      Burst(map_stub.get(), 500, &v1::Mapping::Stub::AsyncGetStatus, v1::MappingGetStatusRequest());
  for (const auto* codes : {&sim_codes, &loc_codes, &map_codes}) {
    ASSERT_EQ(codes->size(), 1u);
    EXPECT_EQ(codes->begin()->first, grpc::StatusCode::OK);
    EXPECT_EQ(codes->begin()->second, 500);
  }
  // 500 calls with bad input at once: each is refused by name, none crashes the server.
  v1::LoadScenarioRequest bad;
  bad.mutable_preset()->set_name("no-such-preset");
  const auto bad_codes = Burst(sim_stub.get(), 500, &v1::Simulator::Stub::AsyncLoadScenario, bad);
  ASSERT_EQ(bad_codes.size(), 1u);
  EXPECT_EQ(bad_codes.begin()->first, grpc::StatusCode::INVALID_ARGUMENT);

  // A second server on a busy port fails at once, naming the address.
  const std::string port = sim.substr(sim.rfind(':') + 1);
  Child second({mav::testing::BinaryDir() + "/bin/mav-simulator", "--port", port, "--dds-domain",
                std::to_string(stack.domain())},
               stack.Log("mav-simulator") + ".second");
  EXPECT_EQ(second.Wait(std::chrono::seconds(10)), std::optional<int>(1));
  EXPECT_TRUE(WaitServing(sim, "mav.v1.Simulator")) << "the first server must keep serving";

  // kill -9, then a restart on the same port serves again.
  stack.Process("mav-simulator")->Signal(SIGKILL);
  EXPECT_TRUE(stack.Process("mav-simulator")->Wait(std::chrono::seconds(10)).has_value());
  Child restarted({mav::testing::BinaryDir() + "/bin/mav-simulator", "--port", port, "--dds-domain",
                   std::to_string(stack.domain())},
                  stack.Log("mav-simulator") + ".restarted");
  ASSERT_TRUE(restarted.running());
  EXPECT_TRUE(WaitServing(sim, "mav.v1.Simulator"))
      << "see " << stack.Log("mav-simulator") << ".restarted";
  restarted.Signal(SIGTERM);
  EXPECT_EQ(restarted.Wait(std::chrono::seconds(10)), std::optional<int>(0));
}

}  // namespace
}  // namespace mav
