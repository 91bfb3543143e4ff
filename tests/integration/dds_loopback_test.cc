// The data plane over real loopback sockets, across processes:
//  * a DDS subscriber in another process (`mavctl listen`) receives every stereo frame intact
//    (CRC-32) and in order;
//  * end to end: the mav-simulator binary on a free port, driven over gRPC (health, LoadScenario,
//    Start as fast as subscribers), streams room-easy to a subscriber in this process, and shuts
//    down cleanly on SIGTERM;
//  * the same stream through Cyclone's shared-memory transport (iceoryx, --dds-shm).
// Each test uses a DDS domain derived from the pid so concurrent test runs do not cross-talk.

#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
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

// Waits for a `mavctl listen` (up to 60 s) and checks its RESULT line: exit 0, `frames` frames
// from sequence 0, none missing, out of order or corrupt. Its output goes to *output.
void ExpectEveryFrameIntact(Child& listener, int frames, std::string* output) {
  *output = listener.ReadAll();
  const std::optional<int> exit_code = listener.Wait(std::chrono::seconds(60));
  ASSERT_TRUE(exit_code.has_value()) << "mavctl listen did not finish:\n" << *output;
  EXPECT_EQ(*exit_code, 0) << *output;
  const auto result = ParseResult(*output);
  ASSERT_FALSE(result.empty()) << *output;
  EXPECT_EQ(result.at("frames"), std::to_string(frames)) << *output;
  EXPECT_EQ(result.at("first_seq"), "0") << *output;
  EXPECT_EQ(result.at("missing"), "0") << *output;
  EXPECT_EQ(result.at("out_of_order"), "0") << *output;
  EXPECT_EQ(result.at("crc_failures"), "0") << *output;
}

// Publishes `frames` synthetic 752x480 pairs of seeded noise (every byte matters to the
// checksum), each acknowledged by every matched reader before the next.
void PublishNoiseFrames(simulator_service::DdsStreamSink& sink, int frames) {
  cv::RNG rng(42);
  const int64_t start_ns = MonotonicNowNs();
  for (int k = 0; k < frames; ++k) {
    simulator_service::RenderedFrame frame;
    frame.index = k;
    frame.t_ns = 1'000'000'000 + k * 50'000'000LL;
    frame.left = cv::Mat(480, 752, CV_8UC1);
    frame.right = cv::Mat(480, 752, CV_8UC1);
    rng.fill(frame.left, cv::RNG::UNIFORM, 0, 256);
    rng.fill(frame.right, cv::RNG::UNIFORM, 0, 256);
    ASSERT_TRUE(sink.PublishStereo(k, frame, false).ok());
    ASSERT_TRUE(sink.WaitForStereoAcks(5'000'000'000).ok()) << "frame " << k;
  }
  const double publish_s = NsToSeconds(MonotonicNowNs() - start_ns);
  std::printf("%d frames of 722 KB published and acknowledged in %.3f s (%.1f frames/s)\n", frames,
              publish_s, frames / publish_s);
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

  ASSERT_NO_FATAL_FAILURE(PublishNoiseFrames(**sink, kFrames));
  for (const auto& listener : listeners) {
    std::string output;
    ASSERT_NO_FATAL_FAILURE(ExpectEveryFrameIntact(*listener, kFrames, &output));
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

// Runs `mavctl ARGS...` to the end (up to 60 s); its exit status, -1 if it did not finish. Its
// standard output goes to *output if given, else is printed on failure.
int Mavctl(std::vector<std::string> args, std::string* output = nullptr) {
  args.insert(args.begin(), kBinDir + "/mavctl");
  Child child(args);
  const std::string text = child.ReadAll();
  const std::optional<int> code = child.Wait(std::chrono::seconds(60));
  if (output != nullptr) {
    *output = text;
  } else if (code != std::optional<int>(0)) {
    std::printf("%s", text.c_str());
  }
  return code.value_or(-1);
}

// Starts iceoryx's RouDi with deploy/roudi.toml and waits until it answers.
void StartRoudi(const std::string& log, std::unique_ptr<Child>* roudi) {
  const std::string exe = "/usr/bin/iox-roudi";
  ASSERT_EQ(::access(exe.c_str(), X_OK), 0)
      << exe << " is missing: install Debian's iceoryx (deploy/setup.sh does)";
  *roudi = std::make_unique<Child>(
      std::vector<std::string>{exe, "-c", mav::testing::SourceDir() + "/deploy/roudi.toml"}, log);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (!transport::CheckRoudi().ok() && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_TRUE(transport::CheckRoudi().ok()) << "iox-roudi did not come up; see " << log;
}

// Cyclone's shared-memory transport (--dds-shm): the mav-simulator binary streams room-easy as
// fast as its subscriber takes it, and the frames reach `mavctl listen --dds-shm` in another
// process through iceoryx (its reader says so), intact and in order. Uses the machine's RouDi if
// one answers, else starts one with deploy/roudi.toml and stops it at the end. This process never
// joins shared memory itself: a RouDi that stops terminates every process registered with it.
// With a RouDi of its own, the test then SIGKILLs it and starts another: the simulator, whose
// shared memory is the old RouDi's, must notice and stop by itself (its restart policy would
// bring it back in the new one's).
TEST(DdsLoopbackTest, SharedMemoryCarriesEveryStereoFrameToAnotherProcess) {
  constexpr int kFrames = 40;
  std::system(("mkdir -p " + mav::testing::BinaryDir() + "/Testing").c_str());
  const std::string logs = mav::testing::BinaryDir() + "/Testing/";
  const std::string pid = std::to_string(::getpid());
  std::unique_ptr<Child> roudi;
  if (!transport::CheckRoudi().ok()) {
    ASSERT_NO_FATAL_FAILURE(StartRoudi(logs + "iox-roudi-" + pid + ".log", &roudi));
  }
  const std::string domain = std::to_string(TestDomain(31));
  const std::string port = std::to_string(FreeTcpPort());
  {
    Child simulator(
        {kBinDir + "/mav-simulator", "--port", port, "--dds-domain", domain, "--dds-shm"},
        logs + "mav-simulator-shm-" + pid + ".log");
    Child listener({kBinDir + "/mavctl", "listen", "--topic", "stereo", "--frames",
                    std::to_string(kFrames), "--timeout", "60", "--dds-domain", domain, "--quiet",
                    "--dds-shm"});
    ASSERT_TRUE(simulator.running() && listener.running());
    int health = -1;
    for (int i = 0; i < 100 && health != 0; ++i) {
      health = Mavctl({"health", "--port", port, "--timeout", "1"});
      if (health != 0) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    ASSERT_EQ(health, 0) << "mav-simulator did not come up; see " << logs;
    ASSERT_EQ(Mavctl({"sim", "load", "--port", port, "--preset", "room-easy", "--frames",
                      std::to_string(kFrames)}),
              0);
    ASSERT_EQ(Mavctl({"sim", "start", "--port", port, "--fast", "--wait-subscribers", "1",
                      "--wait-timeout", "20"}),
              0);

    std::string output;
    ASSERT_NO_FATAL_FAILURE(ExpectEveryFrameIntact(listener, kFrames, &output));
    EXPECT_EQ(ParseResult(output).at("shm"), "1") << "the reader is not in shared memory:\n"
                                                  << output;
    EXPECT_NE(output.find("shared memory, keep last 16"), std::string::npos) << output;
    std::printf("%s", output.c_str());
    // The writer's side: the simulator says its stereo writer is in shared memory too.
    std::string status;
    EXPECT_EQ(Mavctl({"sim", "status", "--port", port}, &status), 0);
    EXPECT_NE(status.find("stereo in shared memory"), std::string::npos) << status;
    if (roudi != nullptr) {
      roudi->Signal(SIGKILL);
      EXPECT_TRUE(roudi->Wait(std::chrono::seconds(10)).has_value());
      ASSERT_NO_FATAL_FAILURE(StartRoudi(logs + "iox-roudi-2-" + pid + ".log", &roudi));
    } else {
      std::printf("(a RouDi this test did not start is running: its restart is not tested)\n");
      simulator.Signal(SIGTERM);
    }
    EXPECT_EQ(simulator.Wait(std::chrono::seconds(10)), std::optional<int>(0));
    std::ifstream sim_log(logs + "mav-simulator-shm-" + pid + ".log");
    const std::string sim_output((std::istreambuf_iterator<char>(sim_log)),
                                 std::istreambuf_iterator<char>());
    if (roudi != nullptr) {
      EXPECT_NE(sim_output.find("was restarted"), std::string::npos) << sim_output;
    }
  }
  if (roudi != nullptr) {  // SIGTERM: RouDi removes its shared memory and socket on the way out
    roudi->Signal(SIGTERM);
    EXPECT_TRUE(roudi->Wait(std::chrono::seconds(15)).has_value());
  }
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
