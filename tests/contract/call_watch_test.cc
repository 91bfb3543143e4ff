// The one cancellation path of the services (services/common/call_watch.h): a handler's
// Termination stops when the client cancels or its deadline passes, says which, and the watch
// leaves nothing behind. A small Planning service stands in for a long RPC; the real services'
// long calls (BuildRoadmap, fresh plans, LoadMap) are cancelled in planning_contract_test.cc.

#include <atomic>
#include <chrono>
#include <future>
#include <memory>
#include <thread>

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include "mav/v1/planning.grpc.pb.h"

#include "mav/transport/grpc_server.h"
#include "services/common/call_watch.h"
#include "services/common/grpc_status.h"

namespace mav::service_common {
namespace {

// BuildRoadmap runs until its CallWatch says stop and reports how it stopped.
class LongCallService final : public v1::Planning::Service {
 public:
  grpc::Status BuildRoadmap(grpc::ServerContext* context, const v1::BuildRoadmapRequest*,
                            v1::RoadmapInfo*) override {
    const CallWatch call(context);
    started_.set_value();
    while (!call.termination().ShouldStop()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    const Status why = call.termination().Check("BuildRoadmap");
    stopped_.set_value(why);
    return ToGrpcStatus(why);
  }

  std::promise<void> started_;
  std::promise<Status> stopped_;
};

// Waits until the handler's watch is gone (it leaves after the handler reported) and says how
// many calls are still watched then.
int WatchedAfterHandlers() {
  for (int i = 0; i < 500 && CallWatch::Watched() != 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return CallWatch::Watched();
}

class CallWatchTest : public ::testing::Test {
 protected:
  void SetUp() override {
    transport::ServerOptions options;
    options.port = 0;
    auto server =
        transport::GrpcServer::Start(options, {&service_}, {v1::Planning::service_full_name()});
    ASSERT_TRUE(server.ok()) << server.status().ToString();
    server_ = std::move(*server);
    stub_ = v1::Planning::NewStub(server_->InProcessChannel());
  }
  void TearDown() override { server_->Shutdown(); }

  LongCallService service_;
  std::unique_ptr<transport::GrpcServer> server_;
  std::unique_ptr<v1::Planning::Stub> stub_;
};

TEST_F(CallWatchTest, AClientThatCancelsStopsTheCall) {
  grpc::ClientContext context;  // no deadline: only the cancellation can stop it
  std::future<void> started = service_.started_.get_future();
  std::future<Status> stopped = service_.stopped_.get_future();
  std::thread canceller([&] {
    started.wait();
    context.TryCancel();
  });
  v1::RoadmapInfo info;
  const grpc::Status status = stub_->BuildRoadmap(&context, v1::BuildRoadmapRequest(), &info);
  canceller.join();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::CANCELLED);
  // The handler saw it (a hang here is the failure: the test's ctest timeout names it).
  const Status why = stopped.get();
  EXPECT_EQ(why.code(), StatusCode::kCancelled) << why.ToString();
  EXPECT_EQ(why.message(), "BuildRoadmap: cancelled");
  EXPECT_EQ(WatchedAfterHandlers(), 0);
}

TEST_F(CallWatchTest, ACallPastItsDeadlineSaysDeadlineNotCancelled) {
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(200));
  std::future<Status> stopped = service_.stopped_.get_future();
  v1::RoadmapInfo info;
  const grpc::Status status = stub_->BuildRoadmap(&context, v1::BuildRoadmapRequest(), &info);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::DEADLINE_EXCEEDED);
  const Status why = stopped.get();
  EXPECT_EQ(why.code(), StatusCode::kDeadlineExceeded) << why.ToString();
  EXPECT_EQ(WatchedAfterHandlers(), 0);
}

TEST(CallWatchDeadline, NoDeadlineMeansNever) {
  grpc::ServerContext context;  // a context no client set a deadline on
  EXPECT_EQ(DeadlineOf(context).deadline_ns(), Termination::kNever);
}

}  // namespace
}  // namespace mav::service_common
