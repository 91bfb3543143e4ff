// DDS Security on the data plane (issue 31): certificates from deploy/dds-security/make-certs.sh
// (made once per run into build/Testing), the mav-simulator binary with its own identity
// (--dds-security OUT/mav-simulator) streaming room-easy in a loop, and participants in this
// process with other identities, one at a time (Cyclone takes one configuration per domain and
// process; the domain goes with the last participant, so each identity gets a fresh one):
//  * a participant without credentials matches no writer and receives no stereo frame, and its
//    actuator writer matches no reader (the simulator's), so its commands reach no rotor; with
//    mavctl's identity the same reader receives the frames (the control);
//  * mavctl's identity may read actuator commands but not write them: creating the writer is
//    refused (FailedPrecondition naming the permissions); mav-control's identity matches;
//  * a certificate that expired cannot create a participant at all, and one signed by another
//    CA matches nothing.

#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <optional>
#include <string>
#include <thread>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>

#include "mav/common/file.h"
#include "mav/common/time.h"
#include "mav/transport/dds.h"
#include "mav/v1/simulator.grpc.pb.h"
#include "mav_control.h"
#include "mav_sensors.h"
#include "tests/common/build_paths.h"
#include "tests/common/stack_fixture.h"

namespace mav {
namespace {

// How long a participant is given to match (or, for the refused ones, to fail to): discovery and
// the authentication handshake take ~0.1 s on loopback.
constexpr int64_t kMatchWindowNs = 3 * kNsPerSecond;

class DdsSecurityTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    certs_ = new std::string(mav::testing::BinaryDir() + "/Testing/dds-security-" +
                             std::to_string(::getpid()));
    const std::string command =
        "bash " + mav::testing::SourceDir() + "/deploy/dds-security/make-certs.sh " + *certs_ +
        " --force --extra-expired expired --extra-foreign intruder > " + *certs_ + ".log 2>&1";
    make_certs_status_ = std::system(command.c_str());
  }
  static void TearDownTestSuite() {
    std::system(("rm -rf " + *certs_ + " " + *certs_ + ".log").c_str());
    delete certs_;
  }

  void SetUp() override {
    ASSERT_EQ(make_certs_status_, 0) << *ReadFileToString(*certs_ + ".log");
    stack_ = std::make_unique<test_support::Stack>(/*domain_key=*/64);
    const std::string target = stack_->Start("mav-simulator", "mav.v1.Simulator",
                                             {"--dds-security", Identity("mav-simulator")});
    ASSERT_FALSE(target.empty()) << *ReadFileToString(stack_->Log("mav-simulator"));
    auto stub = v1::Simulator::NewStub(stack_->Channel("mav-simulator"));
    v1::LoadScenarioRequest load;
    load.mutable_preset()->set_name("room-easy");
    load.mutable_preset()->set_frames(20);
    v1::LoadScenarioResponse loaded;
    grpc::ClientContext load_context;
    load_context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
    ASSERT_TRUE(stub->LoadScenario(&load_context, load, &loaded).ok());
    v1::SimulatorStartRequest start;
    start.set_real_time_factor(1.0);
    start.set_loop(true);
    v1::SimulatorStatus started;
    grpc::ClientContext start_context;
    start_context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
    ASSERT_TRUE(stub->Start(&start_context, start, &started).ok());
  }

  static std::string Identity(const std::string& name) { return *certs_ + "/" + name; }

  transport::DdsOptions Options(const std::string& identity) const {
    transport::DdsOptions options;
    options.domain = stack_->domain();
    if (!identity.empty()) options.security_dir = Identity(identity);
    return options;
  }

  struct Received {
    uint32_t matched_writers = 0;
    int64_t frames = 0;
  };

  // Subscribes to the stereo stream as `identity` ("" = no security) for the match window.
  static Result<Received> ReceiveStereo(const transport::DdsOptions& options) {
    MAV_ASSIGN_OR_RETURN(transport::Participant participant,
                         transport::Participant::Create(options));
    MAV_ASSIGN_OR_RETURN(auto topic,
                         transport::Topic<mav_dds_StereoFrame>::Create(
                             participant, transport::kStereoTopic, &mav_dds_StereoFrame_desc));
    MAV_ASSIGN_OR_RETURN(auto reader, transport::Reader<mav_dds_StereoFrame>::Create(
                                          participant, topic, transport::Qos::SensorStream()));
    Received out;
    const int64_t end_ns = MonotonicNowNs() + kMatchWindowNs;
    while (MonotonicNowNs() < end_ns && out.frames < 3) {
      MAV_RETURN_IF_ERROR(reader.WaitForData(100'000'000).status());
      MAV_ASSIGN_OR_RETURN(auto samples, reader.Take(4));
      for (int32_t i = 0; i < samples.size(); ++i) out.frames += samples.valid(i) ? 1 : 0;
    }
    MAV_ASSIGN_OR_RETURN(out.matched_writers, reader.MatchedWriters());
    return out;
  }

  // Creates an actuator-command writer as `identity` and returns how many readers it matched
  // within the match window (the simulator's is the only one).
  static Result<uint32_t> ActuatorReadersMatched(const transport::DdsOptions& options) {
    MAV_ASSIGN_OR_RETURN(transport::Participant participant,
                         transport::Participant::Create(options));
    MAV_ASSIGN_OR_RETURN(
        auto topic, transport::Topic<mav_dds_ActuatorCommand>::Create(
                        participant, transport::kActuatorTopic, &mav_dds_ActuatorCommand_desc));
    MAV_ASSIGN_OR_RETURN(auto writer, transport::Writer<mav_dds_ActuatorCommand>::Create(
                                          participant, topic, transport::Qos::Command()));
    const int64_t end_ns = MonotonicNowNs() + kMatchWindowNs;
    uint32_t matched = 0;
    while (MonotonicNowNs() < end_ns && matched == 0) {
      MAV_ASSIGN_OR_RETURN(matched, writer.MatchedReaders());
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return matched;
  }

  static std::string* certs_;
  static int make_certs_status_;
  std::unique_ptr<test_support::Stack> stack_;
};

std::string* DdsSecurityTest::certs_ = nullptr;
int DdsSecurityTest::make_certs_status_ = -1;

TEST_F(DdsSecurityTest, ASubscriberWithoutCredentialsGetsNoFrame) {
  Result<Received> open = ReceiveStereo(Options(""));
  ASSERT_TRUE(open.ok()) << open.status().ToString();
  EXPECT_EQ(open->matched_writers, 0u);
  EXPECT_EQ(open->frames, 0);

  Result<Received> mavctl = ReceiveStereo(Options("mavctl"));
  ASSERT_TRUE(mavctl.ok()) << mavctl.status().ToString();
  EXPECT_EQ(mavctl->matched_writers, 1u);
  EXPECT_GE(mavctl->frames, 3) << "the control: an authenticated subscriber gets the stream";
}

TEST_F(DdsSecurityTest, OnlyMavControlMayCommandTheRotors) {
  Result<uint32_t> open = ActuatorReadersMatched(Options(""));
  ASSERT_TRUE(open.ok()) << open.status().ToString();
  EXPECT_EQ(*open, 0u) << "a writer without credentials reached the simulator's actuator reader";

  Result<uint32_t> mavctl = ActuatorReadersMatched(Options("mavctl"));
  ASSERT_FALSE(mavctl.ok()) << "mavctl's identity may not write actuator commands";
  EXPECT_EQ(mavctl.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(mavctl.status().message().find("dds_create_writer(mav/control/actuators)"),
            std::string::npos)
      << mavctl.status().message();
  EXPECT_NE(mavctl.status().message().find("permissions"), std::string::npos)
      << mavctl.status().message();

  Result<uint32_t> control = ActuatorReadersMatched(Options("mav-control"));
  ASSERT_TRUE(control.ok()) << control.status().ToString();
  EXPECT_EQ(*control, 1u) << "the control: mav-control's commands reach the simulator";
}

TEST_F(DdsSecurityTest, ExpiredAndForeignCertificatesAreRefused) {
  Result<transport::Participant> expired = transport::Participant::Create(Options("expired"));
  ASSERT_FALSE(expired.ok()) << "an expired certificate made a participant";
  EXPECT_NE(expired.status().message().find("DDS Security identity " + Identity("expired")),
            std::string::npos)
      << expired.status().message();

  Result<Received> foreign = ReceiveStereo(Options("intruder"));
  ASSERT_TRUE(foreign.ok()) << foreign.status().ToString();
  EXPECT_EQ(foreign->matched_writers, 0u);
  EXPECT_EQ(foreign->frames, 0);
  Result<uint32_t> foreign_writer = ActuatorReadersMatched(Options("intruder"));
  ASSERT_TRUE(foreign_writer.ok()) << foreign_writer.status().ToString();
  EXPECT_EQ(*foreign_writer, 0u);
}

// The flag's own checks, before any DDS call: a missing directory or file is named.
TEST(DdsSecurityDirTest, AMissingIdentityFileIsNamed) {
  Result<std::string> missing = transport::CheckSecurityDir("/nonexistent/mav", "--dds-security");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.status().message().find("--dds-security: /nonexistent/mav: not a directory"),
            std::string::npos)
      << missing.status().message();
  const std::string dir =
      mav::testing::BinaryDir() + "/Testing/dds-security-empty-" + std::to_string(::getpid());
  std::system(("mkdir -p " + dir).c_str());
  Result<std::string> empty = transport::CheckSecurityDir(dir, "--dds-security");
  std::system(("rm -rf " + dir).c_str());
  ASSERT_FALSE(empty.ok());
  EXPECT_NE(empty.status().message().find(dir + "/identity_ca.pem"), std::string::npos)
      << empty.status().message();
  Result<std::string> comma = transport::CheckSecurityDir("/tmp/a,b", "--dds-security");
  ASSERT_FALSE(comma.ok());
  EXPECT_NE(comma.status().message().find("comma"), std::string::npos);
}

}  // namespace
}  // namespace mav
