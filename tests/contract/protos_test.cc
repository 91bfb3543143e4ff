// The generated contract code compiles, links and behaves as docs/contracts.md says: protobuf
// messages round-trip, every service has the documented RPCs with the documented streaming
// shape, and a DDS StereoFrame travels writer -> reader in-process with its CRC-32 intact and
// its key (rig_id) separating instances.

#include <gtest/gtest.h>
#include <unistd.h>
#include <zlib.h>

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "dds/dds.h"
#include "mav/v1/common.pb.h"
#include "mav/v1/control.grpc.pb.h"
#include "mav/v1/localization.grpc.pb.h"
#include "mav/v1/mapping.grpc.pb.h"
#include "mav/v1/planning.grpc.pb.h"
#include "mav/v1/simulator.grpc.pb.h"
#include "mav_control.h"
#include "mav_sensors.h"
#include "mav_state.h"

namespace {

constexpr uint32_t kWidth = 752;
constexpr uint32_t kHeight = 480;

std::string MakeImage(uint32_t seed) {
  std::string data(kWidth * kHeight, '\0');
  uint32_t x = seed * 2654435761u + 1;
  for (char& c : data) {
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    c = static_cast<char>(x & 0xff);
  }
  return data;
}

uint32_t Crc32(const uint8_t* left, size_t left_size, const uint8_t* right, size_t right_size) {
  uLong crc = crc32(0L, Z_NULL, 0);
  crc = crc32(crc, left, static_cast<uInt>(left_size));
  crc = crc32(crc, right, static_cast<uInt>(right_size));
  return static_cast<uint32_t>(crc);
}

TEST(ProtosTest, StereoPairRoundTripsBelowTheDefaultMessageLimit) {
  mav::v1::StereoPair pair;
  pair.set_t_ns(1403636579763555584);
  for (auto [image, seed] : {std::pair{pair.mutable_left(), 1u}, {pair.mutable_right(), 2u}}) {
    image->set_width(kWidth);
    image->set_height(kHeight);
    image->set_encoding(mav::v1::IMAGE_ENCODING_MONO8);
    image->set_data(MakeImage(seed));
  }
  std::string wire;
  ASSERT_TRUE(pair.SerializeToString(&wire));
  EXPECT_LT(wire.size(), 4u * 1024 * 1024);  // fits gRPC's default 4 MiB limit
  EXPECT_GT(wire.size(), 2u * kWidth * kHeight);

  mav::v1::StereoPair parsed;
  ASSERT_TRUE(parsed.ParseFromString(wire));
  EXPECT_EQ(parsed.t_ns(), pair.t_ns());
  EXPECT_EQ(parsed.left().data(), pair.left().data());
  EXPECT_EQ(parsed.right().data(), pair.right().data());
  EXPECT_EQ(parsed.right().encoding(), mav::v1::IMAGE_ENCODING_MONO8);
  EXPECT_NE(parsed.left().data(), parsed.right().data());
}

TEST(ProtosTest, TrackingStateNumbersMatchTheDdsEnum) {
  EXPECT_EQ(static_cast<int>(mav::v1::TRACKING_STATE_UNSPECIFIED),
            static_cast<int>(mav_dds_TRACKING_STATE_UNSPECIFIED));
  EXPECT_EQ(static_cast<int>(mav::v1::TRACKING_STATE_INITIALIZING),
            static_cast<int>(mav_dds_TRACKING_STATE_INITIALIZING));
  EXPECT_EQ(static_cast<int>(mav::v1::TRACKING_STATE_OK),
            static_cast<int>(mav_dds_TRACKING_STATE_OK));
  EXPECT_EQ(static_cast<int>(mav::v1::TRACKING_STATE_LOST),
            static_cast<int>(mav_dds_TRACKING_STATE_LOST));
  EXPECT_EQ(static_cast<int>(mav::v1::TRACKING_STATE_DEGRADED),
            static_cast<int>(mav_dds_TRACKING_STATE_DEGRADED));
}

// The RPCs of docs/contracts.md: service -> {rpc name -> streaming shape}.
enum Shape { kUnary, kServerStream, kClientStream };

const std::map<std::string, std::map<std::string, Shape>>& DocumentedRpcs() {
  static const auto* rpcs = new std::map<std::string, std::map<std::string, Shape>>{
      {"mav.v1.Simulator",
       {{"LoadScenario", kUnary},
        {"Start", kUnary},
        {"Pause", kUnary},
        {"Step", kUnary},
        {"GetStatus", kUnary},
        {"GetCalibration", kUnary},
        {"GetGroundTruthOccupancy", kServerStream},
        {"LoadFlightTask", kUnary},
        {"StartFlight", kUnary},
        {"PauseFlight", kUnary},
        {"GetFlightStatus", kUnary}}},
      {"mav.v1.Localization",
       {{"Configure", kUnary},
        {"Reset", kUnary},
        {"GetStatus", kUnary},
        {"GetTrajectory", kServerStream},
        {"ProcessStereoPair", kUnary}}},
      {"mav.v1.Mapping",
       {{"StartSession", kUnary},
        {"Reset", kUnary},
        {"InsertKeyframe", kUnary},
        {"BuildMap", kUnary},
        {"GetOccupancy", kServerStream},
        {"QueryCollision", kUnary},
        {"ExportMesh", kServerStream},
        {"GetStatus", kUnary}}},
      {"mav.v1.Planning",
       {{"LoadMap", kUnary},
        {"UploadMap", kClientStream},
        {"BuildRoadmap", kUnary},
        {"SaveRoadmap", kUnary},
        {"LoadRoadmap", kUnary},
        {"PlanPath", kUnary},
        {"GetPlan", kUnary},
        {"GetRoadmapStatus", kUnary},
        {"SampleTrajectory", kUnary}}},
      {"mav.v1.Control",
       {{"Configure", kUnary},
        {"Arm", kUnary},
        {"Disarm", kUnary},
        {"Hover", kUnary},
        {"SetTrajectory", kUnary},
        {"SetGains", kUnary},
        {"GetState", kUnary},
        {"GetStatus", kUnary}}},
  };
  return *rpcs;
}

TEST(ProtosTest, EveryServiceHasTheDocumentedRpcs) {
  // Touch each generated file so that its object (and its descriptors) is linked.
  ASSERT_NE(mav::v1::LoadScenarioRequest::descriptor(), nullptr);
  ASSERT_NE(mav::v1::LocalizationConfigureRequest::descriptor(), nullptr);
  ASSERT_NE(mav::v1::BuildMapRequest::descriptor(), nullptr);
  ASSERT_NE(mav::v1::PlanPathRequest::descriptor(), nullptr);
  ASSERT_NE(mav::v1::ControlConfigureRequest::descriptor(), nullptr);
  EXPECT_STREQ(mav::v1::Simulator::service_full_name(), "mav.v1.Simulator");
  EXPECT_STREQ(mav::v1::Localization::service_full_name(), "mav.v1.Localization");
  EXPECT_STREQ(mav::v1::Mapping::service_full_name(), "mav.v1.Mapping");
  EXPECT_STREQ(mav::v1::Planning::service_full_name(), "mav.v1.Planning");
  EXPECT_STREQ(mav::v1::Control::service_full_name(), "mav.v1.Control");

  const auto* pool = google::protobuf::DescriptorPool::generated_pool();
  for (const auto& [service_name, rpcs] : DocumentedRpcs()) {
    const auto* service = pool->FindServiceByName(service_name);
    ASSERT_NE(service, nullptr) << service_name;
    EXPECT_EQ(service->method_count(), static_cast<int>(rpcs.size())) << service_name;
    for (const auto& [name, shape] : rpcs) {
      const auto* method = service->FindMethodByName(name);
      ASSERT_NE(method, nullptr) << service_name << "." << name;
      EXPECT_EQ(method->server_streaming(), shape == kServerStream) << name;
      EXPECT_EQ(method->client_streaming(), shape == kClientStream) << name;
    }
  }
}

// Every enum of the contract starts with an UNSPECIFIED zero value, so that an unset field is
// never mistaken for a real choice.
TEST(ProtosTest, EveryEnumHasAnUnspecifiedZero) {
  const auto* pool = google::protobuf::DescriptorPool::generated_pool();
  int enums = 0;
  for (const char* file_name :
       {"mav/v1/common.proto", "mav/v1/simulator.proto", "mav/v1/localization.proto",
        "mav/v1/mapping.proto", "mav/v1/planning.proto", "mav/v1/control.proto"}) {
    const auto* file = pool->FindFileByName(file_name);
    ASSERT_NE(file, nullptr) << file_name;
    for (int i = 0; i < file->enum_type_count(); ++i, ++enums) {
      const auto* zero = file->enum_type(i)->FindValueByNumber(0);
      ASSERT_NE(zero, nullptr) << file->enum_type(i)->full_name();
      const std::string& name = zero->name();
      EXPECT_TRUE(name.ends_with("_UNSPECIFIED"))
          << file->enum_type(i)->full_name() << ": " << name;
    }
  }
  EXPECT_GE(enums, 15);
}

// In-process DDS round trip on loopback; a private domain id and topic name keep concurrent test
// runs on this host apart.
class DdsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    domain_id_ = 200 + static_cast<dds_domainid_t>(getpid() % 30);
    const char* config =
        "<CycloneDDS><Domain><General><Interfaces><NetworkInterface name=\"lo\"/></Interfaces>"
        "<AllowMulticast>false</AllowMulticast></General>"
        "<Discovery><ParticipantIndex>none</ParticipantIndex></Discovery>"
        "</Domain></CycloneDDS>";
    domain_ = dds_create_domain(domain_id_, config);
    ASSERT_GT(domain_, 0) << dds_strretcode(domain_);
    participant_ = dds_create_participant(domain_id_, nullptr, nullptr);
    ASSERT_GT(participant_, 0) << dds_strretcode(participant_);
  }
  void TearDown() override {
    if (participant_ > 0) dds_delete(participant_);
    if (domain_ > 0) dds_delete(domain_);
  }

  dds_domainid_t domain_id_ = 0;
  dds_entity_t domain_ = 0;
  dds_entity_t participant_ = 0;
};

TEST_F(DdsTest, StereoFramesArriveIntactAndRigIdSeparatesInstances) {
  const std::string topic_name = "mav/test/stereo_" + std::to_string(getpid());
  const dds_entity_t topic = dds_create_topic(participant_, &mav_dds_StereoFrame_desc,
                                              topic_name.c_str(), nullptr, nullptr);
  ASSERT_GT(topic, 0) << dds_strretcode(topic);

  // The stereo QoS of docs/contracts.md: reliable, volatile, keep-last per instance.
  dds_qos_t* qos = dds_create_qos();
  dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_durability(qos, DDS_DURABILITY_VOLATILE);
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 1);
  const dds_entity_t reader = dds_create_reader(participant_, topic, qos, nullptr);
  const dds_entity_t writer = dds_create_writer(participant_, topic, qos, nullptr);
  dds_delete_qos(qos);
  ASSERT_GT(reader, 0) << dds_strretcode(reader);
  ASSERT_GT(writer, 0) << dds_strretcode(writer);

  // Rig 0 writes frames 0 and 1 (keep-last 1 keeps only frame 1), rig 1 writes frame 0.
  std::map<uint32_t, uint32_t> crc_sent;  // rig -> crc of its last frame
  for (auto [rig, seq] : {std::pair{0u, 0ull}, {0u, 1ull}, {1u, 0ull}}) {
    const std::string left = MakeImage(rig * 10 + static_cast<uint32_t>(seq));
    const std::string right = MakeImage(rig * 10 + static_cast<uint32_t>(seq) + 100);
    mav_dds_StereoFrame frame{};
    frame.rig_id = rig;
    frame.sequence_number = seq;
    frame.t_ns = 1000 + static_cast<int64_t>(seq) * 50'000'000;
    std::snprintf(frame.left_camera_id, sizeof(frame.left_camera_id), "cam0");
    std::snprintf(frame.right_camera_id, sizeof(frame.right_camera_id), "cam1");
    frame.width = kWidth;
    frame.height = kHeight;
    frame.encoding = mav_dds_PIXEL_FORMAT_MONO8;
    // Borrow the buffers (_release = false): dds_write serialises and does not free them.
    frame.left = {kWidth * kHeight, kWidth * kHeight,
                  reinterpret_cast<uint8_t*>(const_cast<char*>(left.data())), false};
    frame.right = {kWidth * kHeight, kWidth * kHeight,
                   reinterpret_cast<uint8_t*>(const_cast<char*>(right.data())), false};
    frame.crc32 =
        Crc32(frame.left._buffer, frame.left._length, frame.right._buffer, frame.right._length);
    crc_sent[rig] = frame.crc32;
    ASSERT_EQ(dds_write(writer, &frame), DDS_RETCODE_OK);
  }

  void* samples[4] = {};
  dds_sample_info_t infos[4];
  std::map<uint32_t, uint64_t> received;  // rig -> sequence number
  for (int attempt = 0; attempt < 200 && received.size() < 2; ++attempt) {
    const int n = dds_take(reader, samples, infos, 4, 4);
    ASSERT_GE(n, 0) << dds_strretcode(n);
    for (int i = 0; i < n; ++i) {
      if (!infos[i].valid_data) continue;
      const auto* frame = static_cast<const mav_dds_StereoFrame*>(samples[i]);
      ASSERT_EQ(frame->left._length, kWidth * kHeight);
      ASSERT_EQ(frame->right._length, kWidth * kHeight);
      EXPECT_EQ(Crc32(frame->left._buffer, frame->left._length, frame->right._buffer,
                      frame->right._length),
                frame->crc32);
      EXPECT_EQ(frame->crc32, crc_sent[frame->rig_id]);
      EXPECT_STREQ(frame->left_camera_id, "cam0");
      received[frame->rig_id] = frame->sequence_number;
    }
    if (n > 0) dds_return_loan(reader, samples, n);
    if (received.size() < 2) dds_sleepfor(DDS_MSECS(10));
  }
  ASSERT_EQ(received.size(), 2u);
  EXPECT_EQ(received[0], 1u);  // keep-last 1 per instance: rig 0's newest frame
  EXPECT_EQ(received[1], 0u);  // and rig 1's own frame was not evicted by rig 0's
}

TEST(DdsTypesTest, AllocatedSamplesFreeTheirBuffers) {
  // An owned sample (the reader's representation): dds_sample_free releases the sequences.
  auto* command = static_cast<mav_dds_ActuatorCommand*>(dds_alloc(sizeof(mav_dds_ActuatorCommand)));
  command->rotor_speeds._buffer = static_cast<double*>(dds_alloc(6 * sizeof(double)));
  command->rotor_speeds._maximum = 6;
  command->rotor_speeds._length = 6;
  command->rotor_speeds._release = true;
  for (uint32_t i = 0; i < 6; ++i) command->rotor_speeds._buffer[i] = 400.0 + i;
  EXPECT_EQ(mav_dds_ActuatorCommand_desc.m_size, sizeof(mav_dds_ActuatorCommand));
  dds_sample_free(command, &mav_dds_ActuatorCommand_desc, DDS_FREE_ALL);

  mav_dds_PoseWithCovariance pose{};
  EXPECT_EQ(sizeof(pose.covariance) / sizeof(pose.covariance[0]), 36u);
  EXPECT_EQ(mav_dds_PoseWithCovariance_desc.m_size, sizeof(mav_dds_PoseWithCovariance));
  EXPECT_EQ(mav_dds_GroundTruthState_desc.m_size, sizeof(mav_dds_GroundTruthState));
  EXPECT_EQ(mav_dds_ImuSample_desc.m_size, sizeof(mav_dds_ImuSample));
}

}  // namespace
