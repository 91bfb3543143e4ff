// The mapping service builds a map from the simulator's streams over loopback DDS and serves it
// over gRPC: the mav-simulator and mav-mapping binaries on free loopback ports and a per-pid DDS
// domain; mapping takes its calibration from the simulator (CalibrationSource.simulator_address)
// and its poses from mav/sim/ground_truth; the simulator streams room-easy (raw EuRoC-like rig:
// mapping rectifies) as fast as its stereo subscriber acknowledges. Then BuildMap, the occupancy
// map streamed into a .bt file that OctoMap reads back, collision queries against boxes that the
// simulator's exact ground-truth occupancy (libs/sim, in process) says are solid or free, and the
// mesh as PLY.

#include <gtest/gtest.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fcntl.h>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>
#include <octomap/OcTree.h>

#include "mav/common/file.h"
#include "mav/common/time.h"
#include "mav/geometry/se3.h"
#include "mav/mapping/mesh.h"
#include "mav/sim/occupancy.h"
#include "mav/sim/scenario.h"
#include "mav/transport/grpc_server.h"
#include "mav/v1/mapping.grpc.pb.h"
#include "mav/v1/simulator.grpc.pb.h"
#include "tests/common/stack_fixture.h"

namespace mav {
namespace {

using ::mav::test_support::Stack;  // tests/common/stack_fixture.h

std::chrono::system_clock::time_point Deadline(int seconds) {
  return std::chrono::system_clock::now() + std::chrono::seconds(seconds);
}

v1::Box BoxAround(const Eigen::Vector3d& c, double half) {
  v1::Box box;
  box.mutable_min()->set_x(c.x() - half);
  box.mutable_min()->set_y(c.y() - half);
  box.mutable_min()->set_z(c.z() - half);
  box.mutable_max()->set_x(c.x() + half);
  box.mutable_max()->set_y(c.y() + half);
  box.mutable_max()->set_z(c.z() + half);
  return box;
}

// True when every ground-truth voxel the box [c - half, c + half] touches has `state`.
bool AllVoxels(const dataset::OccupancyGrid& grid, const Eigen::Vector3d& c, double half,
               dataset::VoxelState state) {
  const Eigen::Vector3i lo = grid.IndexOf(c - Eigen::Vector3d::Constant(half));
  const Eigen::Vector3i hi = grid.IndexOf(c + Eigen::Vector3d::Constant(half));
  for (int k = lo.z(); k <= hi.z(); ++k) {
    for (int j = lo.y(); j <= hi.y(); ++j) {
      for (int i = lo.x(); i <= hi.x(); ++i) {
        if (!grid.InBounds({i, j, k}) || grid.at({i, j, k}) != state) return false;
      }
    }
  }
  return true;
}

// MAV_MAP_STACK_FRAMES=N overrides the frame count for measurements (not used by ctest).
int FramesFromEnv() {
  const char* frames = std::getenv("MAV_MAP_STACK_FRAMES");
  return frames != nullptr && std::atoi(frames) >= 20 ? std::atoi(frames) : 150;
}

TEST(MappingStackTest, BuildsAMapFromTheSimulatorsStreamsAndServesIt) {
  const int kFrames = FramesFromEnv();
  const int64_t start_ns = MonotonicNowNs();
  Stack stack(/*domain_key=*/53);
  const std::string sim_target = stack.Start("mav-simulator", "mav.v1.Simulator");
  ASSERT_FALSE(sim_target.empty()) << "see " << stack.Log("mav-simulator");
  // A queue deep enough that no keyframe is dropped while rendering and mapping share two cores.
  const std::string map_target =
      stack.Start("mav-mapping", "mav.v1.Mapping", {"--queue-length", "200"});
  ASSERT_FALSE(map_target.empty()) << "see " << stack.Log("mav-mapping");

  auto sim =
      v1::Simulator::NewStub(grpc::CreateChannel(sim_target, grpc::InsecureChannelCredentials()));
  auto map =
      v1::Mapping::NewStub(grpc::CreateChannel(map_target, grpc::InsecureChannelCredentials()));
  {
    v1::LoadScenarioRequest request;
    request.mutable_preset()->set_name("room-easy");
    request.mutable_preset()->set_frames(kFrames);
    request.mutable_preset()->set_seed(1);
    grpc::ClientContext context;
    context.set_deadline(Deadline(20));
    v1::LoadScenarioResponse response;
    const grpc::Status status = sim->LoadScenario(&context, request, &response);
    ASSERT_TRUE(status.ok()) << status.error_message();
  }
  {
    v1::StartSessionRequest request;
    request.mutable_calibration()->set_simulator_address(sim_target);
    request.set_pose_source(v1::POSE_SOURCE_GROUND_TRUTH);
    grpc::ClientContext context;
    context.set_deadline(Deadline(20));
    v1::MappingStatus status;
    const grpc::Status rpc = map->StartSession(&context, request, &status);
    ASSERT_TRUE(rpc.ok()) << rpc.error_message();
    ASSERT_TRUE(status.session_active());
    ASSERT_EQ(status.pose_source(), v1::POSE_SOURCE_GROUND_TRUTH);
  }
  {
    v1::SimulatorStartRequest request;
    request.set_as_fast_as_subscribers(true);
    request.set_wait_for_subscribers(1);
    grpc::ClientContext context;
    context.set_deadline(Deadline(10));
    v1::SimulatorStatus status;
    const grpc::Status rpc = sim->Start(&context, request, &status);
    ASSERT_TRUE(rpc.ok()) << rpc.error_message();
  }

  // Every frame reaches the mapper: the simulator finishes and the mapper has seen them all.
  v1::MappingStatus status;
  bool finished = false;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(70);
  while (std::chrono::steady_clock::now() < deadline) {
    v1::SimulatorStatus sim_status;
    grpc::ClientContext sim_context;
    sim_context.set_deadline(Deadline(2));
    ASSERT_TRUE(sim->GetStatus(&sim_context, v1::SimulatorGetStatusRequest(), &sim_status).ok());
    grpc::ClientContext context;
    context.set_deadline(Deadline(2));
    ASSERT_TRUE(map->GetStatus(&context, v1::MappingGetStatusRequest(), &status).ok());
    if (sim_status.state() == v1::SIMULATOR_STATE_FINISHED &&
        status.frames_seen() + status.frames_without_pose() >= static_cast<uint64_t>(kFrames)) {
      finished = true;
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_TRUE(finished) << "frames seen " << status.frames_seen() << " of " << kFrames << "; see "
                        << stack.Log("mav-mapping");
  const double streamed_s = NsToSeconds(MonotonicNowNs() - start_ns);
  EXPECT_EQ(status.frames_seen(), static_cast<uint64_t>(kFrames));
  EXPECT_EQ(status.frames_without_pose(), 0u) << "every frame has a ground-truth pose";

  // BuildMap waits for the queued keyframes, then meshes.
  v1::BuildMapRequest build;
  build.set_method(v1::MAPPING_METHOD_SPARSE_MESH);
  v1::BuildMapResponse built;
  {
    grpc::ClientContext context;
    context.set_deadline(Deadline(60));
    const grpc::Status rpc = map->BuildMap(&context, build, &built);
    ASSERT_TRUE(rpc.ok()) << rpc.error_message();
  }
  EXPECT_GE(built.keyframes(), 5u);
  EXPECT_GT(built.points(), 300u);
  EXPECT_GT(built.mesh_faces(), 100u);
  EXPECT_GT(built.occupancy().occupied_voxels(), 1000u);

  // The occupancy map streamed in 4 KiB chunks into a file that OctoMap reads.
  const std::string bt_path =
      ::testing::TempDir() + "/map-stack-" + std::to_string(::getpid()) + ".bt";
  {
    v1::GetOccupancyRequest request;
    request.set_method(v1::MAPPING_METHOD_SPARSE_MESH);
    request.set_chunk_size(4096);
    grpc::ClientContext context;
    context.set_deadline(Deadline(30));
    auto reader = map->GetOccupancy(&context, request);
    std::ofstream out(bt_path, std::ios::binary);
    v1::OccupancyChunk chunk;
    uint64_t bytes = 0, total = 0;
    int chunks = 0;
    while (reader->Read(&chunk)) {
      EXPECT_EQ(chunk.chunk().offset(), bytes);
      out.write(chunk.chunk().data().data(),
                static_cast<std::streamsize>(chunk.chunk().data().size()));
      bytes += chunk.chunk().data().size();
      total = chunk.chunk().total_size();
      ++chunks;
    }
    const grpc::Status rpc = reader->Finish();
    ASSERT_TRUE(rpc.ok()) << rpc.error_message();
    EXPECT_EQ(bytes, total);
    EXPECT_GT(chunks, 1);
  }
  octomap::OcTree tree(0.1);
  ASSERT_TRUE(tree.readBinary(bt_path)) << bt_path;
  int64_t occupied_leaves = 0;
  for (auto it = tree.begin_leafs(); it != tree.end_leafs(); ++it) {
    occupied_leaves += tree.isNodeOccupied(*it) ? 1 : 0;
  }
  EXPECT_GT(occupied_leaves, 1000);
  std::remove(bt_path.c_str());

  // Ground truth in process (the simulator's scenario, same preset, frames and seed): boxes of
  // 10 cm entirely free a metre in front of the camera, and entirely solid behind the surfaces
  // the camera looks at.
  sim::ScenarioOptions options;
  options.preset = "room-easy";
  options.frames = kFrames;
  options.seed = 1;
  Result<sim::Scenario> scenario = sim::Scenario::Create(options);
  ASSERT_TRUE(scenario.ok()) << scenario.status().ToString();
  const dataset::OccupancyGrid truth = scenario->ComputeOccupancy(0.05);
  constexpr double kHalf = 0.05;
  constexpr double kSolidHalf = 0.025;
  constexpr double kMaxSolidDepth = 6.0;
  constexpr double kAhead = 1.0;
  std::vector<Eigen::Vector3d> in_front;
  for (int k = 0; k < kFrames; k += 5) {
    const geometry::SE3 T_world_body = scenario->StateAt(scenario->FrameTimeNs(k)).T_world_body;
    const Eigen::Vector3d p =
        T_world_body * scenario->calibration().T_body_cam0 * Eigen::Vector3d(0, 0, kAhead);
    if (AllVoxels(truth, p, kHalf, dataset::VoxelState::kFree)) in_front.push_back(p);
  }
  const v1::Box& b = built.occupancy().bounds();
  const Eigen::AlignedBox3d map_bounds(Eigen::Vector3d(b.min().x(), b.min().y(), b.min().z()),
                                       Eigen::Vector3d(b.max().x(), b.max().y(), b.max().z()));
  // Solid boxes the cameras looked at: along 35 lines of sight spread over the image of every 5th
  // frame, the first solid surface in the ground truth if it is closer than 6 m (the sparse
  // points' depth limit), and a 5 cm box just behind it.
  std::vector<Eigen::Vector3d> solid;
  for (int k = 0; k < kFrames; k += 5) {
    const geometry::SE3 T_world_cam = scenario->StateAt(scenario->FrameTimeNs(k)).T_world_body *
                                      scenario->calibration().T_body_cam0;
    for (int r = 0; r < 35; ++r) {
      const int column = r % 7, row = r / 7;
      const Eigen::Vector3d ray(-0.6 + 0.2 * column, -0.4 + 0.2 * row, 1.0);
      const Eigen::Vector3d& origin = T_world_cam.Translation();
      const Eigen::Vector3d direction = T_world_cam.Rotation() * ray.normalized();
      for (double d = 0.1; d < kMaxSolidDepth; d += 0.01) {
        const dataset::VoxelState state = truth.StateAt(origin + d * direction);
        if (state == dataset::VoxelState::kFree) continue;
        const Eigen::Vector3d c = origin + (d + 0.04) * direction;
        if (state == dataset::VoxelState::kOccupied && map_bounds.contains(c) &&
            AllVoxels(truth, c, kSolidHalf, dataset::VoxelState::kOccupied)) {
          solid.push_back(c);
        }
        break;
      }
    }
  }
  ASSERT_GT(solid.size(), 10u);
  ASSERT_GT(in_front.size(), 5u);

  v1::QueryCollisionRequest query;
  query.set_method(v1::MAPPING_METHOD_SPARSE_MESH);
  for (const Eigen::Vector3d& c : solid) *query.add_boxes() = BoxAround(c, kSolidHalf);
  for (const Eigen::Vector3d& c : in_front) *query.add_boxes() = BoxAround(c, kHalf);
  v1::QueryCollisionResponse answer;
  {
    grpc::ClientContext context;
    context.set_deadline(Deadline(10));
    const grpc::Status rpc = map->QueryCollision(&context, query, &answer);
    ASSERT_TRUE(rpc.ok()) << rpc.error_message();
  }
  ASSERT_EQ(answer.states_size(), static_cast<int>(solid.size() + in_front.size()));
  int solid_collision = 0, solid_free = 0, front_free = 0, front_collision = 0;
  for (size_t i = 0; i < solid.size(); ++i) {
    solid_collision += answer.states(static_cast<int>(i)) == v1::COLLISION_STATE_COLLISION;
    solid_free += answer.states(static_cast<int>(i)) == v1::COLLISION_STATE_FREE;
  }
  for (size_t i = 0; i < in_front.size(); ++i) {
    const v1::CollisionState s = answer.states(static_cast<int>(solid.size() + i));
    front_free += s == v1::COLLISION_STATE_FREE;
    front_collision += s == v1::COLLISION_STATE_COLLISION;
  }
  std::printf(
      "MAPSTACK frames=%d streamed_s=%.1f keyframes=%u points=%llu faces=%llu build_ms=%.0f "
      "solid_boxes=%zu collision=%d free=%d | free_boxes=%zu free=%d collision=%d\n",
      kFrames, streamed_s, built.keyframes(), static_cast<unsigned long long>(built.points()),
      static_cast<unsigned long long>(built.mesh_faces()), built.timing().total_ms(), solid.size(),
      solid_collision, solid_free, in_front.size(), front_free, front_collision);
  // Solids the cameras saw: mostly COLLISION (measured 59 of 73 on 150 frames, 12 keyframes;
  // the FREE ones are surfaces the ~100 sparse points per keyframe missed). Free space a metre in
  // front of the camera: FREE (measured 30 of 30).
  EXPECT_GE(solid_collision, static_cast<int>(solid.size() * 6 / 10));
  EXPECT_LE(solid_free, static_cast<int>(solid.size() / 4));
  EXPECT_GE(front_free, static_cast<int>(in_front.size() * 8 / 10));
  EXPECT_LE(front_collision, static_cast<int>(in_front.size() / 10));

  // The mesh as PLY with faces.
  {
    v1::ExportMeshRequest request;
    grpc::ClientContext context;
    context.set_deadline(Deadline(30));
    auto reader = map->ExportMesh(&context, request);
    v1::FileChunk chunk;
    std::string bytes;
    while (reader->Read(&chunk)) bytes += chunk.data();
    const grpc::Status rpc = reader->Finish();
    ASSERT_TRUE(rpc.ok()) << rpc.error_message();
    Result<mapping::TriangleMesh> mesh = mapping::DecodePly(bytes, "ExportMesh");
    ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
    EXPECT_EQ(mesh->triangles.size(), built.mesh_faces());
  }

  // The baseline on the same keyframes is served too.
  build.set_method(v1::MAPPING_METHOD_OCTOMAP);
  {
    grpc::ClientContext context;
    context.set_deadline(Deadline(60));
    v1::BuildMapResponse octomap;
    const grpc::Status rpc = map->BuildMap(&context, build, &octomap);
    ASSERT_TRUE(rpc.ok()) << rpc.error_message();
    EXPECT_EQ(octomap.keyframes(), built.keyframes());
    EXPECT_GT(octomap.occupancy().occupied_voxels(), 1000u);
  }

  // SIGTERM during a build: the server drains (5 s grace) and the client gets its map.
  {
    v1::BuildMapRequest slow = build;
    slow.set_resolution_m(0.025);  // ~30 M voxels to paint: seconds
    grpc::ClientContext context;
    context.set_deadline(Deadline(60));
    v1::BuildMapResponse response;
    grpc::Status rpc;
    std::thread client([&] { rpc = map->BuildMap(&context, slow, &response); });
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    stack.Process("mav-mapping")->Signal(SIGTERM);
    client.join();
    EXPECT_TRUE(rpc.ok()) << "the build in flight must reach its client: " << rpc.error_message();
    EXPECT_EQ(response.keyframes(), built.keyframes());
  }
  EXPECT_EQ(stack.Process("mav-mapping")->Wait(std::chrono::seconds(10)), std::optional<int>(0))
      << "see " << stack.Log("mav-mapping");
  stack.Process("mav-simulator")->Signal(SIGTERM);
  EXPECT_EQ(stack.Process("mav-simulator")->Wait(std::chrono::seconds(10)), std::optional<int>(0));
}

}  // namespace
}  // namespace mav
