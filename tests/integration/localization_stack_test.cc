// The localization service runs in the stack: the mav-simulator and mav-localization binaries on
// free loopback ports and a per-pid DDS domain; localization takes its calibration from the
// simulator (CalibrationSource.simulator_address), the simulator streams room-easy as fast as its
// stereo subscriber (the localization service) acknowledges, and this test subscribes to
// mav/localization/pose and mav/sim/ground_truth and compares the estimated body trajectory with
// the ground truth: every frame has a pose, tracking is OK on (nearly) every frame, and the end
// point error is a small fraction of the path length.

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
#include <iterator>
#include <map>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>

#include "mav/common/time.h"
#include "mav/geometry/se3.h"
#include "mav/transport/dds.h"
#include "mav/transport/grpc_server.h"
#include "mav/v1/localization.grpc.pb.h"
#include "mav/v1/simulator.grpc.pb.h"
#include "mav_state.h"
#include "tests/common/stack_fixture.h"

namespace mav {
namespace {

using ::mav::test_support::Stack;  // tests/common/stack_fixture.h

geometry::SE3 PoseOf(const mav_dds_Vector3& p, const mav_dds_Quaternion& q) {
  return geometry::SE3(Eigen::Quaterniond(q.w, q.x, q.y, q.z), Eigen::Vector3d(p.x, p.y, p.z));
}

std::chrono::system_clock::time_point Deadline(int seconds) {
  return std::chrono::system_clock::now() + std::chrono::seconds(seconds);
}

// Environment overrides for measurements (docs/services.md), not used by ctest:
// MAV_LOC_STACK_METHOD=sparse-pixel|sparse-subpixel|dense, MAV_LOC_STACK_FRAMES=N,
// MAV_LOC_STACK_EUROC=DIR (the simulator replays that EuRoC directory instead of the preset).
v1::LocalizationMethod MethodFromEnv() {
  const char* name = std::getenv("MAV_LOC_STACK_METHOD");
  const std::string method = name != nullptr ? name : "sparse-subpixel";
  if (method == "sparse-pixel") return v1::LOCALIZATION_METHOD_SPARSE_PIXEL;
  if (method == "dense") return v1::LOCALIZATION_METHOD_DENSE;
  return v1::LOCALIZATION_METHOD_SPARSE_SUBPIXEL;
}

int FramesFromEnv() {
  const char* frames = std::getenv("MAV_LOC_STACK_FRAMES");
  return frames != nullptr && std::atoi(frames) >= 10 ? std::atoi(frames) : 60;
}

TEST(LocalizationStackTest, PosesFromTheStackFollowTheGroundTruth) {
  const int kFrames = FramesFromEnv();
  const v1::LocalizationMethod method = MethodFromEnv();
  Stack stack(/*domain_key=*/37);
  const std::string sim_target = stack.Start("mav-simulator", "mav.v1.Simulator");
  ASSERT_FALSE(sim_target.empty()) << "see " << stack.Log("mav-simulator");
  const std::string loc_target = stack.Start("mav-localization", "mav.v1.Localization");
  ASSERT_FALSE(loc_target.empty()) << "see " << stack.Log("mav-localization");

  auto sim =
      v1::Simulator::NewStub(grpc::CreateChannel(sim_target, grpc::InsecureChannelCredentials()));
  auto loc = v1::Localization::NewStub(
      grpc::CreateChannel(loc_target, grpc::InsecureChannelCredentials()));
  {
    v1::LoadScenarioRequest request;
    if (std::getenv("MAV_LOC_STACK_EUROC")) {
      request.mutable_euroc()->set_directory(std::getenv("MAV_LOC_STACK_EUROC"));
    } else {
      request.mutable_preset()->set_name("room-easy");
      request.mutable_preset()->set_frames(kFrames);
    }
    grpc::ClientContext context;
    context.set_deadline(Deadline(20));
    v1::LoadScenarioResponse response;
    const grpc::Status status = sim->LoadScenario(&context, request, &response);
    ASSERT_TRUE(status.ok()) << status.error_message();
  }
  {
    v1::LocalizationConfigureRequest request;
    request.set_method(method);
    request.mutable_calibration()->set_simulator_address(sim_target);
    // Deep enough that no frame is dropped even when rendering and VO share the two cores.
    request.set_queue_length(100);
    grpc::ClientContext context;
    context.set_deadline(Deadline(20));
    v1::LocalizationStatus status;
    const grpc::Status rpc = loc->Configure(&context, request, &status);
    ASSERT_TRUE(rpc.ok()) << rpc.error_message();
    ASSERT_TRUE(status.dds_input());
    ASSERT_EQ(status.state(), v1::LOCALIZATION_SERVICE_STATE_READY);
  }

  // The test's subscribers: every pose and every ground-truth state.
  transport::DdsOptions options;
  options.domain = stack.domain();
  auto participant = transport::Participant::Create(options);
  ASSERT_TRUE(participant.ok()) << participant.status().ToString();
  auto pose_topic = transport::Topic<mav_dds_PoseWithCovariance>::Create(
      *participant, transport::kPoseTopic, &mav_dds_PoseWithCovariance_desc);
  ASSERT_TRUE(pose_topic.ok());
  auto pose_reader = transport::Reader<mav_dds_PoseWithCovariance>::Create(
      *participant, *pose_topic, transport::Qos::State().KeepAll());
  ASSERT_TRUE(pose_reader.ok());
  auto gt_topic = transport::Topic<mav_dds_GroundTruthState>::Create(
      *participant, transport::kGroundTruthTopic, &mav_dds_GroundTruthState_desc);
  ASSERT_TRUE(gt_topic.ok());
  auto gt_reader = transport::Reader<mav_dds_GroundTruthState>::Create(
      *participant, *gt_topic, transport::Qos::State().KeepAll());
  ASSERT_TRUE(gt_reader.ok());
  ASSERT_TRUE(pose_reader->WaitForWriters(1, 15 * kNsPerSecond).ok())
      << "the localization pose writer never matched";
  ASSERT_TRUE(gt_reader->WaitForWriters(1, 15 * kNsPerSecond).ok());

  const int64_t start_ns = MonotonicNowNs();
  {
    v1::SimulatorStartRequest request;
    request.set_as_fast_as_subscribers(true);
    request.set_wait_for_subscribers(1);  // the localization service's stereo reader
    request.set_wait_timeout_s(15);
    grpc::ClientContext context;
    context.set_deadline(Deadline(20));
    v1::SimulatorStatus status;
    const grpc::Status rpc = sim->Start(&context, request, &status);
    ASSERT_TRUE(rpc.ok()) << rpc.error_message();
  }

  struct Received {
    geometry::SE3 T_world_body;
    int tracking_state;
    double variance_x;
  };
  std::map<int64_t, Received> poses;
  std::map<int64_t, geometry::SE3> truth;
  uint64_t next_sequence = 0;
  // Until every frame has its pose, or nothing arrived for 10 s (frames dropped: see below).
  const int64_t end_ns = MonotonicNowNs() + (kFrames <= 60 ? 50 : kFrames) * kNsPerSecond;
  int64_t last_arrival_ns = MonotonicNowNs();
  while (static_cast<int>(poses.size()) < kFrames && MonotonicNowNs() < end_ns &&
         MonotonicNowNs() - last_arrival_ns < 10 * kNsPerSecond) {
    ASSERT_TRUE(pose_reader->WaitForData(100'000'000).ok());
    auto gt = gt_reader->Take(512);
    ASSERT_TRUE(gt.ok());
    for (int32_t i = 0; i < gt->size(); ++i) {
      if (gt->valid(i)) truth[(*gt)[i].t_ns] = PoseOf((*gt)[i].position, (*gt)[i].orientation);
    }
    auto samples = pose_reader->Take(64);
    ASSERT_TRUE(samples.ok());
    for (int32_t i = 0; i < samples->size(); ++i) {
      if (!samples->valid(i)) continue;
      const mav_dds_PoseWithCovariance& p = (*samples)[i];
      EXPECT_EQ(p.sequence_number, next_sequence++) << "a pose went missing";
      EXPECT_STREQ(p.frame_id, "world");
      EXPECT_STREQ(p.child_frame_id, "body");
      poses[p.t_ns] = {PoseOf(p.position, p.orientation), static_cast<int>(p.tracking_state),
                       p.covariance[0]};
      last_arrival_ns = MonotonicNowNs();
    }
  }
  const double run_s = NsToSeconds(MonotonicNowNs() - start_ns);
  // The ground truth up to the last frame arrived before that frame (simulator's time order).
  auto gt = gt_reader->Take(512);
  ASSERT_TRUE(gt.ok());
  for (int32_t i = 0; i < gt->size(); ++i) {
    if (gt->valid(i)) truth[(*gt)[i].t_ns] = PoseOf((*gt)[i].position, (*gt)[i].orientation);
  }
  v1::LocalizationStatus loc_status;
  {
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    ASSERT_TRUE(loc->GetStatus(&context, v1::LocalizationGetStatusRequest(), &loc_status).ok());
  }
  // As fast as subscribers paces the simulator by DDS acknowledgements (on receipt), not by the
  // VO: frames beyond the input queue are dropped (drop-oldest). The 60 frames of the default run
  // fit the queue of 100, so none may be missing; longer measurement runs may drop some.
  const int dropped = static_cast<int>(loc_status.frames_dropped());
  if (static_cast<int>(poses.size()) + (kFrames > 100 ? dropped : 0) != kFrames) {
    // Say where the frames stopped: the simulator's side (published, subscribers: more than one
    // stereo subscriber means another stack shares this DDS domain) and the service's.
    grpc::ClientContext sim_context;
    sim_context.set_deadline(Deadline(5));
    v1::SimulatorStatus sim_status;
    (void)sim->GetStatus(&sim_context, v1::SimulatorGetStatusRequest(), &sim_status);
    ADD_FAILURE() << "simulator: " << sim_status.ShortDebugString()
                  << "\nlocalization: " << loc_status.ShortDebugString();
  }
  ASSERT_EQ(static_cast<int>(poses.size()) + (kFrames > 100 ? dropped : 0), kFrames)
      << "every frame gives a pose; see " << stack.Log("mav-localization");
  const int received = static_cast<int>(poses.size());

  // Compare: the estimate's world is the first frame's body (initial pose identity), so the
  // estimate and the truth are tied at the first frame. The ground-truth writer may match this
  // reader a few milliseconds after the reader matched it (DDS discovery runs on both sides), and
  // what it wrote before is not resent (volatile): then the tie is at the first frame that has
  // its truth, T_est_world = T_est_body(t) * T_world_body(t)^-1, and the frames before it are
  // left out of the error figures. At most the first 3.
  auto anchor = poses.begin();
  while (anchor != poses.end() && !truth.count(anchor->first)) ++anchor;
  ASSERT_TRUE(anchor != poses.end()) << "no ground truth at any frame";
  const int untied = static_cast<int>(std::distance(poses.begin(), anchor));
  ASSERT_LE(untied, 3) << "no ground truth for the first " << untied << " frames";
  const geometry::SE3 T_est_world = anchor->second.T_world_body * truth.at(anchor->first).Inverse();
  int ok = 0, lost = 0, degraded = 0;
  double path_m = 0.0, max_error_m = 0.0;
  std::optional<Eigen::Vector3d> previous;
  Eigen::Vector3d end_error = Eigen::Vector3d::Zero();
  double previous_variance = 0.0;
  for (const auto& [t_ns, received] : poses) {
    if (t_ns >= anchor->first) {
      ASSERT_TRUE(truth.count(t_ns)) << "no ground truth at " << t_ns;
      const geometry::SE3 expected = T_est_world * truth.at(t_ns);
      if (previous.has_value()) path_m += (expected.Translation() - *previous).norm();
      previous = expected.Translation();
      end_error = received.T_world_body.Translation() - expected.Translation();
      max_error_m = std::max(max_error_m, end_error.norm());
    }
    if (received.tracking_state == mav_dds_TRACKING_STATE_OK) ++ok;
    if (received.tracking_state == mav_dds_TRACKING_STATE_LOST) ++lost;
    if (received.tracking_state == mav_dds_TRACKING_STATE_DEGRADED) ++degraded;
    EXPECT_GE(received.variance_x, previous_variance);
    previous_variance = received.variance_x;
  }
  const double end_fraction = end_error.norm() / path_m;
  std::printf(
      "localization in the stack (%s): %d frames in %.1f s (%.1f frames/s), OK %d, LOST %d, "
      "DEGRADED %d, path "
      "%.2f m, end-point error %.3f m (%.2f %% of the path), max position error %.3f m; first %d "
      "frames without ground truth\n",
      v1::LocalizationMethod_Name(method).c_str(), kFrames, run_s, kFrames / run_s, ok, lost,
      degraded, path_m, end_error.norm(), 100 * end_fraction, max_error_m, untied);
  // DEGRADED poses (dense: the consistency check) are predictions, published as such.
  EXPECT_GE(ok + degraded, received - 3) << "tracking OK on all but the first frames";
  EXPECT_GT(path_m, 0.3) << "the preset moves";
  EXPECT_LT(end_fraction, 0.05);

  // The service's own view agrees.
  {
    const v1::LocalizationStatus& status = loc_status;
    EXPECT_EQ(status.frames_processed(), static_cast<uint64_t>(received));
    if (kFrames <= 100) {
      EXPECT_EQ(status.frames_dropped(), 0u);
    }
    EXPECT_EQ(status.frames_rejected(), 0u);
    // The simulator's IMU (200 Hz) reaches the odometry's gyro buffer (10 samples a frame).
    EXPECT_GT(status.gyro_samples(), static_cast<uint64_t>(received));
    EXPECT_EQ(status.frames_degraded(), static_cast<uint64_t>(degraded));
    EXPECT_EQ(status.state(), v1::LOCALIZATION_SERVICE_STATE_RUNNING);
    EXPECT_EQ(status.last_pose().t_ns(), poses.rbegin()->first);
    std::printf(
        "service: %d poses, %d dropped, %llu gyro samples, %llu DEGRADED; processing mean %.1f "
        "ms, median %.1f ms, p95 %.1f ms\n",
        received, dropped, static_cast<unsigned long long>(status.gyro_samples()),
        static_cast<unsigned long long>(status.frames_degraded()), status.processing_ms().mean_ms(),
        status.processing_ms().median_ms(), status.processing_ms().p95_ms());
  }
  {
    grpc::ClientContext context;
    context.set_deadline(Deadline(10));
    auto reader = loc->GetTrajectory(&context, v1::GetTrajectoryRequest());
    v1::TrajectoryChunk chunk;
    int points = 0;
    while (reader->Read(&chunk)) points += chunk.points_size();
    ASSERT_TRUE(reader->Finish().ok());
    EXPECT_EQ(points, received);
  }

  // Both shut down cleanly on SIGTERM.
  stack.Process("mav-localization")->Signal(SIGTERM);
  stack.Process("mav-simulator")->Signal(SIGTERM);
  const std::optional<int> loc_exit =
      stack.Process("mav-localization")->Wait(std::chrono::seconds(10));
  const std::optional<int> sim_exit =
      stack.Process("mav-simulator")->Wait(std::chrono::seconds(10));
  ASSERT_TRUE(loc_exit.has_value()) << "mav-localization ignored SIGTERM";
  ASSERT_TRUE(sim_exit.has_value()) << "mav-simulator ignored SIGTERM";
  EXPECT_EQ(*loc_exit, 0) << "see " << stack.Log("mav-localization");
  EXPECT_EQ(*sim_exit, 0) << "see " << stack.Log("mav-simulator");
}

}  // namespace
}  // namespace mav
