// mav.v1.Planning: every RPC with good and bad input (the field named), through an in-process
// channel and a real loopback port (health), deadlines (a late LoadMap, BuildRoadmap or PlanPath
// changes nothing), the limits (plans in flight, one long operation, map memory, milestones,
// upload size, samples), many plans at once while the roadmap is rebuilt, and a map loaded from
// a running mapping service (a fake mav.v1.Mapping on a loopback port serving a .bt).
// Maps: a hand-made 10 x 10 x 5 m room at 0.25 m (fast), and maps/power_plant.bt with
// a small roadmap where the real map matters.

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>

#include "mav/v1/mapping.grpc.pb.h"
#include "mav/v1/planning.grpc.pb.h"

#include "mav/common/file.h"
#include "mav/common/time.h"
#include "mav/dataset/occupancy_io.h"
#include "mav/transport/grpc_server.h"
#include "services/planning/planner_core.h"
#include "services/planning/planning_service.h"
#include "tests/common/build_paths.h"
#include "tests/common/contract_server.h"

namespace mav::planning_service {
namespace {

using grpc::StatusCode;

using ::mav::test_support::StartOnFreePort;  // tests/common/contract_server.h

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
const std::string kPowerPlant = mav::testing::SourceDir() + "/maps/power_plant.bt";

std::chrono::system_clock::time_point Deadline(double seconds) {
  return std::chrono::system_clock::now() +
         std::chrono::microseconds(static_cast<int64_t>(seconds * 1e6));
}

std::string TestDir() {
  std::string dir = mav::testing::BinaryDir() + "/Testing/planning_contract";
  EXPECT_TRUE(MakeDirectories(dir).ok());
  return dir;
}

// The room: free inside 10 x 10 x 5 m, a wall x in [4, 6], y in [0, 7] over the whole height (a
// 3 m gap beyond y = 7), as OctoMap .bt bytes.
const std::string& RoomBytes() {
  static const std::string* bytes = [] {
    dataset::GridGeometry g;
    g.origin = Eigen::Vector3d::Zero();
    g.resolution = 0.25;
    g.size = Eigen::Vector3i(40, 40, 20);
    dataset::OccupancyGrid grid(g, dataset::VoxelState::kFree);
    for (int k = 0; k < 20; ++k) {
      for (int j = 0; j < 28; ++j) {
        for (int i = 16; i < 24; ++i) grid.set({i, j, k}, dataset::VoxelState::kOccupied);
      }
    }
    Result<std::string> encoded = dataset::EncodeOctomapBt(grid);
    MAV_CHECK(encoded.ok()) << encoded.status().ToString();
    return new std::string(*encoded);
  }();
  return *bytes;
}

const std::string& RoomPath() {
  static const std::string path = [] {
    std::string p = TestDir() + "/room.bt";
    MAV_CHECK(WriteStringToFileAtomic(p, RoomBytes()).ok());
    return p;
  }();
  return path;
}

void Set(v1::Vector3* v, double x, double y, double z) {
  v->set_x(x);
  v->set_y(y);
  v->set_z(z);
}

// Around the wall of the room.
v1::PlanPathRequest RoomQuery() {
  v1::PlanPathRequest r;
  Set(r.mutable_start(), 2, 2, 2.5);
  Set(r.mutable_goal(), 8, 2, 2.5);
  return r;
}

// Expects `status` to have `code` and a message starting with `prefix`.
void ExpectError(const grpc::Status& status, StatusCode code, const std::string& prefix) {
  EXPECT_EQ(status.error_code(), code) << status.error_message();
  EXPECT_EQ(status.error_message().rfind(prefix, 0), 0u)
      << "message '" << status.error_message() << "' does not start with '" << prefix << "'";
}

// Calls `call` until it is no longer refused as busy (RESOURCE_EXHAUSTED: the worker is still
// finishing an operation that gave up), for at most `limit_ms`; *waited_ms is how long it took.
grpc::Status WhenNotBusy(const std::function<grpc::Status()>& call, double limit_ms,
                         double* waited_ms) {
  const int64_t start = MonotonicNowNs();
  grpc::Status status = call();
  while (status.error_code() == StatusCode::RESOURCE_EXHAUSTED && MsSince(start) < limit_ms) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    status = call();
  }
  *waited_ms = MsSince(start);
  return status;
}

// Cancels `context` after `ms` on a thread of its own (join it).
std::thread CancelAfter(grpc::ClientContext* context, int ms) {
  return std::thread([context, ms] {
    std::this_thread::sleep_for(std::chrono::milliseconds(ms));
    context->TryCancel();
  });
}

// A Mapping service whose GetOccupancy streams `bytes` (NOT_FOUND for OCTOMAP), or, when
// `broken`, chunks with a gap.
class FakeMapping final : public v1::Mapping::Service {
 public:
  FakeMapping(std::string bytes, bool broken) : bytes_(std::move(bytes)), broken_(broken) {}
  grpc::Status GetOccupancy(grpc::ServerContext*, const v1::GetOccupancyRequest* request,
                            grpc::ServerWriter<v1::OccupancyChunk>* writer) override {
    calls_.fetch_add(1);
    if (request->format() != v1::OCCUPANCY_FORMAT_OCTOMAP_BT) {
      return grpc::Status(StatusCode::INVALID_ARGUMENT, "format: the planner wants OCTOMAP_BT");
    }
    if (request->method() == v1::MAPPING_METHOD_OCTOMAP) {
      return grpc::Status(StatusCode::NOT_FOUND, "no octomap map has been built");
    }
    const size_t n = bytes_.size() / 3 + 1;  // three chunks
    for (size_t offset = 0; offset < bytes_.size(); offset += n) {
      v1::OccupancyChunk message;
      v1::FileChunk* chunk = message.mutable_chunk();
      chunk->set_offset(broken_ && offset > 0 ? offset + 1 : offset);
      chunk->set_total_size(bytes_.size());
      chunk->set_data(bytes_.substr(offset, n));
      chunk->set_last(offset + n >= bytes_.size());
      if (!writer->Write(message)) break;
    }
    return grpc::Status::OK;
  }
  int calls() const { return calls_.load(); }

 private:
  std::string bytes_;
  bool broken_;
  std::atomic<int> calls_{0};
};

class PlanningContractTest : public ::testing::Test {
 protected:
  void SetUp() override { Start({}, {}); }
  void TearDown() override { Stop(); }

  void Start(PlannerCoreOptions core_options, PlanningServiceOptions service_options) {
    if (core_options.max_plans_in_flight == 0) core_options.max_plans_in_flight = 64;
    core_ = std::make_unique<PlannerCore>(core_options);
    service_ = std::make_unique<PlanningService>(core_.get(), service_options);
    server_ = StartOnFreePort<v1::Planning>(service_.get());
    ASSERT_NE(server_, nullptr);
    stub_ = v1::Planning::NewStub(server_->InProcessChannel());
  }
  void Stop() {
    if (server_) server_->Shutdown();
    if (core_) core_->Shutdown();
    stub_.reset();
    server_.reset();
    service_.reset();
    core_.reset();
  }

  grpc::Status LoadMap(const v1::LoadMapRequest& request, v1::MapInfo* info = nullptr,
                       double deadline_s = 30) {
    grpc::ClientContext context;
    context.set_deadline(Deadline(deadline_s));
    v1::MapInfo ignored;
    return stub_->LoadMap(&context, request, info != nullptr ? info : &ignored);
  }
  grpc::Status LoadFile(const std::string& path, v1::MapInfo* info = nullptr) {
    v1::LoadMapRequest request;
    request.mutable_file()->set_path(path);
    return LoadMap(request, info);
  }
  grpc::Status Build(const v1::BuildRoadmapRequest& request, v1::RoadmapInfo* info = nullptr,
                     double deadline_s = 60) {
    grpc::ClientContext context;
    context.set_deadline(Deadline(deadline_s));
    v1::RoadmapInfo ignored;
    return stub_->BuildRoadmap(&context, request, info != nullptr ? info : &ignored);
  }
  grpc::Status BuildSmall(uint32_t milestones = 3000, uint64_t seed = 1) {
    v1::BuildRoadmapRequest request;
    request.set_max_milestones(milestones);
    request.set_seed(seed);
    return Build(request);
  }
  grpc::Status Plan(const v1::PlanPathRequest& request, v1::PlanPathResponse* response = nullptr,
                    double deadline_s = 10) {
    grpc::ClientContext context;
    context.set_deadline(Deadline(deadline_s));
    v1::PlanPathResponse ignored;
    return stub_->PlanPath(&context, request, response != nullptr ? response : &ignored);
  }
  grpc::Status GetPlan(const std::string& id, v1::PlanPathResponse* response) {
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    v1::GetPlanRequest request;
    request.set_plan_id(id);
    return stub_->GetPlan(&context, request, response);
  }
  grpc::Status Sample(const v1::SampleTrajectoryRequest& request,
                      v1::SampleTrajectoryResponse* response) {
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    return stub_->SampleTrajectory(&context, request, response);
  }
  v1::PlanningStatus Status() {
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    v1::PlanningStatus status;
    EXPECT_TRUE(stub_->GetRoadmapStatus(&context, v1::GetRoadmapStatusRequest(), &status).ok());
    return status;
  }
  // Polls until no plan is in flight, for `limit_ms` at most (a liveness bound: a plan whose
  // work was not stopped stays in flight for its whole budget). True when none is.
  bool WaitUntilNoPlanInFlight(double limit_ms) {
    const int64_t start = MonotonicNowNs();
    while (Status().plans_in_flight() > 0 && MsSince(start) < limit_ms) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return Status().plans_in_flight() == 0;
  }
  grpc::Status Upload(const std::vector<v1::UploadMapRequest>& messages,
                      v1::MapInfo* info = nullptr) {
    grpc::ClientContext context;
    context.set_deadline(Deadline(30));
    v1::MapInfo ignored;
    auto writer = stub_->UploadMap(&context, info != nullptr ? info : &ignored);
    for (const auto& m : messages) {
      if (!writer->Write(m)) break;
    }
    writer->WritesDone();
    return writer->Finish();
  }
  // The room as five upload messages; options in the first.
  static std::vector<v1::UploadMapRequest> RoomUpload() {
    const std::string& bytes = RoomBytes();
    const size_t chunk = bytes.size() / 5 + 1;
    std::vector<v1::UploadMapRequest> messages;
    for (size_t offset = 0; offset < bytes.size(); offset += chunk) {
      v1::UploadMapRequest m;
      if (offset == 0) m.mutable_options()->set_robot_radius_m(0.5);
      m.mutable_chunk()->set_offset(offset);
      m.mutable_chunk()->set_total_size(bytes.size());
      m.mutable_chunk()->set_data(bytes.substr(offset, chunk));
      m.mutable_chunk()->set_last(offset + chunk >= bytes.size());
      messages.push_back(m);
    }
    return messages;
  }

  std::unique_ptr<PlannerCore> core_;
  std::unique_ptr<PlanningService> service_;
  std::unique_ptr<transport::GrpcServer> server_;
  std::unique_ptr<v1::Planning::Stub> stub_;
};

TEST_F(PlanningContractTest, StatusBeforeAnythingAndWithoutAMap) {
  const v1::PlanningStatus s = Status();
  EXPECT_FALSE(s.map_loaded());
  EXPECT_FALSE(s.roadmap_ready());
  EXPECT_FALSE(s.busy());
  EXPECT_EQ(s.plan_history(), 16u);
  EXPECT_EQ(s.max_plans_in_flight(), 64u);
  ExpectError(Plan(RoomQuery()), StatusCode::FAILED_PRECONDITION, "no map");
  ExpectError(BuildSmall(), StatusCode::FAILED_PRECONDITION, "no map");
  v1::LoadRoadmapRequest load;
  load.set_path(TestDir() + "/none.mavprm");
  grpc::ClientContext context;
  v1::RoadmapInfo info;
  ExpectError(stub_->LoadRoadmap(&context, load, &info), StatusCode::FAILED_PRECONDITION, "no map");
  EXPECT_EQ(Status().plans_failed(), 1u);
}

TEST_F(PlanningContractTest, LoadMapFromAFile) {
  v1::MapInfo info;
  ASSERT_TRUE(LoadFile(RoomPath(), &info).ok());
  EXPECT_DOUBLE_EQ(info.resolution_m(), 0.25);
  EXPECT_EQ(info.source(), RoomPath());
  EXPECT_NEAR(info.bounds().max().x(), 10, 1e-9);
  EXPECT_NEAR(info.planning_bounds().max().z(), 5, 1e-9);
  EXPECT_GT(info.occupied_voxels(), 0u);
  EXPECT_GT(info.free_voxels(), 0u);
  EXPECT_GT(info.unknown_voxels(), 0u);  // the shell around the map
  EXPECT_GT(info.memory_bytes(), 0u);
  EXPECT_NE(info.fingerprint(), 0u);
  EXPECT_DOUBLE_EQ(info.robot_radius_m(), 0.5);
  EXPECT_EQ(info.distance_method(), v1::DISTANCE_METHOD_EXACT);
  const v1::PlanningStatus s = Status();
  EXPECT_TRUE(s.map_loaded());
  EXPECT_EQ(s.map().fingerprint(), info.fingerprint());
  EXPECT_FALSE(s.roadmap_ready());
}

TEST_F(PlanningContractTest, LoadMapBadInputNamesTheField) {
  v1::LoadMapRequest r;
  ExpectError(LoadMap(r), StatusCode::INVALID_ARGUMENT, "source: not set");
  r.mutable_file()->set_path("");
  ExpectError(LoadMap(r), StatusCode::INVALID_ARGUMENT, "file.path: empty");
  r.mutable_mapping()->set_address("");
  ExpectError(LoadMap(r), StatusCode::INVALID_ARGUMENT, "mapping.address: empty");
  r.mutable_file()->set_path(RoomPath());
  r.mutable_options()->set_robot_radius_m(11);
  ExpectError(LoadMap(r), StatusCode::INVALID_ARGUMENT, "options.robot_radius_m: ");
  r.mutable_options()->set_robot_radius_m(-1);
  ExpectError(LoadMap(r), StatusCode::INVALID_ARGUMENT, "options.robot_radius_m: ");
  r.mutable_options()->set_robot_radius_m(0);
  r.mutable_options()->set_max_distance_m(kNaN);
  ExpectError(LoadMap(r), StatusCode::INVALID_ARGUMENT, "options.max_distance_m: ");
  r.mutable_options()->set_max_distance_m(0.3);
  ExpectError(LoadMap(r), StatusCode::INVALID_ARGUMENT, "options.max_distance_m: ");
  r.mutable_options()->set_max_distance_m(0);
  Set(r.mutable_options()->mutable_bounds()->mutable_min(), kNaN, 0, 0);
  Set(r.mutable_options()->mutable_bounds()->mutable_max(), 5, 5, 5);
  ExpectError(LoadMap(r), StatusCode::INVALID_ARGUMENT, "options.bounds.min.x: not finite");
  Set(r.mutable_options()->mutable_bounds()->mutable_min(), 1, 6, 1);
  ExpectError(LoadMap(r), StatusCode::INVALID_ARGUMENT, "options.bounds: min.y 6 > max.y 5");
  Set(r.mutable_options()->mutable_bounds()->mutable_min(), 1, 5, 1);  // ordered, but flat
  ExpectError(LoadMap(r), StatusCode::INVALID_ARGUMENT, "options.bounds.max: must exceed");
  r.mutable_options()->clear_bounds();
  r.mutable_options()->set_distance_method(static_cast<v1::DistanceMethod>(9));
  ExpectError(LoadMap(r), StatusCode::INVALID_ARGUMENT, "options.distance_method: unknown");
  EXPECT_FALSE(Status().map_loaded());
}

TEST_F(PlanningContractTest, LoadMapMissingAndCorruptFiles) {
  ExpectError(LoadFile(TestDir() + "/missing.bt"), StatusCode::NOT_FOUND, "");
  const std::string corrupt = TestDir() + "/corrupt.bt";
  ASSERT_TRUE(WriteStringToFileAtomic(corrupt, RoomBytes().substr(0, RoomBytes().size() / 2)).ok());
  const grpc::Status s = LoadFile(corrupt);
  EXPECT_EQ(s.error_code(), StatusCode::DATA_LOSS) << s.error_message();
  EXPECT_NE(s.error_message().find("corrupt.bt"), std::string::npos) << s.error_message();
  EXPECT_FALSE(Status().map_loaded());
  EXPECT_NE(Status().last_error().find("corrupt.bt"), std::string::npos);
}

TEST_F(PlanningContractTest, MapAboveTheMemoryLimitIsRefusedBeforeAllocating) {
  Stop();
  PlannerCoreOptions options;
  options.max_map_memory_bytes = 100000;  // the room's grids need ~0.5 MB
  Start(options, {});
  const grpc::Status s = LoadFile(RoomPath());
  EXPECT_EQ(s.error_code(), StatusCode::RESOURCE_EXHAUSTED) << s.error_message();
  EXPECT_FALSE(Status().map_loaded());
}

TEST_F(PlanningContractTest, LoadMapStoppedByItsDeadlineKeepsTheOldMap) {
  ASSERT_TRUE(LoadFile(RoomPath()).ok());
  const uint64_t room = Status().map().fingerprint();
  // DynamicEDT3D on the power plant takes seconds: a 300 ms deadline stops it.
  v1::LoadMapRequest r;
  r.mutable_file()->set_path(kPowerPlant);
  r.mutable_options()->set_distance_method(v1::DISTANCE_METHOD_DYNAMIC_EDT3D);
  const grpc::Status s = LoadMap(r, nullptr, 0.3);
  EXPECT_EQ(s.error_code(), StatusCode::DEADLINE_EXCEEDED) << s.error_message();
  EXPECT_EQ(Status().map().fingerprint(), room);
  // The worker stops at the library's next poll (DynamicEDT3D's transform is one call, ~3 s
  // here); the late map is dropped, and the next long operation is accepted after it.
  double waited_ms = 0;
  const grpc::Status next = WhenNotBusy([&] { return LoadFile(RoomPath()); }, 20000, &waited_ms);
  EXPECT_TRUE(next.ok()) << next.error_message();
  EXPECT_EQ(Status().map().fingerprint(), room);
  EXPECT_EQ(Status().map().distance_method(), v1::DISTANCE_METHOD_EXACT);
}

TEST_F(PlanningContractTest, UploadMap) {
  v1::MapInfo info;
  ASSERT_TRUE(Upload(RoomUpload(), &info).ok());
  EXPECT_EQ(info.source(), "upload");
  v1::MapInfo from_file;
  ASSERT_TRUE(LoadFile(RoomPath(), &from_file).ok());
  EXPECT_EQ(info.fingerprint(), from_file.fingerprint());

  auto messages = RoomUpload();
  messages[0].clear_options();
  ExpectError(Upload(messages), StatusCode::INVALID_ARGUMENT, "options: not set");
  messages = RoomUpload();
  messages[2].mutable_chunk()->set_offset(messages[2].chunk().offset() + 1);
  ExpectError(Upload(messages), StatusCode::INVALID_ARGUMENT, "chunk[2].offset: ");
  messages = RoomUpload();
  messages[1].mutable_chunk()->set_total_size(7);
  ExpectError(Upload(messages), StatusCode::INVALID_ARGUMENT, "chunk[1].total_size: ");
  messages = RoomUpload();
  messages.pop_back();
  ExpectError(Upload(messages), StatusCode::INVALID_ARGUMENT, "chunk: ");
  messages = RoomUpload();
  messages[1].mutable_options()->set_robot_radius_m(1);
  ExpectError(Upload(messages), StatusCode::INVALID_ARGUMENT, "options: only allowed");
  ExpectError(Upload({}), StatusCode::INVALID_ARGUMENT, "options: the stream is empty");

  // Not an OctoMap: DATA_LOSS naming the upload.
  v1::UploadMapRequest junk;
  junk.mutable_options();
  junk.mutable_chunk()->set_total_size(13);
  junk.mutable_chunk()->set_data("not a octree!");
  junk.mutable_chunk()->set_last(true);
  const grpc::Status s = Upload({junk});
  EXPECT_EQ(s.error_code(), StatusCode::DATA_LOSS) << s.error_message();
  EXPECT_NE(s.error_message().find("upload"), std::string::npos) << s.error_message();
  EXPECT_EQ(Status().map().fingerprint(), from_file.fingerprint());
}

TEST_F(PlanningContractTest, UploadAboveTheLimitIsRefusedOnTheFirstChunk) {
  Stop();
  PlanningServiceOptions options;
  options.max_upload_bytes = RoomBytes().size() - 1;
  Start({}, options);
  ExpectError(Upload(RoomUpload()), StatusCode::RESOURCE_EXHAUSTED, "chunk.total_size: ");
  EXPECT_FALSE(Status().map_loaded());
}

TEST_F(PlanningContractTest, BuildRoadmapGoodAndBadInput) {
  ASSERT_TRUE(LoadFile(RoomPath()).ok());
  v1::BuildRoadmapRequest r;
  r.set_time_budget_s(-1);
  ExpectError(Build(r), StatusCode::INVALID_ARGUMENT, "time_budget_s: ");
  r.set_time_budget_s(700);
  ExpectError(Build(r), StatusCode::INVALID_ARGUMENT, "time_budget_s: ");
  r.set_time_budget_s(kNaN);
  ExpectError(Build(r), StatusCode::INVALID_ARGUMENT, "time_budget_s: ");
  r.set_time_budget_s(0);
  r.set_clearance_margin_m(2);
  ExpectError(Build(r), StatusCode::INVALID_ARGUMENT, "clearance_margin_m: ");
  r.clear_clearance_margin_m();
  r.set_validity_resolution_m(0.5);  // coarser than the 0.25 m map
  ExpectError(Build(r), StatusCode::INVALID_ARGUMENT, "validity_resolution_m");
  r.set_validity_resolution_m(0);
  r.set_max_milestones(300000);  // above the server's 200 000
  ExpectError(Build(r), StatusCode::RESOURCE_EXHAUSTED, "max_milestones: ");
  EXPECT_FALSE(Status().roadmap_ready());

  r.set_max_milestones(2000);
  r.set_seed(5);
  r.set_clearance_margin_m(0);  // explicit 0: no margin
  v1::RoadmapInfo info;
  ASSERT_TRUE(Build(r, &info).ok());
  EXPECT_EQ(info.milestones(), 2000u);
  EXPECT_GT(info.edges(), 2000u);
  EXPECT_EQ(info.seed(), 5u);
  EXPECT_GT(info.largest_component(), 1000u);
  EXPECT_GT(info.memory_bytes(), 0u);
  EXPECT_GT(info.build_s(), 0);
  EXPECT_DOUBLE_EQ(info.clearance_margin_m(), 0);
  EXPECT_DOUBLE_EQ(info.robot_radius_m(), 0.5);
  EXPECT_EQ(info.source(), "built");
  const v1::PlanningStatus s = Status();
  ASSERT_TRUE(s.roadmap_ready());
  EXPECT_EQ(s.roadmap().map_fingerprint(), s.map().fingerprint());
  EXPECT_EQ(s.roadmap().milestones(), 2000u);
  // A new map drops the roadmap.
  ASSERT_TRUE(LoadFile(RoomPath()).ok());
  EXPECT_FALSE(Status().roadmap_ready());
}

// A long build: a second long operation is refused while it runs, plans go on with the previous
// roadmap, progress shows, and the client's deadline stops it with nothing kept.
TEST_F(PlanningContractTest, BuildRoadmapStoppedByItsDeadlineKeepsNothing) {
  ASSERT_TRUE(LoadFile(RoomPath()).ok());
  ASSERT_TRUE(BuildSmall(2000, 1).ok());
  const v1::RoadmapInfo before = Status().roadmap();
  grpc::Status long_build;
  std::thread builder([&] {
    v1::BuildRoadmapRequest r;
    r.set_max_milestones(200000);  // ~tens of seconds on this room
    r.set_seed(2);
    long_build = Build(r, nullptr, 1.5);
  });
  v1::PlanningStatus s;
  for (int i = 0; i < 200 && !s.roadmap_building(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    s = Status();
  }
  ASSERT_TRUE(s.roadmap_building());
  EXPECT_TRUE(s.busy());
  EXPECT_EQ(s.operation(), "BuildRoadmap");
  ExpectError(BuildSmall(), StatusCode::RESOURCE_EXHAUSTED,
              "BuildRoadmap: BuildRoadmap is running");
  ExpectError(LoadFile(RoomPath()), StatusCode::RESOURCE_EXHAUSTED,
              "LoadMap: BuildRoadmap is running");
  ExpectError(Upload(RoomUpload()), StatusCode::RESOURCE_EXHAUSTED, "UploadMap: ");
  v1::PlanPathResponse plan;
  ASSERT_TRUE(Plan(RoomQuery(), &plan).ok());
  EXPECT_EQ(plan.status(), v1::PLAN_STATUS_SUCCESS) << plan.message();
  EXPECT_TRUE(plan.used_roadmap());
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  s = Status();
  EXPECT_EQ(s.build_progress().stage(), "roadmap");
  EXPECT_GT(s.build_progress().elapsed_s(), 0.2);
  builder.join();
  EXPECT_EQ(long_build.error_code(), StatusCode::DEADLINE_EXCEEDED) << long_build.error_message();
  s = Status();
  ASSERT_TRUE(s.roadmap_ready());
  EXPECT_EQ(s.roadmap().seed(), before.seed());
  EXPECT_EQ(s.roadmap().milestones(), before.milestones());
  // The worker stops at its next poll: the slot frees within a second.
  double waited_ms = 0;
  // The next poll, not the end of a tens-of-seconds build: within 3 s the slot is free.
  const grpc::Status next = WhenNotBusy([&] { return BuildSmall(1000, 3); }, 3000, &waited_ms);
  EXPECT_TRUE(next.ok()) << next.error_message() << " after " << waited_ms << " ms";
  EXPECT_EQ(Status().roadmap().seed(), 3u);
}

// A client that cancels its BuildRoadmap stops the build (nothing kept, the slot frees at once),
// and a server shutting down does not wait for a long build beyond its grace period.
TEST_F(PlanningContractTest, CancelledBuildAndShutdownDuringABuild) {
  ASSERT_TRUE(LoadFile(RoomPath()).ok());
  v1::BuildRoadmapRequest r;
  r.set_max_milestones(200000);
  {
    grpc::ClientContext context;
    context.set_deadline(Deadline(60));
    std::thread canceller = CancelAfter(&context, 300);
    v1::RoadmapInfo info;
    const grpc::Status s = stub_->BuildRoadmap(&context, r, &info);
    canceller.join();
    EXPECT_EQ(s.error_code(), StatusCode::CANCELLED) << s.error_message();
  }
  double waited_ms = 0;
  const grpc::Status next = WhenNotBusy([&] { return BuildSmall(1000, 3); }, 3000, &waited_ms);
  EXPECT_TRUE(next.ok()) << next.error_message() << " after " << waited_ms << " ms";
  EXPECT_EQ(Status().roadmap().seed(), 3u);

  // Shutdown with a 200 ms grace while a build runs: the build's call is cancelled by the
  // server, the handler returns, and the server stops well before the build would end.
  Stop();
  Start({}, {});
  ASSERT_TRUE(LoadFile(RoomPath()).ok());
  server_->Shutdown();
  transport::ServerOptions options;
  options.port = 0;
  options.shutdown_grace_ms = 200;
  auto server = transport::GrpcServer::Start(options, {service_.get()});
  ASSERT_TRUE(server.ok());
  server_ = std::move(*server);
  stub_ = v1::Planning::NewStub(server_->InProcessChannel());
  grpc::Status long_build;
  std::thread builder([&] { long_build = Build(r, nullptr, 60); });
  for (int i = 0; i < 200 && !Status().roadmap_building(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  server_->Shutdown();
  builder.join();
  EXPECT_FALSE(long_build.ok());
  // The build was stopped, not waited out: no roadmap came of it.
  EXPECT_EQ(core_->GetStatus().snapshot->roadmap, nullptr);
}

// A fresh PRM* (no roadmap, a 10 s budget) stops when its client cancels.
TEST_F(PlanningContractTest, CancelledFreshPlanStops) {
  ASSERT_TRUE(LoadFile(RoomPath()).ok());
  v1::PlanPathRequest r = RoomQuery();
  r.set_use_roadmap(false);
  r.set_time_budget_s(10);
  grpc::ClientContext context;
  context.set_deadline(Deadline(60));
  std::thread canceller = CancelAfter(&context, 200);
  v1::PlanPathResponse p;
  const grpc::Status s = stub_->PlanPath(&context, r, &p);
  canceller.join();
  EXPECT_EQ(s.error_code(), StatusCode::CANCELLED) << s.error_message();
  // The PRM* stops at its next poll, long before its 10 s budget.
  EXPECT_TRUE(WaitUntilNoPlanInFlight(3000));
  EXPECT_EQ(Status().plans_stored(), 0u);
}

TEST_F(PlanningContractTest, PlanPathGoodInput) {
  ASSERT_TRUE(LoadFile(RoomPath()).ok());
  ASSERT_TRUE(BuildSmall().ok());
  v1::PlanPathRequest r = RoomQuery();
  r.set_sample_dt_s(0.1);
  r.set_yaw_policy(v1::YAW_POLICY_ALONG_PATH);
  v1::PlanPathResponse p;
  ASSERT_TRUE(Plan(r, &p).ok());
  ASSERT_EQ(p.status(), v1::PLAN_STATUS_SUCCESS) << p.message();
  EXPECT_FALSE(p.plan_id().empty());
  EXPECT_TRUE(p.used_roadmap());
  EXPECT_EQ(p.invalid_waypoint(), -1);
  EXPECT_EQ(p.map_fingerprint(), Status().map().fingerprint());
  ASSERT_GE(p.shortened_path_size(), 3);  // around the wall's end
  EXPECT_NEAR(p.shortened_path(0).x(), 2, 1e-9);
  EXPECT_NEAR(p.shortened_path(p.shortened_path_size() - 1).x(), 8, 1e-9);
  EXPECT_GT(p.shortened_cost().length_m(), 6);
  EXPECT_LE(p.shortened_cost().total(), 1.1 * p.path_cost().total() + 1e-9);
  EXPECT_GE(p.trajectory_min_clearance_m(), 0.5);
  EXPECT_GT(p.trajectory().segments_size(), 1);
  EXPECT_EQ(p.trajectory().segments(0).x_size(), 6);
  EXPECT_EQ(p.trajectory().yaw_policy(), v1::YAW_POLICY_ALONG_PATH);
  EXPECT_NEAR(p.trajectory().duration_s(), p.duration_s(), 1e-9);
  EXPECT_GT(p.duration_s(), 1);
  EXPECT_LE(p.max_speed_mps(), 10 * 1.001);
  EXPECT_GT(p.timings().total_ms(), 0);
  EXPECT_NEAR(p.planning_ms(),
              p.timings().connect_ms() + p.timings().search_ms() + p.timings().shorten_ms(), 1e-9);
  EXPECT_EQ(p.samples_size(), static_cast<int>(std::floor(p.duration_s() / 0.1)) + 2);
  EXPECT_NEAR(p.samples(0).position().y(), 2, 1e-9);
  EXPECT_NEAR(p.samples(p.samples_size() - 1).t_s(), p.duration_s(), 1e-9);
  EXPECT_NEAR(p.samples(p.samples_size() - 1).velocity().x(), 0, 1e-6);

  // Through a waypoint, with the Firefly's limits lowered.
  r = RoomQuery();
  Set(r.add_waypoints(), 5, 8.5, 2.5);
  r.mutable_limits()->set_max_speed_mps(3);
  r.set_max_cost_increase(0);
  ASSERT_TRUE(Plan(r, &p).ok());
  ASSERT_EQ(p.status(), v1::PLAN_STATUS_SUCCESS) << p.message();
  EXPECT_LE(p.max_speed_mps(), 3 * 1.001);
  bool visited = false;
  for (const auto& q : p.shortened_path()) visited |= q.x() == 5 && q.y() == 8.5;
  EXPECT_TRUE(visited);

  // Without the roadmap: a fresh PRM*.
  r = RoomQuery();
  r.set_use_roadmap(false);
  r.set_time_budget_s(0.3);
  ASSERT_TRUE(Plan(r, &p).ok());
  EXPECT_EQ(p.status(), v1::PLAN_STATUS_SUCCESS) << p.message();
  EXPECT_FALSE(p.used_roadmap());
  EXPECT_EQ(Status().plans_succeeded(), 3u);
}

TEST_F(PlanningContractTest, PlanPathOutcomesAreReplies) {
  ASSERT_TRUE(LoadFile(RoomPath()).ok());
  ASSERT_TRUE(BuildSmall().ok());
  v1::PlanPathRequest r = RoomQuery();
  Set(r.mutable_start(), 5, 3, 2);  // inside the wall
  v1::PlanPathResponse p;
  ASSERT_TRUE(Plan(r, &p).ok());
  EXPECT_EQ(p.status(), v1::PLAN_STATUS_START_INVALID);
  EXPECT_TRUE(p.plan_id().empty());
  EXPECT_FALSE(p.message().empty());
  r = RoomQuery();
  Set(r.add_waypoints(), 5, 1, 1);  // in the wall
  ASSERT_TRUE(Plan(r, &p).ok());
  EXPECT_EQ(p.status(), v1::PLAN_STATUS_GOAL_INVALID);
  EXPECT_EQ(p.invalid_waypoint(), 0);
  EXPECT_NE(p.message().find("waypoints[0]"), std::string::npos) << p.message();
  r = RoomQuery();
  Set(r.mutable_goal(), 8, 2, 40);  // outside the volume
  ASSERT_TRUE(Plan(r, &p).ok());
  EXPECT_EQ(p.status(), v1::PLAN_STATUS_GOAL_INVALID);
  const v1::PlanningStatus s = Status();
  EXPECT_EQ(s.plans(), 3u);
  EXPECT_EQ(s.plans_succeeded(), 0u);
  EXPECT_EQ(s.plans_stored(), 0u);
}

TEST_F(PlanningContractTest, PlanPathBadInputNamesTheField) {
  ASSERT_TRUE(LoadFile(RoomPath()).ok());
  const double inf = std::numeric_limits<double>::infinity();
  v1::PlanPathRequest r = RoomQuery();
  r.clear_start();
  ExpectError(Plan(r), StatusCode::INVALID_ARGUMENT, "start: not set");
  r = RoomQuery();
  r.mutable_start()->set_x(kNaN);
  ExpectError(Plan(r), StatusCode::INVALID_ARGUMENT, "start.x: not finite");
  r = RoomQuery();
  r.mutable_goal()->set_y(inf);
  ExpectError(Plan(r), StatusCode::INVALID_ARGUMENT, "goal.y: not finite");
  r = RoomQuery();
  Set(r.add_waypoints(), 3, 8, 2);
  Set(r.add_waypoints(), 4, 8, 2);
  Set(r.add_waypoints(), 5, 8, -inf);
  ExpectError(Plan(r), StatusCode::INVALID_ARGUMENT, "waypoints[2].z: not finite");
  r = RoomQuery();
  for (int i = 0; i < 1001; ++i) Set(r.add_waypoints(), 3, 8, 2);
  ExpectError(Plan(r), StatusCode::INVALID_ARGUMENT, "waypoints: 1001 waypoints");
  r = RoomQuery();
  r.mutable_weights()->set_clearance_weight(-1);
  ExpectError(Plan(r), StatusCode::INVALID_ARGUMENT, "weights.clearance_weight: ");
  r = RoomQuery();
  r.mutable_weights()->set_length_weight(kNaN);
  ExpectError(Plan(r), StatusCode::INVALID_ARGUMENT, "weights.length_weight: ");
  r = RoomQuery();
  r.mutable_limits()->set_max_speed_mps(25);
  ExpectError(Plan(r), StatusCode::INVALID_ARGUMENT, "limits.max_speed_mps: ");
  r = RoomQuery();
  r.mutable_limits()->set_max_acceleration_mps2(-2);
  ExpectError(Plan(r), StatusCode::INVALID_ARGUMENT, "limits.max_acceleration_mps2: ");
  r = RoomQuery();
  r.mutable_limits()->set_max_lateral_acceleration_mps2(inf);
  ExpectError(Plan(r), StatusCode::INVALID_ARGUMENT, "limits.max_lateral_acceleration_mps2: ");
  r = RoomQuery();
  r.mutable_limits()->set_max_jerk_mps3(500);
  ExpectError(Plan(r), StatusCode::INVALID_ARGUMENT, "limits.max_jerk_mps3: ");
  r = RoomQuery();
  r.set_max_cost_increase(11);
  ExpectError(Plan(r), StatusCode::INVALID_ARGUMENT, "max_cost_increase: ");
  r = RoomQuery();
  r.set_time_budget_s(601);
  ExpectError(Plan(r), StatusCode::INVALID_ARGUMENT, "time_budget_s: ");
  r = RoomQuery();
  r.set_sample_dt_s(0.0001);
  ExpectError(Plan(r), StatusCode::INVALID_ARGUMENT, "sample_dt_s: ");
  r = RoomQuery();
  r.set_yaw_policy(v1::YAW_POLICY_SEGMENT);
  ExpectError(Plan(r), StatusCode::INVALID_ARGUMENT, "yaw_policy: ");
  r = RoomQuery();
  r.set_yaw_policy(static_cast<v1::YawPolicy>(7));
  ExpectError(Plan(r), StatusCode::INVALID_ARGUMENT, "yaw_policy: unknown");
  r = RoomQuery();
  r.set_start_yaw_rad(kNaN);
  ExpectError(Plan(r), StatusCode::INVALID_ARGUMENT, "start_yaw_rad: ");
  // Huge values are named too, and the message stays short.
  r = RoomQuery();
  r.mutable_start()->set_z(1e308 * 10);
  ExpectError(Plan(r), StatusCode::INVALID_ARGUMENT, "start.z: not finite");
  const v1::PlanningStatus s = Status();
  EXPECT_EQ(s.plans(), 0u);
  EXPECT_GE(s.plans_failed(), 18u);
}

TEST_F(PlanningContractTest, TooManySamplesStoreNothing) {
  ASSERT_TRUE(LoadFile(RoomPath()).ok());
  ASSERT_TRUE(BuildSmall().ok());
  v1::PlanPathRequest r = RoomQuery();
  r.mutable_limits()->set_max_speed_mps(0.2);  // ~60 s of flight
  r.set_sample_dt_s(0.001);
  v1::PlanPathResponse p;
  ExpectError(Plan(r, &p), StatusCode::RESOURCE_EXHAUSTED, "sample_dt_s: ");
  EXPECT_EQ(Status().plans_stored(), 0u);
  r.set_sample_dt_s(0.01);
  ASSERT_TRUE(Plan(r, &p).ok());
  EXPECT_EQ(p.status(), v1::PLAN_STATUS_SUCCESS) << p.message();
  EXPECT_LE(p.samples_size(), 20000);
  EXPECT_GT(p.duration_s(), 20);
}

// A fresh PRM* runs its whole time budget; the client's 300 ms deadline stops it and nothing is
// stored.
TEST_F(PlanningContractTest, PlanPathStoppedByItsDeadline) {
  ASSERT_TRUE(LoadFile(RoomPath()).ok());
  v1::PlanPathRequest r = RoomQuery();
  r.set_use_roadmap(false);
  r.set_time_budget_s(10);
  const grpc::Status s = Plan(r, nullptr, 0.3);
  EXPECT_EQ(s.error_code(), StatusCode::DEADLINE_EXCEEDED) << s.error_message();
  // The server stops the work: the slot frees long before the 10 s PRM* would end.
  EXPECT_TRUE(WaitUntilNoPlanInFlight(3000));
  v1::PlanningStatus status = Status();
  EXPECT_EQ(status.plans_in_flight(), 0u);
  EXPECT_EQ(status.plans_stored(), 0u);
  EXPECT_EQ(status.plans(), 0u);
}

TEST_F(PlanningContractTest, PlansBeyondTheLimitAreRefusedAtOnce) {
  Stop();
  PlannerCoreOptions options;
  options.max_plans_in_flight = 1;
  Start(options, {});
  ASSERT_TRUE(LoadFile(RoomPath()).ok());
  EXPECT_EQ(Status().max_plans_in_flight(), 1u);
  // A fresh PRM* holds the one slot for its 1 s budget.
  std::thread slow([&] {
    v1::PlanPathRequest r = RoomQuery();
    r.set_use_roadmap(false);
    r.set_time_budget_s(1);
    v1::PlanPathResponse p;
    EXPECT_TRUE(Plan(r, &p).ok());
  });
  for (int i = 0; i < 200 && Status().plans_in_flight() == 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_EQ(Status().plans_in_flight(), 1u);
  // Refused, not queued: a queued plan would have waited for the slot and succeeded.
  ExpectError(Plan(RoomQuery()), StatusCode::RESOURCE_EXHAUSTED, "PlanPath: 1 plans in flight");
  slow.join();
  EXPECT_EQ(Status().plans_rejected(), 1u);
  EXPECT_TRUE(Plan(RoomQuery()).ok());
}

// Many plans at once against the snapshot while the roadmap is rebuilt: none fails, none blocks
// on the build, and the new roadmap replaces the old one.
TEST_F(PlanningContractTest, ManyPlansWhileTheRoadmapIsRebuilt) {
  ASSERT_TRUE(LoadFile(RoomPath()).ok());
  ASSERT_TRUE(BuildSmall(3000, 1).ok());
  std::atomic<bool> building{true};
  grpc::Status rebuild;
  std::thread builder([&] {
    v1::BuildRoadmapRequest r;
    r.set_max_milestones(20000);
    r.set_seed(9);
    rebuild = Build(r);
    building = false;
  });
  constexpr int kThreads = 12;
  std::atomic<int> ok{0}, failed{0}, during_build{0};
  std::vector<std::thread> clients;
  clients.reserve(kThreads);
  for (int t = 0; t < kThreads; ++t) {
    clients.emplace_back([&, t] {
      auto stub = v1::Planning::NewStub(server_->InProcessChannel());
      for (int i = 0; i < 25; ++i) {
        v1::PlanPathRequest r = RoomQuery();
        Set(r.mutable_start(), 1 + 0.1 * t, 1 + 0.1 * i, 1 + 0.1 * (i % 20));
        grpc::ClientContext context;
        context.set_deadline(Deadline(10));
        v1::PlanPathResponse p;
        const bool was_building = building.load();
        const grpc::Status s = stub->PlanPath(&context, r, &p);
        if (s.ok() && p.status() == v1::PLAN_STATUS_SUCCESS) {
          ++ok;
          during_build += was_building;
        } else {
          ++failed;
          ADD_FAILURE() << s.error_message() << " " << p.message();
        }
      }
    });
  }
  for (std::thread& c : clients) c.join();
  builder.join();
  ASSERT_TRUE(rebuild.ok()) << rebuild.error_message();
  EXPECT_EQ(ok.load(), kThreads * 25);
  EXPECT_EQ(failed.load(), 0);
  EXPECT_GT(during_build.load(), 0);
  const v1::PlanningStatus s = Status();
  EXPECT_EQ(s.roadmap().seed(), 9u);
  EXPECT_EQ(s.roadmap().milestones(), 20000u);
  EXPECT_EQ(s.plans_succeeded(), static_cast<uint64_t>(kThreads * 25));
  EXPECT_EQ(s.plans_stored(), 16u);
  EXPECT_EQ(s.planning_ms().count(), static_cast<uint64_t>(kThreads * 25));
}

TEST_F(PlanningContractTest, GetPlanKeepsTheLastSixteen) {
  ASSERT_TRUE(LoadFile(RoomPath()).ok());
  ASSERT_TRUE(BuildSmall().ok());
  v1::PlanPathResponse reply, got;
  ExpectError(GetPlan("", &got), StatusCode::INVALID_ARGUMENT, "plan_id: empty");
  ExpectError(GetPlan("nope", &got), StatusCode::NOT_FOUND, "plan_id: no plan 'nope'");
  std::vector<std::string> ids;
  for (int i = 0; i < 17; ++i) {
    v1::PlanPathRequest r = RoomQuery();
    r.mutable_start()->set_z(1 + 0.1 * i);
    r.set_sample_dt_s(0.5);
    ASSERT_TRUE(Plan(r, &reply).ok());
    ASSERT_EQ(reply.status(), v1::PLAN_STATUS_SUCCESS);
    ids.push_back(reply.plan_id());
  }
  ASSERT_TRUE(GetPlan(ids.back(), &got).ok());
  EXPECT_EQ(got.SerializeAsString(), reply.SerializeAsString());
  ExpectError(GetPlan(ids.front(), &got), StatusCode::NOT_FOUND, "plan_id: no plan");
  EXPECT_TRUE(GetPlan(ids[1], &got).ok());
  EXPECT_EQ(Status().plans_stored(), 16u);
}

TEST_F(PlanningContractTest, SampleTrajectory) {
  ASSERT_TRUE(LoadFile(RoomPath()).ok());
  ASSERT_TRUE(BuildSmall().ok());
  v1::PlanPathResponse p;
  ASSERT_TRUE(Plan(RoomQuery(), &p).ok());
  ASSERT_EQ(p.status(), v1::PLAN_STATUS_SUCCESS);
  v1::SampleTrajectoryRequest r;
  v1::SampleTrajectoryResponse s;
  ExpectError(Sample(r, &s), StatusCode::INVALID_ARGUMENT, "trajectory_source: not set");
  r.set_plan_id("nope");
  ExpectError(Sample(r, &s), StatusCode::NOT_FOUND, "plan_id: ");
  r.set_plan_id(p.plan_id());
  ExpectError(Sample(r, &s), StatusCode::INVALID_ARGUMENT, "dt_s: ");
  r.set_dt_s(-1);
  ExpectError(Sample(r, &s), StatusCode::INVALID_ARGUMENT, "dt_s: ");
  r.set_dt_s(1e-6);
  ExpectError(Sample(r, &s), StatusCode::RESOURCE_EXHAUSTED, "dt_s: ");
  r.set_dt_s(0.05);
  ASSERT_TRUE(Sample(r, &s).ok());
  EXPECT_NEAR(s.duration_s(), p.duration_s(), 1e-12);
  ASSERT_EQ(s.samples_size(), static_cast<int>(std::floor(p.duration_s() / 0.05)) + 2);
  EXPECT_NEAR(s.samples(0).position().x(), 2, 1e-9);
  EXPECT_NEAR(s.samples(s.samples_size() - 1).position().x(), 8, 1e-9);
  // Derivatives up to snap are there, and the velocity is the position's rate.
  const auto& a = s.samples(10);
  const auto& b = s.samples(11);
  EXPECT_NEAR((b.position().x() - a.position().x()) / 0.05,
              0.5 * (a.velocity().x() + b.velocity().x()), 0.05);
  // Explicit times win.
  r.add_times_s(0);
  r.add_times_s(p.duration_s());
  ASSERT_TRUE(Sample(r, &s).ok());
  ASSERT_EQ(s.samples_size(), 2);
  EXPECT_NEAR(s.samples(1).position().x(), 8, 1e-9);
  r.add_times_s(p.duration_s() + 1);
  ExpectError(Sample(r, &s), StatusCode::INVALID_ARGUMENT, "times_s[2]: ");
  r.clear_times_s();
  r.add_times_s(kNaN);
  ExpectError(Sample(r, &s), StatusCode::INVALID_ARGUMENT, "times_s[0]: ");

  // A given trajectory: the plan's own gives the same samples.
  v1::SampleTrajectoryRequest given;
  *given.mutable_trajectory() = p.trajectory();
  given.set_dt_s(0.05);
  v1::SampleTrajectoryResponse s2;
  ASSERT_TRUE(Sample(given, &s2).ok());
  r.clear_times_s();
  ASSERT_TRUE(Sample(r, &s).ok());
  EXPECT_EQ(s2.SerializeAsString(), s.SerializeAsString());
  given.mutable_trajectory()->mutable_segments(1)->mutable_y()->RemoveLast();
  ExpectError(Sample(given, &s2), StatusCode::INVALID_ARGUMENT, "trajectory.segments[1].y: 5");
  *given.mutable_trajectory() = p.trajectory();
  given.mutable_trajectory()->mutable_segments(2)->set_duration_s(0);
  ExpectError(Sample(given, &s2), StatusCode::INVALID_ARGUMENT,
              "trajectory.segments[2].duration_s: ");
  given.mutable_trajectory()->clear_segments();
  ExpectError(Sample(given, &s2), StatusCode::INVALID_ARGUMENT, "trajectory.segments: no segments");
}

TEST_F(PlanningContractTest, SaveAndLoadRoadmap) {
  ASSERT_TRUE(LoadFile(RoomPath()).ok());
  const std::string path = TestDir() + "/room.mavprm";
  std::remove(path.c_str());
  grpc::ClientContext c0;
  v1::SaveRoadmapRequest save;
  v1::RoadmapInfo info;
  save.set_path(path);
  ExpectError(stub_->SaveRoadmap(&c0, save, &info), StatusCode::FAILED_PRECONDITION, "no roadmap");
  ASSERT_TRUE(BuildSmall(2000, 4).ok());
  {
    grpc::ClientContext c;
    v1::SaveRoadmapRequest bad;
    ExpectError(stub_->SaveRoadmap(&c, bad, &info), StatusCode::INVALID_ARGUMENT, "path: empty");
  }
  {
    grpc::ClientContext c;
    v1::SaveRoadmapRequest bad;
    bad.set_path(RoomPath());  // a .bt
    ExpectError(stub_->SaveRoadmap(&c, bad, &info), StatusCode::INVALID_ARGUMENT, "path: ");
  }
  {
    const std::string not_roadmap = TestDir() + "/precious.mavprm";
    ASSERT_TRUE(WriteStringToFileAtomic(not_roadmap, "my data").ok());
    grpc::ClientContext c;
    v1::SaveRoadmapRequest bad;
    bad.set_path(not_roadmap);
    ExpectError(stub_->SaveRoadmap(&c, bad, &info), StatusCode::FAILED_PRECONDITION, "path: ");
    EXPECT_EQ(*ReadFileToString(not_roadmap), "my data");
  }
  {
    grpc::ClientContext c;
    ASSERT_TRUE(stub_->SaveRoadmap(&c, save, &info).ok());
    EXPECT_EQ(info.source(), path);
    EXPECT_EQ(info.milestones(), 2000u);
  }
  // A second server loads the file instead of building.
  Stop();
  Start({}, {});
  ASSERT_TRUE(LoadFile(RoomPath()).ok());
  v1::LoadRoadmapRequest load;
  {
    grpc::ClientContext c;
    ExpectError(stub_->LoadRoadmap(&c, load, &info), StatusCode::INVALID_ARGUMENT, "path: empty");
  }
  {
    grpc::ClientContext c;
    load.set_path(TestDir() + "/missing.mavprm");
    ExpectError(stub_->LoadRoadmap(&c, load, &info), StatusCode::NOT_FOUND, "");
  }
  {
    grpc::ClientContext c;
    load.set_path(path);
    ASSERT_TRUE(stub_->LoadRoadmap(&c, load, &info).ok());
    EXPECT_EQ(info.milestones(), 2000u);
    EXPECT_EQ(info.seed(), 4u);
    EXPECT_GT(info.load_ms(), 0);
    EXPECT_EQ(info.source(), path);
    EXPECT_EQ(Status().roadmap().source(), path);
  }
  v1::PlanPathResponse p;
  ASSERT_TRUE(Plan(RoomQuery(), &p).ok());
  EXPECT_EQ(p.status(), v1::PLAN_STATUS_SUCCESS);
  EXPECT_TRUE(p.used_roadmap());
  {
    const std::string truncated = TestDir() + "/truncated.mavprm";
    const std::string bytes = *ReadFileToString(path);
    ASSERT_TRUE(WriteStringToFileAtomic(truncated, bytes.substr(0, bytes.size() - 100)).ok());
    grpc::ClientContext c;
    load.set_path(truncated);
    const grpc::Status s = stub_->LoadRoadmap(&c, load, &info);
    EXPECT_EQ(s.error_code(), StatusCode::DATA_LOSS) << s.error_message();
    EXPECT_NE(s.error_message().find("truncated.mavprm"), std::string::npos);
  }
  {
    // The roadmap of another map (another robot radius) is refused.
    v1::LoadMapRequest r;
    r.mutable_file()->set_path(RoomPath());
    r.mutable_options()->set_robot_radius_m(0.4);
    ASSERT_TRUE(LoadMap(r).ok());
    grpc::ClientContext c;
    load.set_path(path);
    const grpc::Status s = stub_->LoadRoadmap(&c, load, &info);
    EXPECT_EQ(s.error_code(), StatusCode::FAILED_PRECONDITION) << s.error_message();
    EXPECT_FALSE(Status().roadmap_ready());
  }
}

// The map the stack builds is planned in: LoadMap from a running mapping service (a fake
// mav.v1.Mapping on a loopback port streaming the room's .bt).
TEST_F(PlanningContractTest, LoadMapFromAMappingService) {
  FakeMapping mapping(RoomBytes(), false);
  transport::ServerOptions options;
  options.port = 0;
  auto server = transport::GrpcServer::Start(options, {&mapping});
  ASSERT_TRUE(server.ok());
  v1::LoadMapRequest r;
  r.mutable_mapping()->set_address((*server)->target());
  r.mutable_mapping()->set_method(v1::MAPPING_METHOD_REF_SPARSE_MESH);
  v1::MapInfo info, from_file;
  ASSERT_TRUE(LoadMap(r, &info).ok());
  EXPECT_EQ(info.source(), "mapping@" + (*server)->target());
  EXPECT_EQ(mapping.calls(), 1);
  ASSERT_TRUE(LoadFile(RoomPath(), &from_file).ok());
  EXPECT_EQ(info.fingerprint(), from_file.fingerprint());

  r.mutable_mapping()->set_method(v1::MAPPING_METHOD_REF_OCTOMAP);
  const grpc::Status none = LoadMap(r);
  EXPECT_EQ(none.error_code(), StatusCode::NOT_FOUND) << none.error_message();
  EXPECT_NE(none.error_message().find("no octomap map"), std::string::npos);
  r.mutable_mapping()->set_method(static_cast<v1::MappingMethodRef>(5));
  ExpectError(LoadMap(r), StatusCode::INVALID_ARGUMENT, "mapping.method: unknown");

  FakeMapping broken(RoomBytes(), true);
  auto broken_server = transport::GrpcServer::Start(options, {&broken});
  ASSERT_TRUE(broken_server.ok());
  r.mutable_mapping()->set_address((*broken_server)->target());
  r.mutable_mapping()->set_method(v1::MAPPING_METHOD_REF_UNSPECIFIED);
  const grpc::Status gap = LoadMap(r);
  EXPECT_EQ(gap.error_code(), StatusCode::DATA_LOSS) << gap.error_message();

  const std::string nobody = "127.0.0.1:1";
  r.mutable_mapping()->set_address(nobody);
  const grpc::Status unreachable = LoadMap(r, nullptr, 5);
  EXPECT_EQ(unreachable.error_code(), StatusCode::UNAVAILABLE) << unreachable.error_message();
  EXPECT_NE(unreachable.error_message().find("mapping@127.0.0.1:1"), std::string::npos)
      << unreachable.error_message();
  EXPECT_EQ(Status().map().fingerprint(), from_file.fingerprint());
}

// A real loopback port, health, and the power plant with a small roadmap: the t4_3 legs.
TEST_F(PlanningContractTest, LoopbackPortHealthAndThePowerPlant) {
  const std::string target = server_->target();
  auto channel = grpc::CreateChannel(target, grpc::InsecureChannelCredentials());
  auto health = transport::CheckHealth(channel, "mav.v1.Planning", std::chrono::seconds(2));
  ASSERT_TRUE(health.ok()) << health.status().ToString();
  EXPECT_EQ(*health, transport::HealthStatus::kServing);
  auto stub = v1::Planning::NewStub(channel);
  v1::MapInfo info;
  {
    grpc::ClientContext c;
    c.set_deadline(Deadline(30));
    v1::LoadMapRequest r;
    r.mutable_file()->set_path(kPowerPlant);
    ASSERT_TRUE(stub->LoadMap(&c, r, &info).ok());
  }
  EXPECT_DOUBLE_EQ(info.resolution_m(), 0.25);
  {
    grpc::ClientContext c;
    c.set_deadline(Deadline(60));
    v1::BuildRoadmapRequest r;
    r.set_max_milestones(20000);
    v1::RoadmapInfo roadmap;
    ASSERT_TRUE(stub->BuildRoadmap(&c, r, &roadmap).ok());
    EXPECT_EQ(roadmap.milestones(), 20000u);
  }
  const double legs[4][3] = {{2, -27, 15}, {20, -15, 15}, {25, 0, 5}, {0, 0, 1}};
  for (int i = 0; i < 3; ++i) {
    v1::PlanPathRequest r;
    Set(r.mutable_start(), legs[i][0], legs[i][1], legs[i][2]);
    Set(r.mutable_goal(), legs[i + 1][0], legs[i + 1][1], legs[i + 1][2]);
    grpc::ClientContext c;
    c.set_deadline(Deadline(10));
    v1::PlanPathResponse p;
    ASSERT_TRUE(stub->PlanPath(&c, r, &p).ok());
    EXPECT_EQ(p.status(), v1::PLAN_STATUS_SUCCESS) << "leg " << i << ": " << p.message();
    EXPECT_GE(p.trajectory_min_clearance_m(), 0.5);
    EXPECT_LT(p.duration_s(), 6.5) << "leg " << i;
  }
}

}  // namespace
}  // namespace mav::planning_service
