// Contract of mav.v1.Localization (protos/mav/v1/localization.proto, docs/contracts.md): every
// RPC with good and bad input through an in-process channel, the calibration sources (inline, an
// EuRoC directory, a simulator service on a real loopback port), and a real loopback port with the
// grpc.health.v1 check. The DDS side is replaced by a recording pose sink and a fake input switch;
// tests/integration/localization_stack_test.cc runs the service over DDS.
//
// Images: the first frames of the simulator's room-easy preset (raw EuRoC rig, rendered once);
// ground truth from Scenario::StateAt.

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <filesystem>
#include <future>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>
#include <opencv2/core/mat.hpp>

#include "mav/camera/rectifier.h"
#include "mav/dataset/euroc.h"
#include "mav/sim/scenario.h"
#include "mav/transport/grpc_server.h"
#include "mav/v1/localization.grpc.pb.h"
#include "services/localization/convert.h"
#include "services/localization/dds_io.h"
#include "services/localization/localization_service.h"
#include "services/localization/localizer.h"
#include "services/simulator/simulator_service.h"
#include "tests/common/contract_server.h"
#include "tests/common/dds_stereo_frame.h"
#include "tests/common/fake_input_control.h"
#include "tests/common/null_stream_sink.h"

namespace mav::localization_service {
namespace {

using grpc::StatusCode;

using ::mav::test_support::FakeInputControl;  // tests/common/fake_input_control.h
using ::mav::test_support::StartOnFreePort;   // tests/common/contract_server.h

constexpr int kFrames = 6;

// The rendered frames every test shares.
struct Frames {
  sim::Scenario scenario;
  std::vector<cv::Mat> left, right;
};

const Frames& TestFrames() {
  static const Frames* frames = [] {
    sim::ScenarioOptions options;
    options.preset = "room-easy";
    options.frames = 20;
    options.seed = 1;
    options.rectified = false;
    Result<sim::Scenario> scenario = sim::Scenario::Create(options);
    MAV_CHECK(scenario.ok()) << scenario.status().ToString();
    auto* out = new Frames{std::move(*scenario), {}, {}};
    for (int k = 0; k < kFrames; ++k) {
      cv::Mat l, r;
      out->scenario.RenderStereo(k, &l, &r);
      out->left.push_back(l);
      out->right.push_back(r);
    }
    return out;
  }();
  return *frames;
}

void SetImage(const cv::Mat& image, v1::Image* out) {
  out->set_width(static_cast<uint32_t>(image.cols));
  out->set_height(static_cast<uint32_t>(image.rows));
  out->set_encoding(v1::IMAGE_ENCODING_MONO8);
  out->set_data(std::string(reinterpret_cast<const char*>(image.data), image.total()));
}

v1::ProcessStereoPairRequest PairRequest(int k) {
  const Frames& f = TestFrames();
  v1::ProcessStereoPairRequest request;
  request.mutable_stereo()->set_t_ns(f.scenario.FrameTimeNs(k));
  SetImage(f.left[k], request.mutable_stereo()->mutable_left());
  SetImage(f.right[k], request.mutable_stereo()->mutable_right());
  request.mutable_stereo()->set_rectified(false);
  return request;
}

geometry::SE3 FromProto(const v1::Pose& pose) {
  return geometry::SE3(
      Eigen::Quaterniond(pose.orientation().w(), pose.orientation().x(), pose.orientation().y(),
                         pose.orientation().z()),
      Eigen::Vector3d(pose.position().x(), pose.position().y(), pose.position().z()));
}

bool StartsWith(const std::string& text, const std::string& prefix) {
  return text.rfind(prefix, 0) == 0;
}

// Records every published pose; optionally blocks the worker inside PublishPose.
class RecordingSink : public PoseSink {
 public:
  Status PublishPose(const RigPose& pose, OutputFrame frame) override {
    std::unique_lock<std::mutex> lock(mutex_);
    poses_.push_back(pose);
    frames_.push_back(frame);
    if (block_) {
      blocked_ = true;
      cv_.notify_all();
      cv_.wait(lock, [this] { return !block_; });
      blocked_ = false;
    }
    return Status::Ok();
  }
  std::vector<RigPose> poses() {
    std::lock_guard<std::mutex> lock(mutex_);
    return poses_;
  }
  void SetBlocking(bool block) {
    std::lock_guard<std::mutex> lock(mutex_);
    block_ = block;
    cv_.notify_all();
  }
  bool WaitUntilBlocked(std::chrono::seconds timeout) {
    std::unique_lock<std::mutex> lock(mutex_);
    return cv_.wait_for(lock, timeout, [this] { return blocked_; });
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<RigPose> poses_;
  std::vector<OutputFrame> frames_;
  bool block_ = false;
  bool blocked_ = false;
};

class LocalizationContractTest : public ::testing::Test {
 protected:
  void SetUp() override {
    TestFrames();
    localizer_ = std::make_unique<Localizer>(&sink_);
    service_ = std::make_unique<LocalizationService>(localizer_.get(), &input_);
    server_ = StartOnFreePort<v1::Localization>(service_.get());
    ASSERT_NE(server_, nullptr);
    stub_ = v1::Localization::NewStub(server_->InProcessChannel());
  }
  void TearDown() override {
    sink_.SetBlocking(false);
    if (server_ != nullptr) server_->Shutdown();
    localizer_->Shutdown();
  }

  static void SetDeadline(grpc::ClientContext* context, double seconds = 20.0) {
    context->set_deadline(std::chrono::system_clock::now() +
                          std::chrono::milliseconds(static_cast<int64_t>(seconds * 1000)));
  }

  // A request with the rig of the rendered frames given inline.
  static v1::LocalizationConfigureRequest ConfigureRequest(v1::LocalizationMethod method) {
    v1::LocalizationConfigureRequest request;
    request.set_method(method);
    ToProto(TestFrames().scenario.calibration(), false,
            request.mutable_calibration()->mutable_calibration());
    return request;
  }

  grpc::Status Configure(const v1::LocalizationConfigureRequest& request,
                         v1::LocalizationStatus* status = nullptr) {
    v1::LocalizationStatus local;
    grpc::ClientContext context;
    SetDeadline(&context);
    return stub_->Configure(&context, request, status != nullptr ? status : &local);
  }
  grpc::Status Process(const v1::ProcessStereoPairRequest& request,
                       v1::ProcessStereoPairResponse* response = nullptr) {
    v1::ProcessStereoPairResponse local;
    grpc::ClientContext context;
    SetDeadline(&context);
    return stub_->ProcessStereoPair(&context, request, response != nullptr ? response : &local);
  }
  v1::LocalizationStatus GetStatus() {
    v1::LocalizationStatus status;
    grpc::ClientContext context;
    SetDeadline(&context);
    EXPECT_TRUE(stub_->GetStatus(&context, v1::LocalizationGetStatusRequest(), &status).ok());
    return status;
  }
  grpc::Status Reset(const v1::LocalizationResetRequest& request,
                     v1::LocalizationStatus* status = nullptr) {
    v1::LocalizationStatus local;
    grpc::ClientContext context;
    SetDeadline(&context);
    return stub_->Reset(&context, request, status != nullptr ? status : &local);
  }
  grpc::Status Trajectory(const v1::GetTrajectoryRequest& request,
                          std::vector<v1::TrajectoryChunk>* chunks) {
    grpc::ClientContext context;
    SetDeadline(&context);
    auto reader = stub_->GetTrajectory(&context, request);
    v1::TrajectoryChunk chunk;
    while (reader->Read(&chunk)) chunks->push_back(chunk);
    return reader->Finish();
  }
  void ExpectInvalid(const grpc::Status& status, const std::string& field) {
    EXPECT_EQ(status.error_code(), StatusCode::INVALID_ARGUMENT) << status.error_message();
    EXPECT_TRUE(StartsWith(status.error_message(), field))
        << "'" << status.error_message() << "' should start with '" << field << "'";
  }

  RecordingSink sink_;
  FakeInputControl input_;
  std::unique_ptr<Localizer> localizer_;
  std::unique_ptr<LocalizationService> service_;
  std::unique_ptr<transport::GrpcServer> server_;
  std::unique_ptr<v1::Localization::Stub> stub_;
};

// ---- GetStatus / Configure ----------------------------------------------------------------------

TEST_F(LocalizationContractTest, GetStatusIsUnconfiguredAtFirst) {
  const v1::LocalizationStatus status = GetStatus();
  EXPECT_EQ(status.state(), v1::LOCALIZATION_SERVICE_STATE_UNCONFIGURED);
  EXPECT_EQ(status.frames_processed(), 0u);
  EXPECT_FALSE(status.dds_input());
  EXPECT_FALSE(status.has_last_pose());
}

TEST_F(LocalizationContractTest, ConfigureRejectsAnUnknownMethodNamingTheField) {
  ExpectInvalid(Configure(ConfigureRequest(v1::LOCALIZATION_METHOD_UNSPECIFIED)), "method:");
  ExpectInvalid(Configure(ConfigureRequest(static_cast<v1::LocalizationMethod>(7))), "method:");
  EXPECT_EQ(GetStatus().state(), v1::LOCALIZATION_SERVICE_STATE_UNCONFIGURED);
}

TEST_F(LocalizationContractTest, ConfigureRejectsOutOfRangeOptionsNamingTheField) {
  auto sparse = ConfigureRequest(v1::LOCALIZATION_METHOD_SPARSE_SUBPIXEL);
  sparse.mutable_sparse()->set_ransac_iterations(5);
  ExpectInvalid(Configure(sparse), "sparse.ransac_iterations:");
  sparse = ConfigureRequest(v1::LOCALIZATION_METHOD_SPARSE_PIXEL);
  sparse.mutable_sparse()->set_inlier_threshold_px(-1.0);
  ExpectInvalid(Configure(sparse), "sparse.inlier_threshold_px:");
  sparse = ConfigureRequest(v1::LOCALIZATION_METHOD_SPARSE_PIXEL);
  sparse.mutable_sparse()->set_nms_radius_px(11);
  ExpectInvalid(Configure(sparse), "sparse.nms_radius_px:");
  for (const double sigma : {-1e-4, 0.2, std::nan("")}) {
    sparse = ConfigureRequest(v1::LOCALIZATION_METHOD_SPARSE_SUBPIXEL);
    sparse.mutable_sparse()->set_gyro_rotation_sigma_rad(sigma);
    ExpectInvalid(Configure(sparse), "sparse.gyro_rotation_sigma_rad:");
  }

  auto dense = ConfigureRequest(v1::LOCALIZATION_METHOD_DENSE);
  dense.mutable_dense()->set_num_disparities(20);
  ExpectInvalid(Configure(dense), "dense.num_disparities:");
  dense = ConfigureRequest(v1::LOCALIZATION_METHOD_DENSE);
  dense.mutable_dense()->set_block_size(8);
  ExpectInvalid(Configure(dense), "dense.block_size:");
  dense = ConfigureRequest(v1::LOCALIZATION_METHOD_DENSE);
  dense.mutable_dense()->set_pyramid_levels(9);
  ExpectInvalid(Configure(dense), "dense.pyramid_levels:");
  dense = ConfigureRequest(v1::LOCALIZATION_METHOD_DENSE);
  dense.mutable_dense()->set_keyframe_translation_m(std::nan(""));
  ExpectInvalid(Configure(dense), "dense.keyframe_translation_m:");

  auto other = ConfigureRequest(v1::LOCALIZATION_METHOD_SPARSE_SUBPIXEL);
  other.set_queue_length(101);
  ExpectInvalid(Configure(other), "queue_length:");
  other = ConfigureRequest(v1::LOCALIZATION_METHOD_SPARSE_SUBPIXEL);
  other.set_output_frame("cam7");
  ExpectInvalid(Configure(other), "output_frame:");
  other = ConfigureRequest(v1::LOCALIZATION_METHOD_SPARSE_SUBPIXEL);
  other.mutable_initial_pose()->mutable_orientation()->set_w(0.5);
  ExpectInvalid(Configure(other), "initial_pose.orientation:");
  other = ConfigureRequest(v1::LOCALIZATION_METHOD_SPARSE_SUBPIXEL);
  other.mutable_initial_pose();  // set, but the all-zero quaternion is not the identity
  ExpectInvalid(Configure(other), "initial_pose.orientation:");
  other = ConfigureRequest(v1::LOCALIZATION_METHOD_SPARSE_SUBPIXEL);
  other.mutable_t_body_imu()->mutable_orientation()->set_z(3.0);
  ExpectInvalid(Configure(other), "t_body_imu.orientation:");
  EXPECT_EQ(GetStatus().state(), v1::LOCALIZATION_SERVICE_STATE_UNCONFIGURED);
}

TEST_F(LocalizationContractTest, ConfigureRejectsAMissingOrBadCalibration) {
  v1::LocalizationConfigureRequest request;
  request.set_method(v1::LOCALIZATION_METHOD_SPARSE_SUBPIXEL);
  ExpectInvalid(Configure(request), "calibration:");

  request = ConfigureRequest(v1::LOCALIZATION_METHOD_SPARSE_SUBPIXEL);
  request.mutable_calibration()
      ->mutable_calibration()
      ->mutable_left()
      ->mutable_intrinsics()
      ->set_fx(0.0);
  ExpectInvalid(Configure(request), "calibration.calibration.left.intrinsics.fx:");
  request = ConfigureRequest(v1::LOCALIZATION_METHOD_SPARSE_SUBPIXEL);
  request.mutable_calibration()->mutable_calibration()->clear_right();
  ExpectInvalid(Configure(request), "calibration.calibration.right:");
  request = ConfigureRequest(v1::LOCALIZATION_METHOD_SPARSE_SUBPIXEL);
  request.mutable_calibration()
      ->mutable_calibration()
      ->mutable_right()
      ->mutable_intrinsics()
      ->set_width(640);
  ExpectInvalid(Configure(request), "calibration.calibration.right");

  request.mutable_calibration()->set_euroc_directory("");
  ExpectInvalid(Configure(request), "calibration.euroc_directory:");
  request.mutable_calibration()->set_euroc_directory("/nonexistent/euroc");
  grpc::Status status = Configure(request);
  EXPECT_EQ(status.error_code(), StatusCode::NOT_FOUND) << status.error_message();
  EXPECT_NE(status.error_message().find("/nonexistent/euroc"), std::string::npos);

  request.mutable_calibration()->set_simulator_address("");
  ExpectInvalid(Configure(request), "calibration.simulator_address:");
  request.mutable_calibration()->set_simulator_address("127.0.0.1:1");
  status = Configure(request);
  EXPECT_EQ(status.error_code(), StatusCode::UNAVAILABLE) << status.error_message();
  EXPECT_TRUE(StartsWith(status.error_message(), "calibration.simulator_address:"));
  EXPECT_EQ(GetStatus().state(), v1::LOCALIZATION_SERVICE_STATE_UNCONFIGURED);
}

TEST_F(LocalizationContractTest, ConfigureReadsAnEurocDirectory) {
  const std::filesystem::path root =
      std::filesystem::temp_directory_path() / ("mav-loc-contract-" + std::to_string(::getpid()));
  std::filesystem::create_directories(root / "mav0" / "cam0");
  std::filesystem::create_directories(root / "mav0" / "cam1");
  const camera::StereoCalibration& calibration = TestFrames().scenario.calibration();
  dataset::CameraSensor cam0{calibration.cam0, calibration.T_body_cam0, 20.0, "cam0"};
  dataset::CameraSensor cam1{calibration.cam1, calibration.T_body_cam1, 20.0, "cam1"};
  ASSERT_TRUE(dataset::WriteCameraSensorYaml((root / "mav0/cam0/sensor.yaml").string(), cam0).ok());

  v1::LocalizationConfigureRequest request;
  request.set_method(v1::LOCALIZATION_METHOD_SPARSE_PIXEL);
  request.mutable_calibration()->set_euroc_directory(root.string());
  grpc::Status status = Configure(request);  // cam1 missing
  EXPECT_EQ(status.error_code(), StatusCode::NOT_FOUND) << status.error_message();
  EXPECT_NE(status.error_message().find("cam1/sensor.yaml"), std::string::npos);

  // A malformed file is INVALID_ARGUMENT naming the file.
  {
    std::FILE* file = std::fopen((root / "mav0/cam1/sensor.yaml").c_str(), "w");
    ASSERT_NE(file, nullptr);
    std::fputs("sensor_type: camera\nintrinsics: [1, 2]\n", file);
    std::fclose(file);
  }
  status = Configure(request);
  EXPECT_EQ(status.error_code(), StatusCode::INVALID_ARGUMENT) << status.error_message();
  EXPECT_NE(status.error_message().find("cam1/sensor.yaml"), std::string::npos)
      << status.error_message();

  ASSERT_TRUE(dataset::WriteCameraSensorYaml((root / "mav0/cam1/sensor.yaml").string(), cam1).ok());
  v1::LocalizationStatus configured;
  status = Configure(request, &configured);
  ASSERT_TRUE(status.ok()) << status.error_message();
  const auto& left = configured.config().calibration().calibration().left().intrinsics();
  EXPECT_DOUBLE_EQ(left.fx(), calibration.cam0.fx);
  EXPECT_DOUBLE_EQ(left.k1(), calibration.cam0.k1);
  EXPECT_EQ(configured.method(), v1::LOCALIZATION_METHOD_SPARSE_PIXEL);
  // The mav0 directory itself works too.
  request.mutable_calibration()->set_euroc_directory((root / "mav0").string());
  EXPECT_TRUE(Configure(request).ok());
  std::filesystem::remove_all(root);
}

// A simulator service on a real loopback port as the calibration source.
TEST_F(LocalizationContractTest, ConfigureAsksASimulatorForItsCalibration) {
  test_support::NullStreamSink null_sink;
  simulator_service::SimulatorService simulator(&null_sink);
  auto simulator_server = transport::GrpcServer::Start(transport::ServerOptions{}, {&simulator});
  ASSERT_TRUE(simulator_server.ok()) << simulator_server.status().ToString();

  v1::LocalizationConfigureRequest request;
  request.set_method(v1::LOCALIZATION_METHOD_SPARSE_SUBPIXEL);
  request.mutable_calibration()->set_simulator_address((*simulator_server)->target());
  grpc::Status status = Configure(request);
  EXPECT_EQ(status.error_code(), StatusCode::FAILED_PRECONDITION) << status.error_message();
  EXPECT_TRUE(StartsWith(status.error_message(), "calibration.simulator_address:"));

  sim::PresetRequest preset;
  preset.name = "room-easy";
  preset.frames = 5;
  auto source = sim::OpenPreset(preset);
  ASSERT_TRUE(source.ok()) << source.status().ToString();
  ASSERT_TRUE(simulator.player().Load(std::move(*source)).ok());
  v1::LocalizationStatus configured;
  status = Configure(request, &configured);
  ASSERT_TRUE(status.ok()) << status.error_message();
  const auto& left = configured.config().calibration().calibration().left().intrinsics();
  EXPECT_DOUBLE_EQ(left.fx(), TestFrames().scenario.calibration().cam0.fx);
  EXPECT_EQ(left.width(), 752u);
  (*simulator_server)->Shutdown();
}

TEST_F(LocalizationContractTest, ConfigureReportsTheEffectiveConfiguration) {
  v1::LocalizationStatus status;
  auto request = ConfigureRequest(v1::LOCALIZATION_METHOD_SPARSE_SUBPIXEL);
  request.mutable_sparse()->set_ransac_iterations(300);
  request.mutable_sparse()->set_gyro_rotation_sigma_rad(1e-4);
  ASSERT_TRUE(Configure(request, &status).ok());
  EXPECT_EQ(status.state(), v1::LOCALIZATION_SERVICE_STATE_READY);
  EXPECT_EQ(status.method(), v1::LOCALIZATION_METHOD_SPARSE_SUBPIXEL);
  EXPECT_TRUE(status.dds_input());
  EXPECT_TRUE(input_.input_enabled());
  const v1::LocalizationConfigureRequest& config = status.config();
  EXPECT_EQ(config.sparse().ransac_iterations(), 300u);
  EXPECT_DOUBLE_EQ(config.sparse().gyro_rotation_sigma_rad(), 1e-4);
  EXPECT_GT(config.sparse().nms_radius_px(), 0u) << "defaults are filled in";
  EXPECT_GT(config.sparse().inlier_threshold_px(), 0.0);
  EXPECT_EQ(config.queue_length(), 2u);
  EXPECT_EQ(config.output_frame(), "body");
  EXPECT_DOUBLE_EQ(config.initial_pose().orientation().w(), 1.0);
  EXPECT_DOUBLE_EQ(config.t_body_imu().orientation().w(), 1.0) << "unset: the body is the IMU";
  EXPECT_FALSE(config.disable_dds_input());

  request = ConfigureRequest(v1::LOCALIZATION_METHOD_DENSE);
  request.set_disable_dds_input(true);
  request.set_queue_length(5);
  // A vehicle's IMU under a forward rig (a mission flight): x up, z forward.
  request.mutable_t_body_imu()->mutable_orientation()->set_w(0.5);
  request.mutable_t_body_imu()->mutable_orientation()->set_x(0.5);
  request.mutable_t_body_imu()->mutable_orientation()->set_y(0.5);
  request.mutable_t_body_imu()->mutable_orientation()->set_z(0.5);
  ASSERT_TRUE(Configure(request, &status).ok());
  EXPECT_DOUBLE_EQ(status.config().t_body_imu().orientation().x(), 0.5);
  EXPECT_EQ(status.method(), v1::LOCALIZATION_METHOD_DENSE);
  EXPECT_FALSE(status.dds_input());
  EXPECT_FALSE(input_.input_enabled());
  EXPECT_TRUE(status.config().disable_dds_input());
  EXPECT_EQ(status.config().queue_length(), 5u);
  EXPECT_GT(status.config().dense().pyramid_levels(), 0u);
  EXPECT_GT(status.config().dense().num_disparities(), 0u);
}

// ---- ProcessStereoPair --------------------------------------------------------------------------

TEST_F(LocalizationContractTest, ProcessStereoPairNeedsAConfiguration) {
  const grpc::Status status = Process(PairRequest(0));
  EXPECT_EQ(status.error_code(), StatusCode::FAILED_PRECONDITION) << status.error_message();
}

TEST_F(LocalizationContractTest, ProcessStereoPairRejectsBadImagesNamingTheField) {
  ASSERT_TRUE(Configure(ConfigureRequest(v1::LOCALIZATION_METHOD_SPARSE_SUBPIXEL)).ok());
  v1::ProcessStereoPairRequest request;
  ExpectInvalid(Process(request), "stereo:");

  request = PairRequest(0);
  request.mutable_stereo()->mutable_left()->Clear();
  ExpectInvalid(Process(request), "stereo.left:");
  request = PairRequest(0);
  request.mutable_stereo()->mutable_right()->clear_data();
  ExpectInvalid(Process(request), "stereo.right.data:");
  request = PairRequest(0);
  request.mutable_stereo()->mutable_left()->set_encoding(v1::IMAGE_ENCODING_UNSPECIFIED);
  ExpectInvalid(Process(request), "stereo.left.encoding:");

  // Wrong size: a consistent 640x480 pair that does not match the 752x480 calibration.
  request = PairRequest(0);
  const cv::Mat small(480, 640, CV_8UC1, cv::Scalar(128));
  SetImage(small, request.mutable_stereo()->mutable_left());
  SetImage(small, request.mutable_stereo()->mutable_right());
  grpc::Status status = Process(request);
  ExpectInvalid(status, "stereo.left:");
  EXPECT_NE(status.error_message().find("752x480"), std::string::npos) << status.error_message();
  // Left and right of different sizes.
  request = PairRequest(0);
  SetImage(small, request.mutable_stereo()->mutable_right());
  ExpectInvalid(Process(request), "stereo.right:");

  // Time must increase.
  ASSERT_TRUE(Process(PairRequest(1)).ok());
  status = Process(PairRequest(0));
  ExpectInvalid(status, "stereo.t_ns:");
  ExpectInvalid(Process(PairRequest(1)), "stereo.t_ns:");
  EXPECT_EQ(GetStatus().frames_processed(), 1u) << "rejected frames are not processed";
}

TEST_F(LocalizationContractTest, ProcessStereoPairTracksTheRenderedFrames) {
  ASSERT_TRUE(Configure(ConfigureRequest(v1::LOCALIZATION_METHOD_SPARSE_SUBPIXEL)).ok());
  const sim::Scenario& scenario = TestFrames().scenario;
  const geometry::SE3 T_world_body0 = scenario.StateAt(scenario.FrameTimeNs(0)).T_world_body;
  double previous_variance = -1.0;
  for (int k = 0; k < kFrames; ++k) {
    v1::ProcessStereoPairResponse response;
    const grpc::Status status = Process(PairRequest(k), &response);
    ASSERT_TRUE(status.ok()) << status.error_message();
    EXPECT_EQ(response.frame_index(), static_cast<uint64_t>(k));
    EXPECT_EQ(response.pose().t_ns(), scenario.FrameTimeNs(k));
    EXPECT_EQ(response.tracking_state(),
              k == 0 ? v1::TRACKING_STATE_INITIALIZING : v1::TRACKING_STATE_OK)
        << response.lost_reason();
    ASSERT_EQ(response.pose().covariance_size(), 36);
    const double variance = response.pose().covariance(0);
    EXPECT_GE(variance, previous_variance) << "the heuristic covariance grows along the path";
    previous_variance = variance;
    if (k > 0) {
      EXPECT_GT(response.inliers(), 20u);
      EXPECT_GE(response.matches(), response.inliers());
      EXPECT_GT(response.timing().total_ms(), 0.0);
      EXPECT_GT(response.timing().rectify_ms(), 0.0) << "raw frames are rectified";
      EXPECT_GT(variance, 0.0);
    }
    // The body pose relative to the first frame's body pose, against ground truth.
    const geometry::SE3 expected =
        T_world_body0.Inverse() * scenario.StateAt(scenario.FrameTimeNs(k)).T_world_body;
    const geometry::SE3 estimate = FromProto(response.pose().pose());
    EXPECT_LT((estimate.Translation() - expected.Translation()).norm(), 0.02) << "frame " << k;
    EXPECT_LT((estimate.Inverse() * expected).Log().tail<3>().norm(), 0.5 * M_PI / 180)
        << "frame " << k;
  }
  EXPECT_EQ(sink_.poses().size(), static_cast<size_t>(kFrames));

  const v1::LocalizationStatus status = GetStatus();
  EXPECT_EQ(status.state(), v1::LOCALIZATION_SERVICE_STATE_RUNNING);
  EXPECT_EQ(status.frames_processed(), static_cast<uint64_t>(kFrames));
  EXPECT_EQ(status.frames_lost(), 0u);
  EXPECT_EQ(status.frames_dropped(), 0u);
  EXPECT_EQ(status.tracking_state(), v1::TRACKING_STATE_OK);
  EXPECT_EQ(status.last_pose().t_ns(), scenario.FrameTimeNs(kFrames - 1));
  EXPECT_EQ(status.processing_ms().count(), static_cast<uint64_t>(kFrames));
  EXPECT_GT(status.processing_ms().mean_ms(), 0.0);
  EXPECT_GE(status.processing_ms().max_ms(), status.processing_ms().p95_ms());
  EXPECT_GT(status.fps(), 0.0);
  std::printf("sparse-subpixel through ProcessStereoPair: %.1f ms/frame mean, %.1f max\n",
              status.processing_ms().mean_ms(), status.processing_ms().max_ms());
}

TEST_F(LocalizationContractTest, SkipPublishOutputFrameAndRectifiedInput) {
  auto request = ConfigureRequest(v1::LOCALIZATION_METHOD_SPARSE_PIXEL);
  request.set_output_frame("cam0");
  request.mutable_initial_pose()->mutable_position()->set_x(1.0);
  request.mutable_initial_pose()->mutable_orientation()->set_w(1.0);
  ASSERT_TRUE(Configure(request).ok());
  const camera::StereoCalibration& calibration = TestFrames().scenario.calibration();

  auto pair = PairRequest(0);
  pair.set_skip_publish(true);
  v1::ProcessStereoPairResponse response;
  ASSERT_TRUE(Process(pair, &response).ok());
  EXPECT_TRUE(sink_.poses().empty()) << "skip_publish";
  // The first pose is the initial body pose composed with T_body_cam0.
  const geometry::SE3 expected =
      geometry::SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 0, 0)) *
      calibration.T_body_cam0;
  EXPECT_TRUE(FromProto(response.pose().pose()).IsApprox(expected, 1e-9));

  // Images rectified by the client with the same rig are not rectified again.
  Result<camera::StereoRectifier> rectifier = camera::StereoRectifier::Create(calibration);
  ASSERT_TRUE(rectifier.ok());
  cv::Mat left, right;
  ASSERT_TRUE(rectifier->Rectify(TestFrames().left[1], TestFrames().right[1], &left, &right).ok());
  pair = PairRequest(1);
  SetImage(left, pair.mutable_stereo()->mutable_left());
  SetImage(right, pair.mutable_stereo()->mutable_right());
  pair.mutable_stereo()->set_rectified(true);
  ASSERT_TRUE(Process(pair, &response).ok());
  EXPECT_EQ(response.tracking_state(), v1::TRACKING_STATE_OK) << response.lost_reason();
  EXPECT_DOUBLE_EQ(response.timing().rectify_ms(), 0.0);
  EXPECT_EQ(sink_.poses().size(), 1u);
  // delta is the motion of cam0 between the frames: small but not zero.
  const geometry::SE3 delta = FromProto(response.delta());
  EXPECT_GT(delta.Translation().norm(), 1e-4);
  EXPECT_LT(delta.Translation().norm(), 0.2);
}

TEST_F(LocalizationContractTest, DenseMethodTracksAndCountsKeyframes) {
  ASSERT_TRUE(Configure(ConfigureRequest(v1::LOCALIZATION_METHOD_DENSE)).ok());
  const sim::Scenario& scenario = TestFrames().scenario;
  const geometry::SE3 T_world_body0 = scenario.StateAt(scenario.FrameTimeNs(0)).T_world_body;
  v1::ProcessStereoPairResponse response;
  for (int k = 0; k < 4; ++k) {
    ASSERT_TRUE(Process(PairRequest(k), &response).ok());
    EXPECT_NE(response.tracking_state(), v1::TRACKING_STATE_LOST) << response.lost_reason();
  }
  const geometry::SE3 expected =
      T_world_body0.Inverse() * scenario.StateAt(scenario.FrameTimeNs(3)).T_world_body;
  EXPECT_LT((FromProto(response.pose().pose()).Translation() - expected.Translation()).norm(),
            0.02);
  EXPECT_GT(response.inliers(), 100u);
  const v1::LocalizationStatus status = GetStatus();
  EXPECT_GE(status.keyframes(), 1u);
  EXPECT_EQ(status.frames_processed(), 4u);
}

// The input queue: unary requests beyond it are RESOURCE_EXHAUSTED, live frames drop the oldest.
TEST_F(LocalizationContractTest, AFullQueueRejectsUnaryRequestsAndDropsLiveFrames) {
  auto request = ConfigureRequest(v1::LOCALIZATION_METHOD_SPARSE_PIXEL);
  request.set_queue_length(1);
  ASSERT_TRUE(Configure(request).ok());
  sink_.SetBlocking(true);  // the worker stops inside the first frame's publish

  auto first = std::async(std::launch::async, [&] { return Process(PairRequest(0)); });
  ASSERT_TRUE(sink_.WaitUntilBlocked(std::chrono::seconds(20)));
  auto second = std::async(std::launch::async, [&] { return Process(PairRequest(1)); });
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (GetStatus().queue_depth() < 1 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_EQ(GetStatus().queue_depth(), 1u);
  const grpc::Status full = Process(PairRequest(2));
  EXPECT_EQ(full.error_code(), StatusCode::RESOURCE_EXHAUSTED) << full.error_message();

  // A live frame finds only a unary request queued: it is dropped, never the request.
  StereoInput live;
  live.t_ns = TestFrames().scenario.FrameTimeNs(3);
  live.left = TestFrames().left[3];
  live.right = TestFrames().right[3];
  EXPECT_EQ(localizer_->SubmitLive(live).code(), mav::StatusCode::kResourceExhausted);
  EXPECT_EQ(GetStatus().frames_dropped(), 1u);

  sink_.SetBlocking(false);
  EXPECT_TRUE(first.get().ok());
  EXPECT_TRUE(second.get().ok());
  // Now live frames queue; a second one while the first waits drops the older one.
  sink_.SetBlocking(true);
  live.t_ns = TestFrames().scenario.FrameTimeNs(3);
  EXPECT_TRUE(localizer_->SubmitLive(live).ok());
  ASSERT_TRUE(sink_.WaitUntilBlocked(std::chrono::seconds(20)));
  live.t_ns = TestFrames().scenario.FrameTimeNs(4);
  live.left = TestFrames().left[4];
  live.right = TestFrames().right[4];
  EXPECT_TRUE(localizer_->SubmitLive(live).ok());
  live.t_ns = TestFrames().scenario.FrameTimeNs(5);
  live.left = TestFrames().left[5];
  live.right = TestFrames().right[5];
  EXPECT_TRUE(localizer_->SubmitLive(live).ok());  // drops the older live frame
  // A malformed live frame is counted as rejected.
  StereoInput bad;
  bad.t_ns = TestFrames().scenario.FrameTimeNs(6);
  bad.left = cv::Mat(10, 10, CV_8UC1, cv::Scalar(0));
  bad.right = bad.left;
  EXPECT_EQ(localizer_->SubmitLive(bad).code(), mav::StatusCode::kInvalidArgument);
  sink_.SetBlocking(false);
  const auto done = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (GetStatus().frames_processed() < 4 && std::chrono::steady_clock::now() < done) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  const v1::LocalizationStatus status = GetStatus();
  EXPECT_EQ(status.frames_processed(), 4u);  // frames 0, 1, 3, 5
  EXPECT_EQ(status.frames_dropped(), 2u);
  EXPECT_EQ(status.frames_rejected(), 1u);
  EXPECT_EQ(status.last_pose().t_ns(), TestFrames().scenario.FrameTimeNs(5));
}

// A value echoed into an error is quoted short: a 10 KB frame name stays INVALID_ARGUMENT (gRPC
// refuses metadata above ~8 KB and would have turned it into RESOURCE_EXHAUSTED), and the message
// names the value's size instead of repeating it.
TEST_F(LocalizationContractTest, AHugeInvalidValueIsStillInvalidArgumentWithAShortMessage) {
  auto request = ConfigureRequest(v1::LOCALIZATION_METHOD_SPARSE_PIXEL);
  request.set_output_frame(std::string(10000, 'x'));
  auto channel = grpc::CreateChannel(server_->target(), grpc::InsecureChannelCredentials());
  auto stub = v1::Localization::NewStub(channel);
  grpc::ClientContext context;
  SetDeadline(&context);
  v1::LocalizationStatus status;
  const grpc::Status rpc = stub->Configure(&context, request, &status);
  ExpectInvalid(rpc, "output_frame:");
  EXPECT_THAT(rpc.error_message(), ::testing::HasSubstr("...' (10000 bytes)"));
  EXPECT_LT(rpc.error_message().size(), 200u);
}

// A calibration source that answers but is no simulator: UNAVAILABLE with a reason.
TEST_F(LocalizationContractTest, ACalibrationSourceThatIsNoSimulatorGivesAReason) {
  auto request = ConfigureRequest(v1::LOCALIZATION_METHOD_SPARSE_PIXEL);
  request.mutable_calibration()->set_simulator_address(server_->target());  // a localization
  const grpc::Status rpc = Configure(request);
  EXPECT_EQ(rpc.error_code(), StatusCode::UNAVAILABLE);
  EXPECT_TRUE(StartsWith(rpc.error_message(), "calibration.simulator_address: GetCalibration at "))
      << rpc.error_message();
  EXPECT_NE(rpc.error_message().find("UNIMPLEMENTED"), std::string::npos) << rpc.error_message();
}

// Calls whose deadline passes while the worker is busy change nothing: the frame is withdrawn,
// the configuration stays.
TEST_F(LocalizationContractTest, CallsPastTheirDeadlineChangeNothing) {
  ASSERT_TRUE(Configure(ConfigureRequest(v1::LOCALIZATION_METHOD_SPARSE_PIXEL)).ok());
  sink_.SetBlocking(true);  // the worker stops inside the first frame's publish
  auto first = std::async(std::launch::async, [&] { return Process(PairRequest(0)); });
  ASSERT_TRUE(sink_.WaitUntilBlocked(std::chrono::seconds(20)));
  {
    grpc::ClientContext context;
    SetDeadline(&context, 0.3);
    v1::ProcessStereoPairResponse response;
    const grpc::Status late = stub_->ProcessStereoPair(&context, PairRequest(1), &response);
    EXPECT_EQ(late.error_code(), StatusCode::DEADLINE_EXCEEDED) << late.error_message();
  }
  std::future<grpc::Status> configure = std::async(std::launch::async, [&] {
    grpc::ClientContext context;
    SetDeadline(&context, 0.3);
    v1::LocalizationStatus status;
    return stub_->Configure(&context, ConfigureRequest(v1::LOCALIZATION_METHOD_DENSE), &status);
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(600));
  sink_.SetBlocking(false);
  EXPECT_TRUE(first.get().ok());
  EXPECT_EQ(configure.get().error_code(), StatusCode::DEADLINE_EXCEEDED);
  const v1::LocalizationStatus status = GetStatus();
  EXPECT_EQ(status.method(), v1::LOCALIZATION_METHOD_SPARSE_PIXEL) << "the late Configure applied";
  EXPECT_EQ(status.frames_processed(), 1u) << "the late frame was processed";
  // The withdrawn frame's time stamp may come again (a retry), and is accepted.
  EXPECT_TRUE(Process(PairRequest(1)).ok());
}

// ---- GetTrajectory / Reset ----------------------------------------------------------------------

TEST_F(LocalizationContractTest, GetTrajectoryStreamsChunksAndValidates) {
  std::vector<v1::TrajectoryChunk> chunks;
  ASSERT_TRUE(Trajectory(v1::GetTrajectoryRequest(), &chunks).ok());
  ASSERT_EQ(chunks.size(), 1u);
  EXPECT_TRUE(chunks[0].last());
  EXPECT_EQ(chunks[0].points_size(), 0);

  v1::GetTrajectoryRequest bad;
  bad.set_start_t_ns(10);
  bad.set_end_t_ns(5);
  chunks.clear();
  ExpectInvalid(Trajectory(bad, &chunks), "start_t_ns:");
  bad = v1::GetTrajectoryRequest();
  bad.set_max_poses_per_chunk(100001);
  chunks.clear();
  ExpectInvalid(Trajectory(bad, &chunks), "max_poses_per_chunk:");

  ASSERT_TRUE(Configure(ConfigureRequest(v1::LOCALIZATION_METHOD_SPARSE_PIXEL)).ok());
  for (int k = 0; k < 5; ++k) ASSERT_TRUE(Process(PairRequest(k)).ok());
  v1::GetTrajectoryRequest request;
  request.set_max_poses_per_chunk(2);
  chunks.clear();
  ASSERT_TRUE(Trajectory(request, &chunks).ok());
  ASSERT_EQ(chunks.size(), 3u);
  EXPECT_EQ(chunks[0].points_size(), 2);
  EXPECT_EQ(chunks[2].points_size(), 1);
  EXPECT_FALSE(chunks[0].last());
  EXPECT_TRUE(chunks[2].last());
  const sim::Scenario& scenario = TestFrames().scenario;
  EXPECT_EQ(chunks[0].points(0).pose().t_ns(), scenario.FrameTimeNs(0));
  EXPECT_EQ(chunks[0].points(0).tracking_state(), v1::TRACKING_STATE_INITIALIZING);
  EXPECT_EQ(chunks[2].points(0).pose().t_ns(), scenario.FrameTimeNs(4));
  EXPECT_EQ(chunks[2].points(0).pose().covariance_size(), 36);

  request = v1::GetTrajectoryRequest();
  request.set_start_t_ns(scenario.FrameTimeNs(1));
  request.set_end_t_ns(scenario.FrameTimeNs(3));
  chunks.clear();
  ASSERT_TRUE(Trajectory(request, &chunks).ok());
  ASSERT_EQ(chunks.size(), 1u);
  ASSERT_EQ(chunks[0].points_size(), 3);
  EXPECT_EQ(chunks[0].points(2).pose().t_ns(), scenario.FrameTimeNs(3));
}

TEST_F(LocalizationContractTest, ResetStartsANewTrajectoryAndKeepsTheConfiguration) {
  ASSERT_TRUE(Configure(ConfigureRequest(v1::LOCALIZATION_METHOD_SPARSE_SUBPIXEL)).ok());
  for (int k = 0; k < 3; ++k) ASSERT_TRUE(Process(PairRequest(k)).ok());

  v1::LocalizationResetRequest bad;
  bad.mutable_initial_pose()->mutable_orientation()->set_x(2.0);
  ExpectInvalid(Reset(bad), "initial_pose.orientation:");
  EXPECT_EQ(GetStatus().frames_processed(), 3u) << "a rejected Reset changes nothing";

  v1::LocalizationResetRequest request;
  request.mutable_initial_pose()->mutable_position()->set_z(2.5);
  request.mutable_initial_pose()->mutable_orientation()->set_w(1.0);
  v1::LocalizationStatus status;
  ASSERT_TRUE(Reset(request, &status).ok());
  EXPECT_EQ(status.state(), v1::LOCALIZATION_SERVICE_STATE_READY);
  EXPECT_EQ(status.frames_processed(), 0u);
  EXPECT_EQ(status.method(), v1::LOCALIZATION_METHOD_SPARSE_SUBPIXEL);
  std::vector<v1::TrajectoryChunk> chunks;
  ASSERT_TRUE(Trajectory(v1::GetTrajectoryRequest(), &chunks).ok());
  EXPECT_EQ(chunks.at(0).points_size(), 0);

  // Time may start again after a reset; the new trajectory starts at the given pose.
  v1::ProcessStereoPairResponse response;
  ASSERT_TRUE(Process(PairRequest(0), &response).ok());
  EXPECT_EQ(response.frame_index(), 0u);
  EXPECT_NEAR(response.pose().pose().position().z(), 2.5, 1e-12);
  EXPECT_EQ(response.tracking_state(), v1::TRACKING_STATE_INITIALIZING);
  // Reset without a pose (always OK, also when unconfigured elsewhere).
  ASSERT_TRUE(Reset(v1::LocalizationResetRequest()).ok());
  ASSERT_TRUE(Process(PairRequest(0), &response).ok());
  EXPECT_NEAR(response.pose().pose().position().z(), 0.0, 1e-12) << "the configured pose again";
}

// ---- A real loopback port -----------------------------------------------------------------------

TEST_F(LocalizationContractTest, LoopbackPortAnswersHealthChecksAndRpcs) {
  auto channel = grpc::CreateChannel(server_->target(), grpc::InsecureChannelCredentials());
  auto overall = transport::CheckHealth(channel, "", std::chrono::seconds(5));
  ASSERT_TRUE(overall.ok()) << overall.status().ToString();
  EXPECT_EQ(*overall, transport::HealthStatus::kServing);
  auto service = transport::CheckHealth(channel, "mav.v1.Localization", std::chrono::seconds(5));
  ASSERT_TRUE(service.ok()) << service.status().ToString();
  EXPECT_EQ(*service, transport::HealthStatus::kServing);

  auto stub = v1::Localization::NewStub(channel);
  {
    grpc::ClientContext context;
    SetDeadline(&context, 5.0);
    v1::LocalizationStatus status;
    const grpc::Status rpc = stub->Configure(
        &context, ConfigureRequest(v1::LOCALIZATION_METHOD_SPARSE_SUBPIXEL), &status);
    ASSERT_TRUE(rpc.ok()) << rpc.error_message();
  }
  {
    // A full 752x480 pair (~722 KB) fits gRPC's default message size.
    grpc::ClientContext context;
    SetDeadline(&context, 5.0);
    v1::ProcessStereoPairResponse response;
    const grpc::Status rpc = stub->ProcessStereoPair(&context, PairRequest(0), &response);
    ASSERT_TRUE(rpc.ok()) << rpc.error_message();
    EXPECT_EQ(response.frame_index(), 0u);
  }
  {
    grpc::ClientContext context;
    SetDeadline(&context, 5.0);
    v1::LocalizationStatus status;
    ASSERT_TRUE(stub->GetStatus(&context, v1::LocalizationGetStatusRequest(), &status).ok());
    EXPECT_EQ(status.frames_processed(), 1u);
  }
  server_->Shutdown();
  auto after = transport::CheckHealth(channel, "", std::chrono::seconds(2));
  if (after.ok()) {
    EXPECT_NE(*after, transport::HealthStatus::kServing);
  }
}

// ---- DDS conversions ----------------------------------------------------------------------------

TEST(LocalizationDdsTest, PoseSamplesCarryTheContractFields) {
  RigPose pose;
  pose.t_ns = 123;
  pose.T_world_out =
      geometry::SE3(Eigen::Quaterniond(0.5, 0.5, 0.5, 0.5), Eigen::Vector3d(1.0, 2.0, 3.0));
  pose.covariance[0] = 0.25;
  pose.covariance[35] = 0.5;
  pose.state = ReportedState::kLost;
  pose.inliers = 42;
  pose.timing.total_ms = 7.5;
  const mav_dds_PoseWithCovariance sample = ToDds(9, pose, OutputFrame::kBody, 1000);
  EXPECT_EQ(sample.sequence_number, 9u);
  EXPECT_EQ(sample.t_ns, 123);
  EXPECT_STREQ(sample.frame_id, "world");
  EXPECT_STREQ(sample.child_frame_id, "body");
  EXPECT_DOUBLE_EQ(sample.position.y, 2.0);
  EXPECT_DOUBLE_EQ(sample.orientation.w, 0.5);
  EXPECT_DOUBLE_EQ(sample.covariance[35], 0.5);
  EXPECT_EQ(sample.tracking_state, mav_dds_TRACKING_STATE_LOST);
  EXPECT_EQ(sample.inliers, 42u);
  EXPECT_DOUBLE_EQ(sample.processing_ms, 7.5);
  EXPECT_STREQ(ToDds(0, pose, OutputFrame::kCam0, 0).child_frame_id, "cam0");
}

TEST(LocalizationDdsTest, StereoFramesAreCheckedBeforeUse) {
  test_support::DdsStereoFrame sample(4, 3, 7, 9);
  mav_dds_StereoFrame& frame = sample.sample();
  EXPECT_TRUE(CheckStereoFrame(frame).ok());
  const dataset::StereoPair input = service_common::StereoFromDds(frame);
  EXPECT_EQ(input.left.cols, 4);
  EXPECT_EQ(input.right.at<uint8_t>(2, 3), 9);
  frame.crc32 ^= 1;
  EXPECT_NE(CheckStereoFrame(frame).message().find("crc32"), std::string::npos);
  frame.crc32 ^= 1;
  frame.right._length = 11;
  EXPECT_NE(CheckStereoFrame(frame).message().find("right: 11 bytes"), std::string::npos);
}

}  // namespace
}  // namespace mav::localization_service
