// The data plane over real loopback sockets, across processes:
//  * a DDS subscriber in another process (`mavctl listen`) receives every stereo frame intact
//    (CRC-32) and in order;
//  * end to end: the mav-simulator binary on a free port, driven over gRPC (health, LoadScenario,
//    Start as fast as subscribers), streams room-easy to a subscriber in this process, and shuts
//    down cleanly on SIGTERM.
// Each test uses a DDS domain derived from the pid so concurrent test runs do not cross-talk.

#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>
#include <opencv2/core.hpp>

#include "mav/common/time.h"
#include "mav/transport/dds.h"
#include "mav/transport/grpc_server.h"
#include "mav/v1/simulator.grpc.pb.h"
#include "mav_sensors.h"
#include "services/simulator/dds_io.h"
#include "tests/common/build_paths.h"
#include "tests/common/stack_process.h"
#include "tests/common/test_domain.h"

namespace mav {
namespace {

const std::string kBinDir = mav::testing::BinaryDir() + "/bin";

using ::mav::test_support::Child;  // tests/common/stack_process.h
using ::mav::test_support::FreeTcpPort;
using ::mav::test_support::TestDomain;  // tests/common/test_domain.h

// key=value pairs of the "RESULT ..." line of `mavctl listen`.
std::map<std::string, std::string> ParseResult(const std::string& output) {
  std::map<std::string, std::string> fields;
  const size_t at = output.find("RESULT ");
  if (at == std::string::npos) return fields;
  std::istringstream line(output.substr(at + 7, output.find('\n', at) - at - 7));
  std::string token;
  while (line >> token) {
    const size_t eq = token.find('=');
    if (eq != std::string::npos) fields[token.substr(0, eq)] = token.substr(eq + 1);
  }
  return fields;
}

// Two subscribers in other processes, one taking on DDS's receive thread (mavctl listen's
// default, --wake listener), one woken by a waitset.
TEST(DdsLoopbackTest, SubscribersInOtherProcessesReceiveEveryStereoFrameIntact) {
  constexpr int kFrames = 40;
  const int64_t domain = TestDomain(11);
  auto listen = [&](const std::string& wake) {
    return std::make_unique<Child>(std::vector<std::string>{
        kBinDir + "/mavctl", "listen", "--topic", "stereo", "--frames", std::to_string(kFrames),
        "--timeout", "40", "--dds-domain", std::to_string(domain), "--quiet", "--wake", wake});
  };
  std::unique_ptr<Child> listeners[] = {listen("listener"), listen("waitset")};
  for (const auto& listener : listeners) ASSERT_TRUE(listener->running());

  transport::DdsOptions options;
  options.domain = domain;
  auto sink = simulator_service::DdsStreamSink::Create(options);
  ASSERT_TRUE(sink.ok()) << sink.status().ToString();
  const auto match_deadline = std::chrono::steady_clock::now() + std::chrono::seconds(15);
  while ((*sink)->StereoSubscribers() < 2 && std::chrono::steady_clock::now() < match_deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_GE((*sink)->StereoSubscribers(), 2u) << "the two mavctl listen never matched";

  // Synthetic 752x480 pairs of seeded noise: every byte matters to the checksum.
  cv::RNG rng(42);
  const int64_t start_ns = MonotonicNowNs();
  for (int k = 0; k < kFrames; ++k) {
    simulator_service::RenderedFrame frame;
    frame.index = k;
    frame.t_ns = 1'000'000'000 + k * 50'000'000LL;
    frame.left = cv::Mat(480, 752, CV_8UC1);
    frame.right = cv::Mat(480, 752, CV_8UC1);
    rng.fill(frame.left, cv::RNG::UNIFORM, 0, 256);
    rng.fill(frame.right, cv::RNG::UNIFORM, 0, 256);
    ASSERT_TRUE((*sink)->PublishStereo(k, frame, false).ok());
    ASSERT_TRUE((*sink)->WaitForStereoAcks(5'000'000'000).ok()) << "frame " << k;
  }
  const double publish_s = NsToSeconds(MonotonicNowNs() - start_ns);

  std::printf("%d frames of 722 KB published and acknowledged in %.3f s (%.1f frames/s)\n", kFrames,
              publish_s, kFrames / publish_s);
  for (const auto& listener : listeners) {
    const std::string output = listener->ReadAll();
    const std::optional<int> exit_code = listener->Wait(std::chrono::seconds(30));
    ASSERT_TRUE(exit_code.has_value()) << "mavctl listen did not finish:\n" << output;
    EXPECT_EQ(*exit_code, 0) << output;
    const auto result = ParseResult(output);
    ASSERT_FALSE(result.empty()) << output;
    EXPECT_EQ(result.at("frames"), std::to_string(kFrames)) << output;
    EXPECT_EQ(result.at("first_seq"), "0") << output;
    EXPECT_EQ(result.at("missing"), "0") << output;
    EXPECT_EQ(result.at("out_of_order"), "0") << output;
    EXPECT_EQ(result.at("crc_failures"), "0") << output;
    EXPECT_NE(output.find("hops p50 / p99: publisher"), std::string::npos) << output;
    std::printf("%s", output.c_str());
  }
  // A wake mode that does not exist is refused before subscribing, naming the flag.
  const std::string bad_log =
      mav::testing::BinaryDir() + "/Testing/mavctl-bad-wake-" + std::to_string(::getpid()) + ".log";
  std::system(("mkdir -p " + mav::testing::BinaryDir() + "/Testing").c_str());
  Child bad(
      {kBinDir + "/mavctl", "listen", "--wake", "poll", "--dds-domain", std::to_string(domain)},
      bad_log);
  EXPECT_EQ(bad.Wait(std::chrono::seconds(10)), std::optional<int>(2));
  std::ifstream bad_file(bad_log);
  const std::string bad_output((std::istreambuf_iterator<char>(bad_file)),
                               std::istreambuf_iterator<char>());
  EXPECT_NE(bad_output.find("--wake: 'poll' is not one of listener|waitset"), std::string::npos)
      << bad_output;
}

// The simulator binary renders at SCHED_IDLE (--render-priority idle), the CRC computed ahead.
TEST(DdsLoopbackTest, SimulatorBinaryStreamsAScenarioEndToEnd) {
  constexpr int kFrames = 20;
  const int64_t domain = TestDomain(23);
  const int port = FreeTcpPort();
  const std::string target = "127.0.0.1:" + std::to_string(port);
  const std::string log = mav::testing::BinaryDir() + "/Testing/mav-simulator-e2e-" +
                          std::to_string(::getpid()) + ".log";
  std::system(("mkdir -p " + mav::testing::BinaryDir() + "/Testing").c_str());
  Child simulator({kBinDir + "/mav-simulator", "--port", std::to_string(port), "--dds-domain",
                   std::to_string(domain), "--render-priority", "idle"},
                  log);
  ASSERT_TRUE(simulator.running());

  // Health first: SERVING once the server is up.
  auto channel = grpc::CreateChannel(target, grpc::InsecureChannelCredentials());
  bool serving = false;
  const auto health_deadline = std::chrono::steady_clock::now() + std::chrono::seconds(15);
  while (!serving && std::chrono::steady_clock::now() < health_deadline) {
    auto health = transport::CheckHealth(channel, "mav.v1.Simulator", std::chrono::seconds(1));
    serving = health.ok() && *health == transport::HealthStatus::kServing;
    if (!serving) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ASSERT_TRUE(serving) << "mav-simulator did not become healthy; see " << log;

  auto stub = v1::Simulator::NewStub(channel);
  auto deadline = [] { return std::chrono::system_clock::now() + std::chrono::seconds(20); };
  {
    v1::LoadScenarioRequest request;
    request.mutable_preset()->set_name("room-easy");
    request.mutable_preset()->set_frames(kFrames);
    grpc::ClientContext context;
    context.set_deadline(deadline());
    v1::LoadScenarioResponse response;
    const grpc::Status status = stub->LoadScenario(&context, request, &response);
    ASSERT_TRUE(status.ok()) << status.error_message();
    ASSERT_EQ(response.scenario().frames(), kFrames);
  }

  // The subscriber: reliable, keep-all, as a recorder would be.
  transport::DdsOptions options;
  options.domain = domain;
  auto participant = transport::Participant::Create(options);
  ASSERT_TRUE(participant.ok()) << participant.status().ToString();
  auto topic = transport::Topic<mav_dds_StereoFrame>::Create(*participant, transport::kStereoTopic,
                                                             &mav_dds_StereoFrame_desc);
  ASSERT_TRUE(topic.ok());
  auto reader = transport::Reader<mav_dds_StereoFrame>::Create(
      *participant, *topic, transport::Qos::SensorStream().KeepAll());
  ASSERT_TRUE(reader.ok());
  auto imu_topic = transport::Topic<mav_dds_ImuSample>::Create(*participant, transport::kImuTopic,
                                                               &mav_dds_ImuSample_desc);
  ASSERT_TRUE(imu_topic.ok());
  auto imu_reader = transport::Reader<mav_dds_ImuSample>::Create(
      *participant, *imu_topic, transport::Qos::HighRate().KeepAll());
  ASSERT_TRUE(imu_reader.ok());

  {
    v1::SimulatorStartRequest request;
    request.set_as_fast_as_subscribers(true);
    request.set_wait_for_subscribers(1);
    request.set_wait_timeout_s(15);
    grpc::ClientContext context;
    context.set_deadline(deadline());
    v1::SimulatorStatus response;
    const grpc::Status status = stub->Start(&context, request, &response);
    ASSERT_TRUE(status.ok()) << status.error_message();
  }

  int received = 0;
  int64_t imu_samples = 0;
  int64_t last_imu_t = 0;
  int64_t last_frame_t = 0;
  const int64_t end_ns = MonotonicNowNs() + 50 * kNsPerSecond;
  while (received < kFrames && MonotonicNowNs() < end_ns) {
    ASSERT_TRUE(reader->WaitForData(100'000'000).ok());
    // IMU first: every sample up to a frame's time is published before the frame.
    auto imu = imu_reader->Take(256);
    ASSERT_TRUE(imu.ok());
    for (int32_t i = 0; i < imu->size(); ++i) {
      if (!imu->valid(i)) continue;
      EXPECT_EQ((*imu)[i].sequence_number, static_cast<uint64_t>(imu_samples));
      last_imu_t = (*imu)[i].t_ns;
      ++imu_samples;
    }
    auto samples = reader->Take(4);
    ASSERT_TRUE(samples.ok());
    for (int32_t i = 0; i < samples->size(); ++i) {
      if (!samples->valid(i)) continue;
      const mav_dds_StereoFrame& frame = (*samples)[i];
      EXPECT_EQ(frame.sequence_number, static_cast<uint64_t>(received)) << "frames out of order";
      const Status check = simulator_service::CheckStereoFrame(frame);
      EXPECT_TRUE(check.ok()) << check.message();
      EXPECT_EQ(frame.width, 752u);
      EXPECT_EQ(frame.height, 480u);
      EXPECT_GT(frame.t_ns, last_frame_t);
      last_frame_t = frame.t_ns;
      ++received;
    }
  }
  EXPECT_EQ(received, kFrames);
  EXPECT_GT(imu_samples, 0);
  EXPECT_LE(last_imu_t, last_frame_t);

  // The simulator says FINISHED with everything published.
  v1::SimulatorStatus status;
  const auto finish_deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  do {
    grpc::ClientContext context;
    context.set_deadline(deadline());
    ASSERT_TRUE(stub->GetStatus(&context, v1::SimulatorGetStatusRequest(), &status).ok());
    if (status.state() == v1::SIMULATOR_STATE_FINISHED) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  } while (std::chrono::steady_clock::now() < finish_deadline);
  EXPECT_EQ(status.state(), v1::SIMULATOR_STATE_FINISHED);
  EXPECT_EQ(status.frames_published(), static_cast<uint64_t>(kFrames));
  EXPECT_EQ(status.dds_domain(), static_cast<uint32_t>(domain));
  std::printf("end to end: %d frames, render mean %.1f ms, publish mean %.1f ms (incl. acks)\n",
              received, status.render_ms().mean_ms(), status.publish_ms().mean_ms());

  // Graceful shutdown on SIGTERM: exit status 0 within the grace period.
  simulator.Signal(SIGTERM);
  const std::optional<int> exit_code = simulator.Wait(std::chrono::seconds(10));
  ASSERT_TRUE(exit_code.has_value()) << "mav-simulator ignored SIGTERM";
  EXPECT_EQ(*exit_code, 0) << "see " << log;
}

}  // namespace
}  // namespace mav
