// The transport layer under the simulator service: the shared flag parser (clear errors naming
// the flag), server options from flags and environment, and the RAII layer over Cyclone DDS
// (typed write/take with loans, matched counts, waits, errors with dds_strretcode text).

#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include <grpcpp/grpcpp.h>

#include "mav/v1/control.grpc.pb.h"

#include "mav/transport/dds.h"
#include "mav/transport/flags.h"
#include "mav/transport/grpc_server.h"
#include "mav_sensors.h"
#include "services/simulator/dds_io.h"
#include "tests/common/build_paths.h"
#include "tests/common/test_domain.h"

namespace mav::transport {
namespace {

using ::mav::test_support::TestDomain;  // tests/common/test_domain.h

TEST(FlagParserTest, ParsesAllKindsAndBothSyntaxes) {
  std::string name = "x";
  int64_t count = 1;
  double rate = 1.0;
  bool fast = false;
  FlagParser flags("prog", "");
  flags.AddString("name", &name, "");
  flags.AddInt("count", &count, "");
  flags.AddDouble("rate", &rate, "");
  flags.AddBool("fast", &fast, "");
  std::vector<std::string> positional;
  ASSERT_TRUE(
      flags.Parse({"--name", "abc", "--count=42", "pos", "--rate", "0.5", "--fast"}, &positional)
          .ok());
  EXPECT_EQ(name, "abc");
  EXPECT_EQ(count, 42);
  EXPECT_DOUBLE_EQ(rate, 0.5);
  EXPECT_TRUE(fast);
  EXPECT_EQ(positional, std::vector<std::string>{"pos"});
  EXPECT_TRUE(flags.WasSet("count"));
  ASSERT_TRUE(flags.Parse({"--fast=false"}, nullptr).ok());
  EXPECT_FALSE(fast);
}

TEST(FlagParserTest, BadInputNamesTheFlag) {
  int64_t port = 0;
  bool fast = false;
  FlagParser flags("prog", "");
  flags.AddInt("port", &port, "");
  flags.AddBool("fast", &fast, "");
  Status s = flags.Parse({"--port", "abc"}, nullptr);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(s.message().rfind("--port:", 0), 0u) << s.message();
  s = flags.Parse({"--prot", "1"}, nullptr);
  EXPECT_NE(s.message().find("unknown flag --prot"), std::string::npos) << s.message();
  s = flags.Parse({"--port"}, nullptr);
  EXPECT_NE(s.message().find("--port: missing value"), std::string::npos) << s.message();
  s = flags.Parse({"--fast=maybe"}, nullptr);
  EXPECT_EQ(s.message().rfind("--fast:", 0), 0u) << s.message();
  s = flags.Parse({"stray"}, nullptr);
  EXPECT_FALSE(s.ok());
  bool help = false;
  EXPECT_TRUE(flags.Parse({"--help"}, nullptr, &help).ok());
  EXPECT_TRUE(help);
}

TEST(ServerOptionsTest, FlagBeatsEnvironmentBeatsDefault) {
  ServerOptions options;
  options.port = 50051;
  FlagParser flags("prog", "");
  AddServerFlags(&flags, &options, "MAV_TEST_TRANSPORT_PORT");
  ASSERT_TRUE(flags.Parse({}, nullptr).ok());
  ::setenv("MAV_TEST_TRANSPORT_PORT", "50999", 1);
  ASSERT_TRUE(ApplyPortEnv(flags, "MAV_TEST_TRANSPORT_PORT", &options).ok());
  EXPECT_EQ(options.port, 50999);
  ASSERT_TRUE(flags.Parse({"--port", "50123"}, nullptr).ok());
  ASSERT_TRUE(ApplyPortEnv(flags, "MAV_TEST_TRANSPORT_PORT", &options).ok());
  EXPECT_EQ(options.port, 50123);

  ServerOptions bad;
  FlagParser flags2("prog", "");
  AddServerFlags(&flags2, &bad, "MAV_TEST_TRANSPORT_PORT");
  ::setenv("MAV_TEST_TRANSPORT_PORT", "70000", 1);
  const Status s = ApplyPortEnv(flags2, "MAV_TEST_TRANSPORT_PORT", &bad);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("MAV_TEST_TRANSPORT_PORT"), std::string::npos);
  ::unsetenv("MAV_TEST_TRANSPORT_PORT");
  std::string why;
  bad.port = -1;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_EQ(why.rfind("port:", 0), 0u);
}

TEST(GrpcServerTest, ABusyPortIsUnavailableNamingTheAddress) {
  ServerOptions options;
  auto first = GrpcServer::Start(options, {});
  ASSERT_TRUE(first.ok());
  options.port = (*first)->port();
  auto second = GrpcServer::Start(options, {});
  ASSERT_FALSE(second.ok());
  EXPECT_EQ(second.status().code(), StatusCode::kUnavailable);
  EXPECT_NE(second.status().message().find("127.0.0.1:" + std::to_string(options.port)),
            std::string::npos)
      << second.status().message();
}

// A service whose GetState takes 300 ms, to hold gRPC's threads.
class SlowControl : public mav::v1::Control::Service {
 public:
  grpc::Status GetState(grpc::ServerContext*, const mav::v1::ControlGetStateRequest*,
                        mav::v1::ControlState*) override {
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    return grpc::Status::OK;
  }
};

// 12 slow calls at once against a server of `max_threads`: the codes they end with.
std::map<grpc::StatusCode, int> TwelveSlowCalls(int64_t max_threads) {
  SlowControl service;
  ServerOptions options;
  options.max_threads = max_threads;
  auto server = GrpcServer::Start(options, {&service});
  EXPECT_TRUE(server.ok()) << server.status().ToString();
  if (!server.ok()) return {};
  auto stub = mav::v1::Control::NewStub(
      grpc::CreateChannel((*server)->target(), grpc::InsecureChannelCredentials()));
  std::mutex mutex;
  std::map<grpc::StatusCode, int> codes;
  std::vector<std::thread> calls;
  calls.reserve(12);
  for (int i = 0; i < 12; ++i) {
    calls.emplace_back([&] {
      grpc::ClientContext context;
      context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
      mav::v1::ControlState state;
      const grpc::Status status = stub->GetState(&context, {}, &state);
      std::lock_guard<std::mutex> lock(mutex);
      ++codes[status.error_code()];
    });
  }
  for (std::thread& t : calls) t.join();
  return codes;
}

TEST(GrpcServerTest, MaxThreadsRefusesTheCallsThatFindNoThread) {
  std::map<grpc::StatusCode, int> bounded = TwelveSlowCalls(4);
  EXPECT_GT(bounded[grpc::StatusCode::OK], 0);
  EXPECT_GT(bounded[grpc::StatusCode::RESOURCE_EXHAUSTED], 0);
  EXPECT_EQ(bounded[grpc::StatusCode::OK] + bounded[grpc::StatusCode::RESOURCE_EXHAUSTED], 12);
  std::map<grpc::StatusCode, int> unbounded = TwelveSlowCalls(0);
  EXPECT_EQ(unbounded[grpc::StatusCode::OK], 12);

  ServerOptions bad;
  bad.max_threads = 2;
  std::string why;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_EQ(why.rfind("max_threads: 2 is outside [4, 10000]", 0), 0u) << why;
}

TEST(DdsOptionsTest, ConfigResolutionAndDomainValidation) {
  DdsOptions options;
  ::unsetenv("CYCLONEDDS_URI");
  EXPECT_EQ(options.ResolvedConfig(), LoopbackDdsConfig());
  options.config = "/etc/x.xml";
  EXPECT_EQ(options.ResolvedConfig(), "file:///etc/x.xml");
  options.config = "<CycloneDDS/>";
  EXPECT_EQ(options.ResolvedConfig(), "<CycloneDDS/>");
  options.config.clear();
  ::setenv("CYCLONEDDS_URI", "file:///tmp/from-env.xml", 1);
  EXPECT_EQ(options.ResolvedConfig(), "file:///tmp/from-env.xml");
  ::unsetenv("CYCLONEDDS_URI");
  options.domain = 231;
  std::string why;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_NE(why.find("domain"), std::string::npos);
  const auto participant = Participant::Create(options);
  EXPECT_EQ(participant.status().code(), StatusCode::kInvalidArgument);
}

// Shared memory (iceoryx): the flag and MAV_DDS_SHM, the fragment appended to the config, the
// refusal to combine it with DDS Security, and the RouDi check that keeps a participant from
// waiting forever for a daemon that is not there (a missing socket, and a stale one).
TEST(DdsOptionsTest, SharedMemoryFlagEnvironmentConfigAndRoudiCheck) {
  ::unsetenv("CYCLONEDDS_URI");
  ::unsetenv("MAV_DDS_SHM");
  {
    FlagParser flags("t", "");
    DdsOptions options;
    AddDdsFlags(&flags, &options);
    ASSERT_TRUE(flags.Parse({"--dds-shm"}, nullptr).ok());
    ASSERT_TRUE(ApplyDdsEnv(flags, &options).ok());
    EXPECT_TRUE(options.shared_memory);
    EXPECT_EQ(options.ResolvedConfig(),
              std::string(LoopbackDdsConfig()) + "," + SharedMemoryConfig());
  }
  for (const auto& [value, on] :
       std::vector<std::pair<std::string, bool>>{{"1", true}, {"0", false}}) {
    FlagParser flags("t", "");
    DdsOptions options;
    AddDdsFlags(&flags, &options);
    ASSERT_TRUE(flags.Parse({}, nullptr).ok());
    ::setenv("MAV_DDS_SHM", value.c_str(), 1);
    ASSERT_TRUE(ApplyDdsEnv(flags, &options).ok());
    EXPECT_EQ(options.shared_memory, on) << value;
  }
  {
    FlagParser flags("t", "");
    DdsOptions options;
    AddDdsFlags(&flags, &options);
    ASSERT_TRUE(flags.Parse({}, nullptr).ok());
    ::setenv("MAV_DDS_SHM", "yes", 1);
    const Status status = ApplyDdsEnv(flags, &options);
    EXPECT_EQ(status.code(), StatusCode::kInvalidArgument);
    EXPECT_NE(status.message().find("MAV_DDS_SHM: 'yes'"), std::string::npos) << status.message();
  }
  ::unsetenv("MAV_DDS_SHM");

  DdsOptions both;
  both.shared_memory = true;
  both.security_dir = "/tmp/identity";
  std::string why;
  EXPECT_FALSE(both.IsValid(&why));
  EXPECT_NE(why.find("cannot be combined"), std::string::npos) << why;
  EXPECT_EQ(Participant::Create(both).status().code(), StatusCode::kInvalidArgument);

  const std::string missing = "/tmp/mav-no-roudi-" + std::to_string(::getpid());
  Status status = CheckRoudi(missing);
  EXPECT_EQ(status.code(), StatusCode::kUnavailable);
  EXPECT_NE(status.message().find(missing), std::string::npos) << status.message();
  EXPECT_NE(status.message().find("iox-roudi"), std::string::npos) << status.message();

  // A socket file nobody listens on any more, as a RouDi that was killed leaves behind.
  const std::string stale = "/tmp/mav-stale-roudi-" + std::to_string(::getpid());
  {
    const int fd = ::socket(AF_UNIX, SOCK_DGRAM, 0);
    ASSERT_GE(fd, 0);
    sockaddr_un address{};
    address.sun_family = AF_UNIX;
    std::snprintf(address.sun_path, sizeof(address.sun_path), "%s", stale.c_str());
    ASSERT_EQ(::bind(fd, reinterpret_cast<const sockaddr*>(&address), sizeof(address)), 0);
    EXPECT_TRUE(CheckRoudi(stale).ok());  // bound: answers
    ::close(fd);
  }
  status = CheckRoudi(stale);
  EXPECT_EQ(status.code(), StatusCode::kUnavailable);
  EXPECT_NE(status.message().find("Connection refused"), std::string::npos) << status.message();
  ::unlink(stale.c_str());
  EXPECT_EQ(CheckRoudi(std::string(200, 'x')).code(), StatusCode::kInvalidArgument);
}

TEST(DdsTest, ABrokenConfigFailsWithTheDdsReason) {
  DdsOptions options;
  options.domain = TestDomain(1);
  options.config = "<CycloneDDS><Domain><Bogus>1</Bogus></Domain></CycloneDDS>";
  const auto participant = Participant::Create(options);
  ASSERT_FALSE(participant.ok());
  EXPECT_NE(participant.status().message().find("dds_create_domain"), std::string::npos)
      << participant.status().message();
}

TEST(DdsTest, TheDeployedConfigFileWorks) {
  DdsOptions options;
  options.domain = TestDomain(3);
  options.config = mav::testing::SourceDir() + "/deploy/cyclonedds.xml";
  const auto participant = Participant::Create(options);
  EXPECT_TRUE(participant.ok()) << participant.status().ToString();
}

TEST(DdsTest, TypedWriteAndLoanedTakeInOneProcess) {
  DdsOptions options;
  options.domain = TestDomain(2);
  auto participant = Participant::Create(options);
  ASSERT_TRUE(participant.ok()) << participant.status().ToString();
  // A second participant of the same domain shares the domain instance.
  auto participant2 = Participant::Create(options);
  ASSERT_TRUE(participant2.ok()) << participant2.status().ToString();

  auto topic =
      Topic<mav_dds_StereoFrame>::Create(*participant, kStereoTopic, &mav_dds_StereoFrame_desc);
  ASSERT_TRUE(topic.ok()) << topic.status().ToString();
  auto topic2 =
      Topic<mav_dds_StereoFrame>::Create(*participant2, kStereoTopic, &mav_dds_StereoFrame_desc);
  ASSERT_TRUE(topic2.ok()) << topic2.status().ToString();
  auto writer = Writer<mav_dds_StereoFrame>::Create(*participant, *topic, Qos::SensorStream());
  ASSERT_TRUE(writer.ok()) << writer.status().ToString();
  auto reader =
      Reader<mav_dds_StereoFrame>::Create(*participant2, *topic2, Qos::SensorStream().KeepAll());
  ASSERT_TRUE(reader.ok()) << reader.status().ToString();
  ASSERT_TRUE(writer->WaitForReaders(1, 5'000'000'000).ok());
  ASSERT_TRUE(reader->WaitForWriters(1, 5'000'000'000).ok());
  EXPECT_EQ(*writer->MatchedReaders(), 1u);

  // Nothing yet: WaitForData times out with false, Take gives zero samples.
  auto waited = reader->WaitForData(10'000'000);
  ASSERT_TRUE(waited.ok());
  EXPECT_FALSE(*waited);

  cv::RNG rng(3);
  constexpr int kFrames = 5;
  std::vector<uint32_t> crcs;
  for (int k = 0; k < kFrames; ++k) {
    simulator_service::RenderedFrame frame;
    frame.t_ns = 1000 + k;
    frame.left = cv::Mat(480, 752, CV_8UC1);
    frame.right = cv::Mat(480, 752, CV_8UC1);
    rng.fill(frame.left, cv::RNG::UNIFORM, 0, 256);
    rng.fill(frame.right, cv::RNG::UNIFORM, 0, 256);
    mav_dds_StereoFrame sample;
    simulator_service::FillStereoFrame(k, frame, false, 0, &sample);
    crcs.push_back(sample.crc32);
    ASSERT_TRUE(writer->Write(sample).ok());
  }
  ASSERT_TRUE(writer->WaitForAcks(5'000'000'000).ok());
  int received = 0;
  while (received < kFrames) {
    auto ready = reader->WaitForData(2'000'000'000);
    ASSERT_TRUE(ready.ok());
    ASSERT_TRUE(*ready) << "only " << received << " frames arrived";
    auto samples = reader->Take(2);
    ASSERT_TRUE(samples.ok()) << samples.status().ToString();
    for (int32_t i = 0; i < samples->size(); ++i) {
      ASSERT_TRUE(samples->valid(i));
      const mav_dds_StereoFrame& frame = (*samples)[i];
      EXPECT_EQ(frame.sequence_number, static_cast<uint64_t>(received));
      EXPECT_EQ(frame.t_ns, 1000 + received);
      EXPECT_EQ(frame.crc32, crcs[received]);
      EXPECT_TRUE(simulator_service::CheckStereoFrame(frame).ok());
      EXPECT_STREQ(frame.left_camera_id, "cam0");
      ++received;
    }
  }
  // Moving an entity transfers ownership: the moved-from one no longer deletes anything.
  Writer<mav_dds_StereoFrame> moved = std::move(*writer);
  EXPECT_TRUE(moved.valid());
  EXPECT_FALSE(writer->valid());
}

// Reader::OnData: the callback takes the samples on the delivering thread; it survives a move of
// the reader and is not called once cleared. The sink's CRC computed ahead is the sample's.
TEST(DdsTest, TheDataListenerTakesOnTheDeliveringThreadAndStopsWhenCleared) {
  DdsOptions options;
  options.domain = TestDomain(3);
  auto participant = Participant::Create(options);
  ASSERT_TRUE(participant.ok()) << participant.status().ToString();
  auto topic =
      Topic<mav_dds_StereoFrame>::Create(*participant, kStereoTopic, &mav_dds_StereoFrame_desc);
  ASSERT_TRUE(topic.ok()) << topic.status().ToString();
  auto writer = Writer<mav_dds_StereoFrame>::Create(*participant, *topic, Qos::SensorStream());
  ASSERT_TRUE(writer.ok()) << writer.status().ToString();
  auto created =
      Reader<mav_dds_StereoFrame>::Create(*participant, *topic, Qos::SensorStream().KeepAll());
  ASSERT_TRUE(created.ok()) << created.status().ToString();
  ASSERT_TRUE(writer->WaitForReaders(1, 5'000'000'000).ok());

  std::mutex mutex;
  std::vector<uint64_t> sequences;
  std::vector<uint32_t> crcs;
  std::thread::id callback_thread;
  std::atomic<Reader<mav_dds_StereoFrame>*> current{&*created};
  ASSERT_TRUE(created
                  ->OnData([&] {
                    auto samples = current.load()->Take(4);
                    std::lock_guard<std::mutex> lock(mutex);
                    callback_thread = std::this_thread::get_id();
                    ASSERT_TRUE(samples.ok());
                    for (int32_t i = 0; i < samples->size(); ++i) {
                      if (!samples->valid(i)) continue;
                      sequences.push_back((*samples)[i].sequence_number);
                      crcs.push_back((*samples)[i].crc32);
                    }
                  })
                  .ok());
  // Moving the reader keeps its callback (the listener's argument lives on the heap).
  Reader<mav_dds_StereoFrame> reader = std::move(*created);
  current.store(&reader);
  simulator_service::RenderedFrame frame;
  frame.left = cv::Mat(48, 64, CV_8UC1, cv::Scalar(5));
  frame.right = cv::Mat(48, 64, CV_8UC1, cv::Scalar(9));
  auto write = [&](uint64_t sequence) {
    mav_dds_StereoFrame sample;
    simulator_service::FillStereoFrame(sequence, frame, false, 0, &sample);
    ASSERT_TRUE(writer->Write(sample).ok());
  };
  const uint32_t computed_here = [&] {
    mav_dds_StereoFrame sample;
    simulator_service::FillStereoFrame(0, frame, false, 0, &sample);
    return sample.crc32;
  }();
  // The sink computes the same CRC ahead, and FillStereoFrame then takes the frame's.
  auto sink = simulator_service::DdsStreamSink::Create(options);
  ASSERT_TRUE(sink.ok()) << sink.status().ToString();
  (*sink)->PrepareStereo(&frame);
  ASSERT_TRUE(frame.crc32.has_value());
  EXPECT_EQ(*frame.crc32, computed_here);
  for (uint64_t k = 0; k < 3; ++k) write(k);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (std::chrono::steady_clock::now() < deadline) {
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (sequences.size() >= 3) break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  {
    std::lock_guard<std::mutex> lock(mutex);
    EXPECT_EQ(sequences, (std::vector<uint64_t>{0, 1, 2}));
    EXPECT_EQ(crcs, (std::vector<uint32_t>(3, computed_here)));
    // In one process Cyclone delivers on the writer's thread (dds_write): here, this one.
    EXPECT_EQ(callback_thread, std::this_thread::get_id());
  }

  // Cleared: later samples stay in the reader for Take.
  ASSERT_TRUE(reader.ClearOnData().ok());
  write(3);
  ASSERT_TRUE(writer->WaitForAcks(5'000'000'000).ok());
  auto ready = reader.WaitForData(2'000'000'000);
  ASSERT_TRUE(ready.ok() && *ready);
  auto left = reader.Take(4);
  ASSERT_TRUE(left.ok());
  ASSERT_EQ(left->size(), 1);
  EXPECT_EQ((*left)[0].sequence_number, 3u);
  std::lock_guard<std::mutex> lock(mutex);
  EXPECT_EQ(sequences.size(), 3u);
}

TEST(DdsTest, CheckStereoFrameNamesTheCorruptField) {
  simulator_service::RenderedFrame frame;
  frame.left = cv::Mat(4, 6, CV_8UC1, cv::Scalar(1));
  frame.right = cv::Mat(4, 6, CV_8UC1, cv::Scalar(2));
  mav_dds_StereoFrame sample;
  simulator_service::FillStereoFrame(9, frame, true, 0, &sample);
  EXPECT_TRUE(simulator_service::CheckStereoFrame(sample).ok());
  frame.right.at<uint8_t>(3, 5) = 7;  // the sample borrows the buffer: a flipped byte
  Status s = simulator_service::CheckStereoFrame(sample);
  EXPECT_EQ(s.code(), StatusCode::kDataLoss);
  EXPECT_NE(s.message().find("crc32"), std::string::npos) << s.message();
  sample.left._length = 5;
  s = simulator_service::CheckStereoFrame(sample);
  EXPECT_NE(s.message().find("left: 5 bytes"), std::string::npos) << s.message();
}

TEST(DdsTest, ErrorCodesCarryTheDdsText) {
  const Status s = DdsStatus(DDS_RETCODE_BAD_PARAMETER, "dds_write(x)");
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(s.message().rfind("dds_write(x): ", 0), 0u);
  EXPECT_GT(s.message().size(), std::string("dds_write(x): ").size());
  EXPECT_TRUE(DdsStatus(0, "ok").ok());
}

}  // namespace
}  // namespace mav::transport
