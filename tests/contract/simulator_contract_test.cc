// Contract of mav.v1.Simulator (protos/mav/v1/simulator.proto, docs/contracts.md): every RPC
// with good and bad input through an in-process channel, and a real loopback port with the
// grpc.health.v1 check and deadlines. The DDS side is replaced by a recording sink so that the
// order of what is published (IMU/ground truth interleaved before each frame) can be asserted.

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>
#include <opencv2/core/mat.hpp>

#include "mav/dataset/euroc.h"
#include "mav/dataset/occupancy_io.h"
#include "mav/sim/scenario.h"
#include "mav/transport/grpc_server.h"
#include "mav/v1/simulator.grpc.pb.h"
#include "services/simulator/dds_io.h"
#include "services/simulator/simulator_service.h"
#include "tests/common/contract_server.h"

namespace mav::simulator_service {
namespace {

using grpc::StatusCode;

using ::mav::test_support::StartOnFreePort;  // tests/common/contract_server.h

// Records everything the player publishes, in order.
class RecordingSink : public StreamSink {
 public:
  struct Event {
    char kind;  // 's' stereo, 'i' imu, 'g' ground truth
    uint64_t sequence;
    int64_t t_ns;
    uint32_t crc = 0;
  };

  Status PublishStereo(uint64_t sequence, const RenderedFrame& frame, bool rectified) override {
    mav_dds_StereoFrame sample;
    FillStereoFrame(sequence, frame, rectified, 0, &sample);
    std::lock_guard<std::mutex> lock(mutex_);
    events_.push_back({'s', sequence, frame.t_ns, sample.crc32});
    return Status::Ok();
  }
  Status PublishImu(uint64_t sequence, const dataset::ImuSample& sample) override {
    std::lock_guard<std::mutex> lock(mutex_);
    events_.push_back({'i', sequence, sample.t_ns});
    return Status::Ok();
  }
  Status PublishGroundTruth(uint64_t sequence, const dataset::GroundTruthState& state) override {
    std::lock_guard<std::mutex> lock(mutex_);
    events_.push_back({'g', sequence, state.t_ns});
    return Status::Ok();
  }
  Status WaitForStereoAcks(int64_t) override { return Status::Ok(); }
  uint32_t StereoSubscribers() override { return 0; }
  uint32_t ImuSubscribers() override { return 0; }
  uint32_t domain() const override { return 0; }

  std::vector<Event> events() {
    std::lock_guard<std::mutex> lock(mutex_);
    return events_;
  }
  std::vector<Event> events(char kind) {
    std::vector<Event> out;
    for (const Event& e : events()) {
      if (e.kind == kind) out.push_back(e);
    }
    return out;
  }

 private:
  std::mutex mutex_;
  std::vector<Event> events_;
};

class SimulatorContractTest : public ::testing::Test {
 protected:
  void SetUp() override {
    service_ = std::make_unique<SimulatorService>(&sink_);
    server_ = StartOnFreePort<v1::Simulator>(service_.get());
    ASSERT_NE(server_, nullptr);
    stub_ = v1::Simulator::NewStub(server_->InProcessChannel());
  }
  void TearDown() override {
    if (server_ != nullptr) server_->Shutdown();
  }

  static void SetDeadline(grpc::ClientContext* context, double seconds = 20.0) {
    context->set_deadline(std::chrono::system_clock::now() +
                          std::chrono::milliseconds(static_cast<int64_t>(seconds * 1000)));
  }

  grpc::Status LoadPreset(const std::string& name, int64_t frames,
                          v1::LoadScenarioResponse* response = nullptr) {
    v1::LoadScenarioRequest request;
    request.mutable_preset()->set_name(name);
    request.mutable_preset()->set_frames(frames);
    request.mutable_preset()->set_seed(7);
    v1::LoadScenarioResponse local;
    grpc::ClientContext context;
    SetDeadline(&context);
    return stub_->LoadScenario(&context, request, response != nullptr ? response : &local);
  }
  grpc::Status LoadEuroc(const std::string& directory, v1::LoadScenarioResponse* response) {
    v1::LoadScenarioRequest request;
    request.mutable_euroc()->set_directory(directory);
    grpc::ClientContext context;
    SetDeadline(&context);
    return stub_->LoadScenario(&context, request, response);
  }
  grpc::Status StartRate(double factor, v1::SimulatorStatus* status) {
    v1::SimulatorStartRequest request;
    request.set_real_time_factor(factor);
    grpc::ClientContext context;
    SetDeadline(&context);
    return stub_->Start(&context, request, status);
  }
  grpc::Status StartFast(v1::SimulatorStatus* status) {
    v1::SimulatorStartRequest request;
    request.set_as_fast_as_subscribers(true);
    grpc::ClientContext context;
    SetDeadline(&context);
    return stub_->Start(&context, request, status);
  }
  grpc::Status Step(uint32_t frames, v1::SimulatorStatus* status) {
    v1::SimulatorStepRequest request;
    request.set_frames(frames);
    grpc::ClientContext context;
    SetDeadline(&context, 60.0);
    return stub_->Step(&context, request, status);
  }
  grpc::Status Pause(v1::SimulatorStatus* status) {
    grpc::ClientContext context;
    SetDeadline(&context);
    return stub_->Pause(&context, v1::SimulatorPauseRequest(), status);
  }
  v1::SimulatorStatus GetStatus() {
    v1::SimulatorStatus status;
    grpc::ClientContext context;
    SetDeadline(&context);
    EXPECT_TRUE(stub_->GetStatus(&context, v1::SimulatorGetStatusRequest(), &status).ok());
    return status;
  }
  // Polls GetStatus until `state` or the timeout.
  v1::SimulatorStatus WaitForState(v1::SimulatorState state, double timeout_s = 45.0) {
    const auto deadline = std::chrono::steady_clock::now() +
                          std::chrono::milliseconds(static_cast<int64_t>(timeout_s * 1000));
    v1::SimulatorStatus status = GetStatus();
    while (status.state() != state && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      status = GetStatus();
    }
    return status;
  }

  RecordingSink sink_;
  std::unique_ptr<SimulatorService> service_;
  std::unique_ptr<transport::GrpcServer> server_;
  std::unique_ptr<v1::Simulator::Stub> stub_;
};

// Each IMU/ground-truth sample precedes the first frame at or after its time, and every frame is
// preceded by all samples up to its time: one merged, time-ordered stream.
void ExpectTimeOrdered(const std::vector<RecordingSink::Event>& events) {
  int64_t last_t = std::numeric_limits<int64_t>::min();
  uint64_t next_stereo = 0;
  for (const RecordingSink::Event& e : events) {
    EXPECT_GE(e.t_ns, last_t) << "event " << e.kind << " " << e.sequence << " out of time order";
    last_t = e.t_ns;
    if (e.kind == 's') {
      EXPECT_EQ(e.sequence, next_stereo);
      ++next_stereo;
    }
  }
}

// ---- GetStatus --------------------------------------------------------------------------------

TEST_F(SimulatorContractTest, GetStatusIsIdleBeforeAnythingIsLoaded) {
  const v1::SimulatorStatus status = GetStatus();
  EXPECT_EQ(status.state(), v1::SIMULATOR_STATE_IDLE);
  EXPECT_FALSE(status.has_scenario());
  EXPECT_EQ(status.frames_published(), 0u);
}

// ---- LoadScenario -----------------------------------------------------------------------------

TEST_F(SimulatorContractTest, LoadScenarioFromAPresetDescribesIt) {
  v1::LoadScenarioResponse response;
  const grpc::Status status = LoadPreset("room-easy", 6, &response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  const v1::ScenarioSummary& s = response.scenario();
  EXPECT_EQ(s.name(), "room-easy");
  EXPECT_TRUE(s.is_preset());
  EXPECT_EQ(s.frames(), 6);
  EXPECT_EQ(s.seed(), 7u);
  EXPECT_EQ(s.image_width(), 752u);
  EXPECT_EQ(s.image_height(), 480u);
  EXPECT_DOUBLE_EQ(s.camera_rate_hz(), 20.0);
  EXPECT_DOUBLE_EQ(s.imu_rate_hz(), 200.0);
  EXPECT_EQ(s.end_t_ns() - s.start_t_ns(), 5 * 50'000'000);
  EXPECT_GE(s.imu_samples(), 50);  // 0.25 s at 200 Hz
  EXPECT_TRUE(s.has_ground_truth());
  EXPECT_EQ(GetStatus().state(), v1::SIMULATOR_STATE_LOADED);
}

TEST_F(SimulatorContractTest, LoadScenarioRejectsAnUnknownPresetNamingTheField) {
  const grpc::Status status = LoadPreset("room-eazy", 10);
  EXPECT_EQ(status.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(status.error_message().rfind("preset.name: unknown preset 'room-eazy'", 0), 0u)
      << status.error_message();
  EXPECT_NE(status.error_message().find("room-easy"), std::string::npos)
      << "the message should list the known presets: " << status.error_message();
  EXPECT_EQ(GetStatus().state(), v1::SIMULATOR_STATE_IDLE);
}

TEST_F(SimulatorContractTest, LoadScenarioRejectsNegativeFrames) {
  const grpc::Status status = LoadPreset("room-easy", -3);
  EXPECT_EQ(status.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(status.error_message().rfind("preset.frames:", 0), 0u) << status.error_message();
}

TEST_F(SimulatorContractTest, LoadScenarioWithoutASourceIsInvalid) {
  v1::LoadScenarioResponse response;
  grpc::ClientContext context;
  SetDeadline(&context);
  const grpc::Status status = stub_->LoadScenario(&context, v1::LoadScenarioRequest(), &response);
  EXPECT_EQ(status.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(status.error_message().rfind("source:", 0), 0u) << status.error_message();
}

TEST_F(SimulatorContractTest, LoadScenarioFromAMissingDirectoryIsNotFoundNamingThePath) {
  const std::string missing = "/nonexistent/mav-test/euroc-" + std::to_string(::getpid());
  v1::LoadScenarioResponse response;
  const grpc::Status status = LoadEuroc(missing, &response);
  EXPECT_EQ(status.error_code(), StatusCode::NOT_FOUND);
  EXPECT_NE(status.error_message().find(missing), std::string::npos) << status.error_message();
}

TEST_F(SimulatorContractTest, LoadScenarioWithAnEmptyDirectoryIsInvalid) {
  v1::LoadScenarioResponse response;
  const grpc::Status status = LoadEuroc("", &response);
  EXPECT_EQ(status.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(status.error_message().rfind("euroc.directory:", 0), 0u) << status.error_message();
}

TEST_F(SimulatorContractTest, LoadScenarioFromADirectoryWithoutMav0IsNotFound) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("mav-contract-empty-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  v1::LoadScenarioResponse response;
  const grpc::Status status = LoadEuroc(dir.string(), &response);
  std::filesystem::remove_all(dir);
  EXPECT_EQ(status.error_code(), StatusCode::NOT_FOUND) << status.error_message();
}

// ---- Start / Pause / Step: preconditions --------------------------------------------------------

TEST_F(SimulatorContractTest, StartStepPauseAndCalibrationNeedALoadedScenario) {
  v1::SimulatorStatus status;
  grpc::Status rpc = StartRate(1.0, &status);
  EXPECT_EQ(rpc.error_code(), StatusCode::FAILED_PRECONDITION) << rpc.error_message();
  rpc = StartFast(&status);
  EXPECT_EQ(rpc.error_code(), StatusCode::FAILED_PRECONDITION) << rpc.error_message();
  rpc = Step(1, &status);
  EXPECT_EQ(rpc.error_code(), StatusCode::FAILED_PRECONDITION) << rpc.error_message();
  rpc = Pause(&status);
  EXPECT_EQ(rpc.error_code(), StatusCode::FAILED_PRECONDITION) << rpc.error_message();

  grpc::ClientContext context;
  SetDeadline(&context);
  v1::GetCalibrationResponse calibration;
  rpc = stub_->GetCalibration(&context, v1::GetCalibrationRequest(), &calibration);
  EXPECT_EQ(rpc.error_code(), StatusCode::FAILED_PRECONDITION) << rpc.error_message();

  grpc::ClientContext occupancy_context;
  SetDeadline(&occupancy_context);
  auto reader =
      stub_->GetGroundTruthOccupancy(&occupancy_context, v1::GetGroundTruthOccupancyRequest());
  v1::OccupancyChunk chunk;
  EXPECT_FALSE(reader->Read(&chunk));
  EXPECT_EQ(reader->Finish().error_code(), StatusCode::FAILED_PRECONDITION);
}

TEST_F(SimulatorContractTest, StartRejectsBadPacingNamingTheField) {
  ASSERT_TRUE(LoadPreset("room-easy", 4).ok());
  // 1e-15 once overflowed the pacing arithmetic and published at full speed; 1e4 is no pacing.
  for (double factor : {-1.0, 0.0, 1e-15, 1e4, std::numeric_limits<double>::quiet_NaN(),
                        std::numeric_limits<double>::infinity()}) {
    v1::SimulatorStatus status;
    const grpc::Status rpc = StartRate(factor, &status);
    EXPECT_EQ(rpc.error_code(), StatusCode::INVALID_ARGUMENT) << "factor " << factor;
    EXPECT_EQ(rpc.error_message().rfind("real_time_factor:", 0), 0u) << rpc.error_message();
  }
  // No pacing at all.
  v1::SimulatorStatus status;
  grpc::ClientContext context;
  SetDeadline(&context);
  grpc::Status rpc = stub_->Start(&context, v1::SimulatorStartRequest(), &status);
  EXPECT_EQ(rpc.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(rpc.error_message().rfind("real_time_factor:", 0), 0u) << rpc.error_message();
  // A negative wait timeout.
  v1::SimulatorStartRequest request;
  request.set_real_time_factor(1.0);
  request.set_wait_timeout_s(-2.0);
  grpc::ClientContext context2;
  SetDeadline(&context2);
  rpc = stub_->Start(&context2, request, &status);
  EXPECT_EQ(rpc.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(rpc.error_message().rfind("wait_timeout_s:", 0), 0u) << rpc.error_message();
  EXPECT_EQ(GetStatus().state(), v1::SIMULATOR_STATE_LOADED);
}

TEST_F(SimulatorContractTest, StepValidatesTheFrameCount) {
  ASSERT_TRUE(LoadPreset("room-easy", 4).ok());
  v1::SimulatorStatus status;
  grpc::Status rpc = Step(0, &status);
  EXPECT_EQ(rpc.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(rpc.error_message().rfind("frames:", 0), 0u) << rpc.error_message();
  rpc = Step(5, &status);
  EXPECT_EQ(rpc.error_code(), StatusCode::OUT_OF_RANGE) << rpc.error_message();
  EXPECT_TRUE(sink_.events('s').empty()) << "nothing may be published on OUT_OF_RANGE";
}

// ---- Step: what is published ------------------------------------------------------------------

TEST_F(SimulatorContractTest, StepPublishesFramesWithImuAndGroundTruthInTimeOrder) {
  v1::LoadScenarioResponse loaded;
  ASSERT_TRUE(LoadPreset("room-easy", 5, &loaded).ok());
  v1::SimulatorStatus status;
  const grpc::Status rpc = Step(3, &status);
  ASSERT_TRUE(rpc.ok()) << rpc.error_message();
  EXPECT_EQ(status.state(), v1::SIMULATOR_STATE_PAUSED);
  EXPECT_EQ(status.next_frame(), 3);
  EXPECT_EQ(status.frames_published(), 3u);
  EXPECT_EQ(status.current_t_ns(), loaded.scenario().start_t_ns() + 2 * 50'000'000);

  const auto stereo = sink_.events('s');
  ASSERT_EQ(stereo.size(), 3u);
  const auto imu = sink_.events('i');
  // IMU samples up to the third frame's time: 0.1 s at 200 Hz, both ends included.
  EXPECT_EQ(imu.size(), 21u);
  EXPECT_EQ(status.imu_samples_published(), imu.size());
  EXPECT_EQ(sink_.events('g').size(), status.ground_truth_published());
  for (size_t i = 0; i < imu.size(); ++i) EXPECT_EQ(imu[i].sequence, i);
  ExpectTimeOrdered(sink_.events());

  // The rest, then the end is out of range.
  ASSERT_TRUE(Step(2, &status).ok());
  EXPECT_EQ(status.frames_published(), 5u);
  EXPECT_EQ(Step(1, &status).error_code(), StatusCode::OUT_OF_RANGE);
  ExpectTimeOrdered(sink_.events());
}

TEST_F(SimulatorContractTest, StartFastPublishesEveryFrameThenFinishes) {
  ASSERT_TRUE(LoadPreset("room-easy", 8).ok());
  v1::SimulatorStatus status;
  const grpc::Status rpc = StartFast(&status);
  ASSERT_TRUE(rpc.ok()) << rpc.error_message();
  EXPECT_EQ(status.state(), v1::SIMULATOR_STATE_RUNNING);
  EXPECT_TRUE(status.as_fast_as_subscribers());
  // A second Start while running is a precondition failure.
  v1::SimulatorStatus again;
  const grpc::Status second = StartFast(&again);
  if (GetStatus().state() == v1::SIMULATOR_STATE_RUNNING) {
    EXPECT_EQ(second.error_code(), StatusCode::FAILED_PRECONDITION);
  }
  status = WaitForState(v1::SIMULATOR_STATE_FINISHED);
  ASSERT_EQ(status.state(), v1::SIMULATOR_STATE_FINISHED);
  EXPECT_EQ(status.frames_published(), 8u);
  EXPECT_EQ(status.render_ms().count(), 8u);
  EXPECT_GT(status.render_ms().mean_ms(), 0.0);
  EXPECT_EQ(sink_.events('s').size(), 8u);
  ExpectTimeOrdered(sink_.events());
  // Rendering is deterministic: the same frames again from the start give the same checksums.
  const auto first = sink_.events('s');
  ASSERT_TRUE(Step(8, &status).ok());
  const auto all = sink_.events('s');
  ASSERT_EQ(all.size(), 16u);
  for (size_t i = 0; i < 8; ++i) {
    EXPECT_EQ(all[8 + i].crc, first[i].crc) << "frame " << i;
    EXPECT_EQ(all[8 + i].sequence, 8 + i) << "sequence numbers keep counting";
  }
}

TEST_F(SimulatorContractTest, StartInRealTimeThenPause) {
  ASSERT_TRUE(LoadPreset("room-easy", 200).ok());
  v1::SimulatorStatus status;
  ASSERT_TRUE(StartRate(1.0, &status).ok());
  EXPECT_EQ(status.state(), v1::SIMULATOR_STATE_RUNNING);
  EXPECT_DOUBLE_EQ(status.real_time_factor(), 1.0);
  std::this_thread::sleep_for(std::chrono::milliseconds(700));
  const grpc::Status rpc = Pause(&status);
  ASSERT_TRUE(rpc.ok()) << rpc.error_message();
  EXPECT_EQ(status.state(), v1::SIMULATOR_STATE_PAUSED);
  const uint64_t published = status.frames_published();
  EXPECT_GE(published, 1u);
  // At 20 Hz, 0.7 s is at most ~15 frames (rendering may make it fewer, never more).
  EXPECT_LE(published, 16u);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  EXPECT_EQ(GetStatus().frames_published(), published) << "nothing is published while paused";
  EXPECT_EQ(Pause(&status).error_code(), StatusCode::FAILED_PRECONDITION);
  // Resume, then a new Load stops the playback and resets the counters.
  ASSERT_TRUE(StartRate(4.0, &status).ok());
  ASSERT_TRUE(LoadPreset("room-easy", 3).ok());
  status = GetStatus();
  EXPECT_EQ(status.state(), v1::SIMULATOR_STATE_LOADED);
  EXPECT_EQ(status.frames_published(), 0u);
  ExpectTimeOrdered(sink_.events());
}

// ---- GetCalibration / GetGroundTruthOccupancy ---------------------------------------------------

TEST_F(SimulatorContractTest, GetCalibrationDescribesTheRig) {
  ASSERT_TRUE(LoadPreset("room-easy", 2).ok());
  grpc::ClientContext context;
  SetDeadline(&context);
  v1::GetCalibrationResponse response;
  ASSERT_TRUE(stub_->GetCalibration(&context, v1::GetCalibrationRequest(), &response).ok());
  EXPECT_EQ(response.stereo().left().camera_id(), "cam0");
  EXPECT_EQ(response.stereo().right().camera_id(), "cam1");
  EXPECT_EQ(response.stereo().left().intrinsics().width(), 752u);
  EXPECT_GT(response.stereo().left().intrinsics().fx(), 100.0);
  EXPECT_NEAR(response.stereo().baseline_m(), 0.11, 0.01);
  EXPECT_DOUBLE_EQ(response.imu().rate_hz(), 200.0);
  EXPECT_NEAR(response.imu().gyroscope_noise_density(), 1.6968e-4, 1e-9);
  EXPECT_DOUBLE_EQ(response.t_body_imu().orientation().w(), 1.0);
}

TEST_F(SimulatorContractTest, GetGroundTruthOccupancyValidatesAndStreamsChunks) {
  ASSERT_TRUE(LoadPreset("room-easy", 2).ok());
  auto call = [&](double resolution, uint32_t chunk_size, std::string* bytes,
                  std::vector<v1::OccupancyChunk>* chunks) {
    v1::GetGroundTruthOccupancyRequest request;
    request.set_resolution_m(resolution);
    request.set_chunk_size(chunk_size);
    request.set_format(v1::OCCUPANCY_FORMAT_OCTOMAP_BT);
    grpc::ClientContext context;
    SetDeadline(&context, 60.0);
    auto reader = stub_->GetGroundTruthOccupancy(&context, request);
    v1::OccupancyChunk chunk;
    while (reader->Read(&chunk)) {
      if (bytes != nullptr) *bytes += chunk.chunk().data();
      if (chunks != nullptr) chunks->push_back(chunk);
    }
    return reader->Finish();
  };
  grpc::Status rpc = call(0.001, 0, nullptr, nullptr);
  EXPECT_EQ(rpc.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(rpc.error_message().rfind("resolution_m:", 0), 0u) << rpc.error_message();
  rpc = call(0.2, 100, nullptr, nullptr);
  EXPECT_EQ(rpc.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(rpc.error_message().rfind("chunk_size:", 0), 0u) << rpc.error_message();

  std::string bytes;
  std::vector<v1::OccupancyChunk> chunks;
  rpc = call(0.2, 4096, &bytes, &chunks);
  ASSERT_TRUE(rpc.ok()) << rpc.error_message();
  ASSERT_FALSE(chunks.empty());
  EXPECT_EQ(chunks.front().format(), v1::OCCUPANCY_FORMAT_OCTOMAP_BT);
  EXPECT_DOUBLE_EQ(chunks.front().resolution_m(), 0.2);
  EXPECT_TRUE(chunks.back().chunk().last());
  EXPECT_EQ(bytes.size(), chunks.front().chunk().total_size());
  uint64_t offset = 0;
  for (const v1::OccupancyChunk& chunk : chunks) {
    EXPECT_EQ(chunk.chunk().offset(), offset);
    EXPECT_LE(chunk.chunk().data().size(), 4096u);
    offset += chunk.chunk().data().size();
  }
  // An OctoMap binary file starts with its header comment.
  EXPECT_EQ(bytes.rfind("# Octomap OcTree binary file", 0), 0u);
}

// 1 cm of a room as OctoMap once took 11 GB and ran on after the client's deadline: the
// answer's memory is estimated first and refused before anything is computed.
TEST_F(SimulatorContractTest, GetGroundTruthOccupancyRefusesWhatWouldExhaustMemory) {
  ASSERT_TRUE(LoadPreset("room-easy", 2).ok());
  v1::GetGroundTruthOccupancyRequest request;
  request.set_resolution_m(0.01);
  request.set_format(v1::OCCUPANCY_FORMAT_OCTOMAP_BT);
  grpc::ClientContext context;
  // Refused before any computation: a computed answer would run into this deadline instead.
  SetDeadline(&context, 10.0);
  auto reader = stub_->GetGroundTruthOccupancy(&context, request);
  v1::OccupancyChunk chunk;
  while (reader->Read(&chunk)) {
  }
  const grpc::Status rpc = reader->Finish();
  EXPECT_EQ(rpc.error_code(), StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_EQ(rpc.error_message().rfind("resolution_m: 0.01", 0), 0u) << rpc.error_message();
  EXPECT_NE(rpc.error_message().find("MiB"), std::string::npos) << rpc.error_message();
}

// A computation the client gave up on stops: the deadline reaches the occupancy computation.
TEST_F(SimulatorContractTest, GetGroundTruthOccupancyStopsAtTheDeadline) {
  ASSERT_TRUE(LoadPreset("room-hard", 2).ok());
  v1::GetGroundTruthOccupancyRequest request;
  request.set_resolution_m(0.01);  // ~190 M voxels as .mavocc: within the memory limit, slow
  request.set_format(v1::OCCUPANCY_FORMAT_MAVOCC);
  grpc::ClientContext context;
  SetDeadline(&context, 0.3);
  auto reader = stub_->GetGroundTruthOccupancy(&context, request);
  v1::OccupancyChunk chunk;
  while (reader->Read(&chunk)) {
  }
  EXPECT_EQ(reader->Finish().error_code(), StatusCode::DEADLINE_EXCEEDED);
  // The server is free again soon after (the computation stopped): a small request answers.
  request.set_resolution_m(0.2);
  grpc::ClientContext small;
  SetDeadline(&small, 10.0);
  auto second = stub_->GetGroundTruthOccupancy(&small, request);
  std::string bytes;
  while (second->Read(&chunk)) bytes += chunk.chunk().data();
  EXPECT_TRUE(second->Finish().ok());
  EXPECT_FALSE(bytes.empty());
}

// ---- A recorded EuRoC directory replays through the same path -----------------------------------

TEST_F(SimulatorContractTest, AnEurocDirectoryReplaysTheSameFramesAsThePreset) {
  // Record 4 frames of room-easy (seed 7) as EuRoC ASL, then replay both and compare checksums.
  sim::ScenarioOptions options;
  options.preset = "room-easy";
  options.frames = 4;
  options.seed = 7;
  auto scenario = sim::Scenario::Create(options);
  ASSERT_TRUE(scenario.ok()) << scenario.status().ToString();
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("mav-contract-euroc-" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  {
    auto writer =
        dataset::EurocWriter::Create(dir.string(), scenario->calibration(), scenario->imu_noise());
    ASSERT_TRUE(writer.ok()) << writer.status().ToString();
    for (int64_t k = 0; k < scenario->num_frames(); ++k) {
      cv::Mat left, right;
      scenario->RenderStereo(k, &left, &right);
      ASSERT_TRUE((*writer)->WriteStereo(scenario->FrameTimeNs(k), left, right).ok());
    }
    ASSERT_TRUE((*writer)->WriteImu(scenario->ImuSamples()).ok());
    ASSERT_TRUE((*writer)->WriteGroundTruth(scenario->GroundTruth()).ok());
    ASSERT_TRUE((*writer)->Close().ok());
  }
  // As mav-sim generate writes it: the exact occupancy beside mav0/.
  const dataset::OccupancyGrid occupancy = scenario->ComputeOccupancy(0.1);
  std::filesystem::create_directories(dir / "ground_truth");
  ASSERT_TRUE(
      dataset::WriteMavocc(occupancy, (dir / "ground_truth" / "occupancy.mavocc").string()).ok());

  v1::LoadScenarioResponse response;
  grpc::Status rpc = LoadEuroc(dir.string(), &response);
  ASSERT_TRUE(rpc.ok()) << rpc.error_message();
  EXPECT_FALSE(response.scenario().is_preset());
  EXPECT_EQ(response.scenario().frames(), 4);
  EXPECT_TRUE(response.scenario().has_ground_truth());
  EXPECT_TRUE(response.scenario().has_ground_truth_occupancy());
  v1::SimulatorStatus status;
  ASSERT_TRUE(Step(4, &status).ok());
  const auto from_euroc = sink_.events('s');
  const size_t imu_from_euroc = sink_.events('i').size();

  ASSERT_TRUE(LoadPreset("room-easy", 4).ok());
  ASSERT_TRUE(Step(4, &status).ok());
  const auto all = sink_.events('s');
  ASSERT_EQ(all.size(), 8u);
  for (size_t k = 0; k < 4; ++k) {
    EXPECT_EQ(from_euroc[k].t_ns, all[4 + k].t_ns) << "frame " << k;
    EXPECT_EQ(from_euroc[k].crc, all[4 + k].crc) << "frame " << k << ": images differ";
  }
  EXPECT_EQ(sink_.events('i').size(), 2 * imu_from_euroc);

  // The recorded occupancy is served as it is (resolution 0 = the file's); another resolution is
  // refused naming the field.
  ASSERT_TRUE(LoadEuroc(dir.string(), &response).ok());
  auto occupancy_of = [&](double resolution, std::string* bytes) {
    v1::GetGroundTruthOccupancyRequest request;
    request.set_resolution_m(resolution);
    request.set_format(v1::OCCUPANCY_FORMAT_MAVOCC);
    grpc::ClientContext context;
    SetDeadline(&context);
    auto reader = stub_->GetGroundTruthOccupancy(&context, request);
    v1::OccupancyChunk chunk;
    while (reader->Read(&chunk)) bytes->append(chunk.chunk().data());
    return reader->Finish();
  };
  std::string bytes;
  ASSERT_TRUE(occupancy_of(0.0, &bytes).ok());
  Result<dataset::OccupancyGrid> served = dataset::DecodeMavocc(bytes, "served");
  ASSERT_TRUE(served.ok()) << served.status().ToString();
  EXPECT_EQ(served->states(), occupancy.states());
  bytes.clear();
  const grpc::Status other = occupancy_of(0.05, &bytes);
  EXPECT_EQ(other.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(other.error_message().rfind("resolution_m:", 0), 0u) << other.error_message();
  // Without the file: NOT_FOUND.
  std::filesystem::remove_all(dir / "ground_truth");
  ASSERT_TRUE(LoadEuroc(dir.string(), &response).ok());
  EXPECT_FALSE(response.scenario().has_ground_truth_occupancy());
  EXPECT_EQ(occupancy_of(0.0, &bytes).error_code(), StatusCode::NOT_FOUND);
  std::filesystem::remove_all(dir);
}

// ---- A real loopback port: health, deadlines ----------------------------------------------------

TEST_F(SimulatorContractTest, LoopbackPortAnswersHealthChecksAndRpcs) {
  ASSERT_GT(server_->port(), 0);
  auto channel = grpc::CreateChannel(server_->target(), grpc::InsecureChannelCredentials());
  auto overall = transport::CheckHealth(channel, "", std::chrono::seconds(5));
  ASSERT_TRUE(overall.ok()) << overall.status().ToString();
  EXPECT_EQ(*overall, transport::HealthStatus::kServing);
  auto simulator = transport::CheckHealth(channel, "mav.v1.Simulator", std::chrono::seconds(5));
  ASSERT_TRUE(simulator.ok()) << simulator.status().ToString();
  EXPECT_EQ(*simulator, transport::HealthStatus::kServing);
  auto unknown = transport::CheckHealth(channel, "mav.v1.Nope", std::chrono::seconds(5));
  ASSERT_TRUE(unknown.ok()) << unknown.status().ToString();
  EXPECT_EQ(*unknown, transport::HealthStatus::kServiceUnknown);

  auto stub = v1::Simulator::NewStub(channel);
  grpc::ClientContext context;
  SetDeadline(&context, 5.0);
  v1::SimulatorStatus status;
  ASSERT_TRUE(stub->GetStatus(&context, v1::SimulatorGetStatusRequest(), &status).ok());
  EXPECT_EQ(status.state(), v1::SIMULATOR_STATE_IDLE);

  // Bad input over the socket too.
  v1::LoadScenarioRequest request;
  request.mutable_preset()->set_name("nope");
  grpc::ClientContext load_context;
  SetDeadline(&load_context, 5.0);
  v1::LoadScenarioResponse response;
  const grpc::Status rpc = stub->LoadScenario(&load_context, request, &response);
  EXPECT_EQ(rpc.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(rpc.error_message().rfind("preset.name:", 0), 0u);

  // After shutdown the health service reports NOT_SERVING or the server is gone.
  server_->Shutdown();
  auto after = transport::CheckHealth(channel, "", std::chrono::seconds(2));
  if (after.ok()) {
    EXPECT_NE(*after, transport::HealthStatus::kServing);
  }
}

TEST_F(SimulatorContractTest, AShortDeadlineExpiresOnALongStep) {
  // 600 frames take seconds on any machine (a fast one rendered 60 inside the 200 ms). Until
  // Player::Step reported a step cut short by its deadline (PlayerTest below), the server answered
  // OK at the deadline, and that answer now and then reached the client before its own timer.
  constexpr int kFrames = 600;
  ASSERT_TRUE(LoadPreset("room-easy", kFrames).ok());
  auto channel = grpc::CreateChannel(server_->target(), grpc::InsecureChannelCredentials());
  // Connect first, so the deadline below times the Step and not the connection set-up.
  ASSERT_TRUE(
      channel->WaitForConnected(std::chrono::system_clock::now() + std::chrono::seconds(5)));
  auto stub = v1::Simulator::NewStub(channel);
  v1::SimulatorStepRequest request;
  request.set_frames(kFrames);  // rendering them takes far longer than 200 ms
  grpc::ClientContext context;
  // Long enough that the server surely receives the call (a call whose deadline passes before
  // it is dispatched is never run), far too short for the step.
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(200));
  v1::SimulatorStatus status;
  const grpc::Status rpc = stub->Step(&context, request, &status);
  EXPECT_EQ(rpc.error_code(), StatusCode::DEADLINE_EXCEEDED);
  // The deadline stops the step too: the frames published before it stay published, no more.
  const v1::SimulatorStatus paused = WaitForState(v1::SIMULATOR_STATE_PAUSED);
  EXPECT_LT(paused.frames_published(), static_cast<uint64_t>(kFrames));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  EXPECT_EQ(WaitForState(v1::SIMULATOR_STATE_PAUSED).frames_published(), paused.frames_published());
}

// The player itself, without gRPC in between: a Step its deadline cuts short is DEADLINE_EXCEEDED
// (the playback loop stops quietly, and the service then answered OK with a partial count, which
// reached the client first now and then: the flaky AShortDeadlineExpiresOnALongStep above). The
// frames published stay published and the player stays usable.
TEST(PlayerTest, AStepCutShortByItsDeadlineIsDeadlineExceeded) {
  RecordingSink sink;
  Player player(&sink);
  Result<std::unique_ptr<ScenarioSource>> source = sim::OpenPreset({"room-easy", 600, 7, false});
  ASSERT_TRUE(source.ok()) << source.status().ToString();
  ASSERT_TRUE(player.Load(std::move(*source)).ok());
  Result<PlayerStatus> stepped = player.Step(600, Termination::AfterMs(100));
  ASSERT_FALSE(stepped.ok());
  EXPECT_EQ(stepped.status().code(), mav::StatusCode::kDeadlineExceeded);
  EXPECT_EQ(stepped.status().message().rfind("Step: the deadline passed after ", 0), 0u)
      << stepped.status().message();
  const PlayerStatus paused = player.GetStatus();
  EXPECT_EQ(paused.state, PlayerState::kPaused);
  EXPECT_LT(paused.frames_published, 600u);
  EXPECT_EQ(sink.events('s').size(), paused.frames_published);
  stepped = player.Step(1);
  ASSERT_TRUE(stepped.ok()) << stepped.status().ToString();
  EXPECT_EQ(stepped->frames_published, paused.frames_published + 1);
}

// A LoadScenario whose deadline passes while the player is busy (a long Step) changes nothing.
TEST_F(SimulatorContractTest, ALoadScenarioPastItsDeadlineChangesNothing) {
  // 200 frames keep the player busy for seconds on any machine (40 could finish within the 100 ms
  // below + the 0.3 s deadline on a fast one).
  constexpr int kFrames = 200;
  ASSERT_TRUE(LoadPreset("room-easy", kFrames).ok());
  std::thread stepper([&] {
    v1::SimulatorStatus status;
    EXPECT_TRUE(Step(kFrames, &status).ok());
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(100));  // the step holds the player
  v1::LoadScenarioRequest request;
  request.mutable_preset()->set_name("room-medium");
  request.mutable_preset()->set_frames(4);
  grpc::ClientContext context;
  SetDeadline(&context, 0.3);
  v1::LoadScenarioResponse response;
  const grpc::Status rpc = stub_->LoadScenario(&context, request, &response);
  stepper.join();
  EXPECT_EQ(rpc.error_code(), StatusCode::DEADLINE_EXCEEDED) << rpc.error_message();
  const v1::SimulatorStatus status = GetStatus();
  EXPECT_EQ(status.scenario().name(), "room-easy");
  EXPECT_EQ(status.frames_published(), static_cast<uint64_t>(kFrames));
}

TEST(SimulatorTransportTest, CallingAPortWithoutServerFailsWithinTheDeadline) {
  // Bind a free port, then close it: nothing listens there.
  transport::ServerOptions options;
  options.port = 0;
  int port = 0;
  {
    auto server = transport::GrpcServer::Start(options, {});
    ASSERT_TRUE(server.ok());
    port = (*server)->port();
  }
  auto channel =
      grpc::CreateChannel("127.0.0.1:" + std::to_string(port), grpc::InsecureChannelCredentials());
  auto stub = v1::Simulator::NewStub(channel);
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(500));
  v1::SimulatorStatus status;
  const grpc::Status rpc = stub->GetStatus(&context, v1::SimulatorGetStatusRequest(), &status);
  EXPECT_TRUE(rpc.error_code() == StatusCode::UNAVAILABLE ||
              rpc.error_code() == StatusCode::DEADLINE_EXCEEDED)
      << rpc.error_code();
}

}  // namespace
}  // namespace mav::simulator_service
