// mav.v1.Mapping: every RPC with good and bad input, through an in-process channel and a real
// loopback port (health, a deadline), plus the gRPC-free pieces of the service: the pose matcher
// (ground-truth interpolation, exact match of localization poses, the drop rules) and the DDS
// sample checks. Keyframes are rendered by libs/sim (room-easy, ideal rectified rig) with their
// exact ground-truth poses.

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <limits>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>
#include <octomap/OcTree.h>
#include <opencv2/core/mat.hpp>

#include "mav/v1/mapping.grpc.pb.h"

#include "mav/camera/rectifier.h"
#include "mav/common/file.h"
#include "mav/common/stats.h"
#include "mav/common/time.h"
#include "mav/dataset/occupancy_io.h"
#include "mav/mapping/mesh.h"
#include "mav/sim/occupancy.h"
#include "mav/sim/scenario.h"
#include "mav/transport/grpc_server.h"
#include "mav/transport/service_main.h"
#include "services/common/dds_codec.h"
#include "services/mapping/convert.h"
#include "services/mapping/dds_io.h"
#include "services/mapping/mapper.h"
#include "services/mapping/mapping_service.h"
#include "tests/common/contract_server.h"
#include "tests/common/dds_stereo_frame.h"
#include "tests/common/sanitizers.h"

namespace mav::mapping_service {
namespace {

using grpc::StatusCode;

using ::mav::test_support::StartOnFreePort;  // tests/common/contract_server.h

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::chrono::system_clock::time_point Deadline(double seconds) {
  return std::chrono::system_clock::now() +
         std::chrono::milliseconds(static_cast<int64_t>(seconds * 1000));
}

void SetPose(const geometry::SE3& pose, v1::Pose* out) {
  const Eigen::Vector3d& t = pose.Translation();
  const Eigen::Quaterniond& q = pose.Rotation();
  out->mutable_position()->set_x(t.x());
  out->mutable_position()->set_y(t.y());
  out->mutable_position()->set_z(t.z());
  out->mutable_orientation()->set_w(q.w());
  out->mutable_orientation()->set_x(q.x());
  out->mutable_orientation()->set_y(q.y());
  out->mutable_orientation()->set_z(q.z());
}

void SetImage(const cv::Mat& image, v1::Image* out) {
  out->set_width(static_cast<uint32_t>(image.cols));
  out->set_height(static_cast<uint32_t>(image.rows));
  out->set_encoding(v1::IMAGE_ENCODING_MONO8);
  out->set_data(std::string(reinterpret_cast<const char*>(image.data), image.total()));
}

void SetCamera(const camera::PinholeRadTan& c, const geometry::SE3& T_body_cam,
               v1::CameraCalibration* out) {
  v1::CameraIntrinsics* k = out->mutable_intrinsics();
  k->set_width(c.width);
  k->set_height(c.height);
  k->set_fx(c.fx);
  k->set_fy(c.fy);
  k->set_cx(c.cx);
  k->set_cy(c.cy);
  k->set_k1(c.k1);
  k->set_k2(c.k2);
  k->set_p1(c.p1);
  k->set_p2(c.p2);
  SetPose(T_body_cam, out->mutable_t_body_cam());
}

v1::Box MakeBox(double x0, double y0, double z0, double x1, double y1, double z1) {
  v1::Box box;
  box.mutable_min()->set_x(x0);
  box.mutable_min()->set_y(y0);
  box.mutable_min()->set_z(z0);
  box.mutable_max()->set_x(x1);
  box.mutable_max()->set_y(y1);
  box.mutable_max()->set_z(z1);
  return box;
}

// Rendered once for the whole suite: keyframes of room-easy with their ground-truth poses.
struct Data {
  camera::StereoCalibration calibration;
  struct Frame {
    int64_t t_ns = 0;
    cv::Mat left, right;
    geometry::SE3 T_world_body;
  };
  std::vector<Frame> frames;
};

const Data& TestData() {
  static const Data* data = [] {
    auto* d = new Data;
    sim::ScenarioOptions options;
    options.preset = "room-easy";
    options.frames = 120;
    options.rectified = true;
    Result<sim::Scenario> scenario = sim::Scenario::Create(options);
    MAV_CHECK(scenario.ok()) << scenario.status().ToString();
    d->calibration = scenario->calibration();
    for (int64_t k = 0; k < 120; k += 12) {
      Data::Frame f;
      f.t_ns = scenario->FrameTimeNs(k);
      scenario->RenderStereo(k, &f.left, &f.right);
      f.T_world_body = scenario->StateAt(f.t_ns).T_world_body;
      d->frames.push_back(std::move(f));
    }
    return d;
  }();
  return *data;
}

class MappingContractTest : public ::testing::Test {
 protected:
  void SetUp() override {
    mapper_ = std::make_unique<Mapper>();
    MappingServiceOptions options;
    options.max_voxels = 20'000'000;
    service_ = std::make_unique<MappingService>(mapper_.get(), nullptr, options);
    server_ = StartOnFreePort<v1::Mapping>(service_.get());
    ASSERT_NE(server_, nullptr);
    stub_ = v1::Mapping::NewStub(server_->InProcessChannel());
  }
  void TearDown() override {
    server_->Shutdown();
    mapper_->Shutdown();
  }

  v1::StartSessionRequest SessionRequest() const {
    const Data& data = TestData();
    v1::StartSessionRequest request;
    v1::StereoCalibration* c = request.mutable_calibration()->mutable_calibration();
    SetCamera(data.calibration.cam0, data.calibration.T_body_cam0, c->mutable_left());
    SetCamera(data.calibration.cam1, data.calibration.T_body_cam1, c->mutable_right());
    c->set_rectified(true);
    request.set_pose_source(v1::POSE_SOURCE_NONE);
    return request;
  }

  grpc::Status StartSession(const v1::StartSessionRequest& request,
                            v1::MappingStatus* status = nullptr) {
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    v1::MappingStatus ignored;
    return stub_->StartSession(&context, request, status != nullptr ? status : &ignored);
  }

  v1::InsertKeyframeRequest KeyframeRequest(size_t i, bool force) const {
    const Data::Frame& f = TestData().frames.at(i);
    v1::InsertKeyframeRequest request;
    request.mutable_stereo()->set_t_ns(f.t_ns);
    SetImage(f.left, request.mutable_stereo()->mutable_left());
    SetImage(f.right, request.mutable_stereo()->mutable_right());
    request.mutable_stereo()->set_rectified(true);
    SetPose(f.T_world_body, request.mutable_t_world_body());
    request.set_force(force);
    return request;
  }

  grpc::Status Insert(const v1::InsertKeyframeRequest& request,
                      v1::InsertKeyframeResponse* response = nullptr) {
    grpc::ClientContext context;
    context.set_deadline(Deadline(20));
    v1::InsertKeyframeResponse ignored;
    return stub_->InsertKeyframe(&context, request, response != nullptr ? response : &ignored);
  }

  grpc::Status Build(const v1::BuildMapRequest& request, v1::BuildMapResponse* response = nullptr,
                     double deadline_s = 60) {
    grpc::ClientContext context;
    context.set_deadline(Deadline(deadline_s));
    v1::BuildMapResponse ignored;
    return stub_->BuildMap(&context, request, response != nullptr ? response : &ignored);
  }

  grpc::Status Query(const v1::QueryCollisionRequest& request,
                     v1::QueryCollisionResponse* response = nullptr) {
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    v1::QueryCollisionResponse ignored;
    return stub_->QueryCollision(&context, request, response != nullptr ? response : &ignored);
  }

  // Downloads the occupancy map; returns the status and fills the bytes and chunk count.
  grpc::Status Occupancy(const v1::GetOccupancyRequest& request, std::string* bytes,
                         int* chunks = nullptr, v1::OccupancyChunk* first = nullptr) {
    grpc::ClientContext context;
    context.set_deadline(Deadline(30));
    auto reader = stub_->GetOccupancy(&context, request);
    v1::OccupancyChunk chunk;
    int n = 0;
    bytes->clear();
    while (reader->Read(&chunk)) {
      EXPECT_EQ(chunk.chunk().offset(), bytes->size());
      if (n == 0 && first != nullptr) *first = chunk;
      bytes->append(chunk.chunk().data());
      ++n;
      if (chunk.chunk().last()) {
        EXPECT_EQ(bytes->size(), chunk.chunk().total_size());
      }
    }
    if (chunks != nullptr) *chunks = n;
    return reader->Finish();
  }

  grpc::Status Mesh(const v1::ExportMeshRequest& request, std::string* bytes) {
    grpc::ClientContext context;
    context.set_deadline(Deadline(30));
    auto reader = stub_->ExportMesh(&context, request);
    v1::FileChunk chunk;
    bytes->clear();
    while (reader->Read(&chunk)) {
      EXPECT_EQ(chunk.offset(), bytes->size());
      bytes->append(chunk.data());
    }
    return reader->Finish();
  }

  // Starts a session and inserts every rendered frame as a forced keyframe.
  void InsertAll() {
    ASSERT_TRUE(StartSession(SessionRequest()).ok());
    for (size_t i = 0; i < TestData().frames.size(); ++i) {
      v1::InsertKeyframeResponse response;
      const grpc::Status status = Insert(KeyframeRequest(i, true), &response);
      ASSERT_TRUE(status.ok()) << status.error_message();
      ASSERT_TRUE(response.accepted());
      EXPECT_EQ(response.keyframe_index(), i);
    }
  }

  std::unique_ptr<Mapper> mapper_;
  std::unique_ptr<MappingService> service_;
  std::unique_ptr<transport::GrpcServer> server_;
  std::unique_ptr<v1::Mapping::Stub> stub_;
};

#define EXPECT_CODE(expr, code, text)                                          \
  do {                                                                         \
    const grpc::Status s_ = (expr);                                            \
    EXPECT_EQ(s_.error_code(), code) << s_.error_message();                    \
    EXPECT_NE(s_.error_message().find(text), std::string::npos)                \
        << "message '" << s_.error_message() << "' does not contain " << text; \
  } while (false)

TEST_F(MappingContractTest, GetStatusAlwaysSucceeds) {
  grpc::ClientContext context;
  context.set_deadline(Deadline(2));
  v1::MappingStatus status;
  ASSERT_TRUE(stub_->GetStatus(&context, v1::MappingGetStatusRequest(), &status).ok());
  EXPECT_FALSE(status.session_active());
  EXPECT_EQ(status.keyframes(), 0u);
  EXPECT_EQ(status.maps_size(), 0);
}

TEST_F(MappingContractTest, EverythingButStartSessionNeedsASession) {
  {
    grpc::ClientContext context;
    v1::MappingStatus status;
    EXPECT_CODE(stub_->Reset(&context, v1::MappingResetRequest(), &status),
                StatusCode::FAILED_PRECONDITION, "StartSession");
  }
  EXPECT_CODE(Insert(KeyframeRequest(0, true)), StatusCode::FAILED_PRECONDITION, "StartSession");
  v1::BuildMapRequest build;
  build.set_method(v1::MAPPING_METHOD_SPARSE_MESH);
  EXPECT_CODE(Build(build), StatusCode::FAILED_PRECONDITION, "StartSession");
}

TEST_F(MappingContractTest, StartSessionValidatesNamingTheField) {
  v1::StartSessionRequest request = SessionRequest();
  request.clear_calibration();
  EXPECT_CODE(StartSession(request), StatusCode::INVALID_ARGUMENT, "calibration: not set");

  request = SessionRequest();
  request.mutable_keyframes()->set_min_translation_m(-1);
  EXPECT_CODE(StartSession(request), StatusCode::INVALID_ARGUMENT, "keyframes.min_translation_m");

  request = SessionRequest();
  request.mutable_keyframes()->set_min_rotation_deg(kNaN);
  EXPECT_CODE(StartSession(request), StatusCode::INVALID_ARGUMENT, "keyframes.min_rotation_deg");

  request = SessionRequest();
  request.mutable_keyframes()->set_features_per_keyframe(10001);
  EXPECT_CODE(StartSession(request), StatusCode::INVALID_ARGUMENT,
              "keyframes.features_per_keyframe");

  request = SessionRequest();
  request.mutable_calibration()
      ->mutable_calibration()
      ->mutable_left()
      ->mutable_intrinsics()
      ->set_fx(0);
  EXPECT_CODE(StartSession(request), StatusCode::INVALID_ARGUMENT,
              "calibration.calibration.left.intrinsics.fx");

  request = SessionRequest();
  request.mutable_calibration()
      ->mutable_calibration()
      ->mutable_right()
      ->mutable_t_body_cam()
      ->mutable_orientation()
      ->set_w(3);
  EXPECT_CODE(StartSession(request), StatusCode::INVALID_ARGUMENT,
              "calibration.calibration.right.t_body_cam.orientation");

  request = SessionRequest();
  request.set_pose_source(static_cast<v1::PoseSource>(42));
  EXPECT_CODE(StartSession(request), StatusCode::INVALID_ARGUMENT, "pose_source");

  request = SessionRequest();
  request.mutable_calibration()->set_euroc_directory("/nonexistent/mav-mapping-test");
  EXPECT_CODE(StartSession(request), StatusCode::NOT_FOUND, "calibration.euroc_directory");

  request = SessionRequest();
  request.mutable_calibration()->set_simulator_address("127.0.0.1:1");
  EXPECT_CODE(StartSession(request), StatusCode::UNAVAILABLE, "calibration.simulator_address");

  v1::MappingStatus status;
  ASSERT_TRUE(StartSession(SessionRequest(), &status).ok());
  EXPECT_TRUE(status.session_active());
  EXPECT_EQ(status.pose_source(), v1::POSE_SOURCE_NONE);
}

TEST_F(MappingContractTest, AnEmptyMapCannotBeBuiltNorQueried) {
  ASSERT_TRUE(StartSession(SessionRequest()).ok());
  v1::BuildMapRequest build;
  build.set_method(v1::MAPPING_METHOD_SPARSE_MESH);
  EXPECT_CODE(Build(build), StatusCode::FAILED_PRECONDITION, "empty map");
  build.set_method(v1::MAPPING_METHOD_OCTOMAP);
  EXPECT_CODE(Build(build), StatusCode::FAILED_PRECONDITION, "empty map");

  v1::QueryCollisionRequest query;
  *query.add_boxes() = MakeBox(0, 0, 0, 1, 1, 1);
  EXPECT_CODE(Query(query), StatusCode::NOT_FOUND, "BuildMap");
  std::string bytes;
  EXPECT_CODE(Occupancy(v1::GetOccupancyRequest(), &bytes), StatusCode::NOT_FOUND, "BuildMap");
  EXPECT_CODE(Mesh(v1::ExportMeshRequest(), &bytes), StatusCode::NOT_FOUND, "sparse-mesh");
}

TEST_F(MappingContractTest, InsertKeyframeValidatesImagesAndPose) {
  ASSERT_TRUE(StartSession(SessionRequest()).ok());
  v1::InsertKeyframeRequest request = KeyframeRequest(0, true);
  request.clear_stereo();
  EXPECT_CODE(Insert(request), StatusCode::INVALID_ARGUMENT, "stereo: not set");

  // A consistent image of the wrong size for the calibration.
  request = KeyframeRequest(0, true);
  const cv::Mat small(240, 376, CV_8UC1, cv::Scalar(7));
  SetImage(small, request.mutable_stereo()->mutable_left());
  SetImage(small, request.mutable_stereo()->mutable_right());
  EXPECT_CODE(Insert(request), StatusCode::INVALID_ARGUMENT,
              "stereo.left: 376x240 differs from the calibration's 752x480");

  request = KeyframeRequest(0, true);
  request.mutable_stereo()->mutable_left()->mutable_data()->resize(1000);
  EXPECT_CODE(Insert(request), StatusCode::INVALID_ARGUMENT,
              "stereo.left.data: 1000 bytes, expected width*height = 360960");

  request = KeyframeRequest(0, true);
  request.mutable_stereo()->mutable_right()->set_encoding(v1::IMAGE_ENCODING_UNSPECIFIED);
  EXPECT_CODE(Insert(request), StatusCode::INVALID_ARGUMENT, "stereo.right.encoding");

  request = KeyframeRequest(0, true);
  request.mutable_t_world_body()->mutable_orientation()->set_w(0.5);
  EXPECT_CODE(Insert(request), StatusCode::INVALID_ARGUMENT, "t_world_body.orientation");

  request = KeyframeRequest(0, true);
  request.mutable_t_world_body()->mutable_position()->set_y(kNaN);
  EXPECT_CODE(Insert(request), StatusCode::INVALID_ARGUMENT, "t_world_body.position: not finite");

  request = KeyframeRequest(0, true);
  request.clear_t_world_body();
  EXPECT_CODE(Insert(request), StatusCode::INVALID_ARGUMENT, "t_world_body: not set");

  grpc::ClientContext context;
  v1::MappingStatus status;
  ASSERT_TRUE(stub_->GetStatus(&context, v1::MappingGetStatusRequest(), &status).ok());
  EXPECT_EQ(status.keyframes(), 0u) << "rejected frames must not reach the map";
}

TEST_F(MappingContractTest, TheKeyframeRuleSkipsFramesThatDidNotMoveAndTheLimitHolds) {
  v1::StartSessionRequest session = SessionRequest();
  session.mutable_keyframes()->set_max_keyframes(2);
  ASSERT_TRUE(StartSession(session).ok());
  v1::InsertKeyframeResponse response;
  ASSERT_TRUE(Insert(KeyframeRequest(0, false), &response).ok());
  EXPECT_TRUE(response.accepted());
  EXPECT_EQ(response.keyframe_index(), 0u);
  EXPECT_GT(response.features(), 20u);
  EXPECT_EQ(response.points_total(), response.features());
  EXPECT_GT(response.processing_ms(), 0.0);

  // Same pose again (1 and 2 ns later): not a keyframe; forced: a keyframe.
  v1::InsertKeyframeRequest same = KeyframeRequest(0, false);
  same.mutable_stereo()->set_t_ns(same.stereo().t_ns() + 1);
  ASSERT_TRUE(Insert(same, &response).ok());
  EXPECT_FALSE(response.accepted());
  same.mutable_stereo()->set_t_ns(same.stereo().t_ns() + 1);
  same.set_force(true);
  ASSERT_TRUE(Insert(same, &response).ok());
  EXPECT_TRUE(response.accepted());
  EXPECT_EQ(response.keyframe_index(), 1u);
  // A time stamp that is not after the previous frame's is refused, as ProcessStereoPair does.
  EXPECT_CODE(Insert(KeyframeRequest(0, true)), StatusCode::INVALID_ARGUMENT, "stereo.t_ns: ");

  EXPECT_CODE(Insert(KeyframeRequest(1, true)), StatusCode::RESOURCE_EXHAUSTED, "max_keyframes");

  grpc::ClientContext context;
  v1::MappingStatus status;
  ASSERT_TRUE(stub_->GetStatus(&context, v1::MappingGetStatusRequest(), &status).ok());
  EXPECT_EQ(status.frames_seen(), 3u);
  EXPECT_EQ(status.keyframes(), 2u);
  EXPECT_EQ(status.keyframe_ms().count(), 2u);
}

TEST_F(MappingContractTest, BuildMapValidatesNamingTheField) {
  ASSERT_TRUE(StartSession(SessionRequest()).ok());
  ASSERT_TRUE(Insert(KeyframeRequest(0, true)).ok());
  v1::BuildMapRequest request;
  EXPECT_CODE(Build(request), StatusCode::INVALID_ARGUMENT, "method: not set");

  request.set_method(v1::MAPPING_METHOD_SPARSE_MESH);
  request.set_resolution_m(5);
  EXPECT_CODE(Build(request), StatusCode::INVALID_ARGUMENT, "resolution_m");

  request.set_resolution_m(0);
  *request.mutable_bounds() = MakeBox(0, 0, 3, 1, 1, 1);
  EXPECT_CODE(Build(request), StatusCode::INVALID_ARGUMENT, "bounds: min.z 3 > max.z 1");
  *request.mutable_bounds() = MakeBox(0, kNaN, 0, 1, 1, 1);
  EXPECT_CODE(Build(request), StatusCode::INVALID_ARGUMENT, "bounds.min.y: not finite");

  request.clear_bounds();
  request.mutable_sparse_mesh()->set_min_visibility(1000);
  EXPECT_CODE(Build(request), StatusCode::INVALID_ARGUMENT, "sparse_mesh.min_visibility");
  request.clear_sparse_mesh();
  request.mutable_sparse_mesh()->set_free_space_weight(-1);
  EXPECT_CODE(Build(request), StatusCode::INVALID_ARGUMENT, "sparse_mesh.free_space_weight");
  request.clear_sparse_mesh();
  request.mutable_octomap()->set_num_disparities(50);
  EXPECT_CODE(Build(request), StatusCode::INVALID_ARGUMENT, "octomap.num_disparities");
  request.clear_octomap();
  request.mutable_octomap()->set_prob_hit(0.3);
  EXPECT_CODE(Build(request), StatusCode::INVALID_ARGUMENT, "octomap.prob_hit");
  request.clear_octomap();
  request.set_prefer(static_cast<v1::MapPreference>(9));
  EXPECT_CODE(Build(request), StatusCode::INVALID_ARGUMENT, "prefer: unknown value 9");
  request.set_prefer(v1::MAP_PREFERENCE_MCC);

  // Above the server's voxel limit (20 M in this fixture): 1 km^3 at 5 cm.
  *request.mutable_bounds() = MakeBox(-500, -500, -500, 500, 500, 500);
  EXPECT_CODE(Build(request), StatusCode::RESOURCE_EXHAUSTED, "voxels");
}

TEST_F(MappingContractTest, BuildQueryDownloadAndReset) {
  ASSERT_NO_FATAL_FAILURE(InsertAll());
  const size_t keyframes = TestData().frames.size();

  v1::BuildMapRequest build;
  build.set_method(v1::MAPPING_METHOD_SPARSE_MESH);
  v1::BuildMapResponse mesh_stats;
  grpc::Status status = Build(build, &mesh_stats);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(mesh_stats.method(), v1::MAPPING_METHOD_SPARSE_MESH);
  EXPECT_EQ(mesh_stats.keyframes(), keyframes);
  EXPECT_GT(mesh_stats.points(), 200u);
  EXPECT_GT(mesh_stats.tetrahedra(), mesh_stats.points());
  EXPECT_GT(mesh_stats.mesh_faces(), 100u);
  EXPECT_GT(mesh_stats.occupancy().occupied_voxels(), 1000u);
  EXPECT_GT(mesh_stats.occupancy().free_voxels(), 1000u);
  EXPECT_DOUBLE_EQ(mesh_stats.occupancy().resolution_m(), 0.05);
  EXPECT_GT(mesh_stats.timing().delaunay_ms(), 0.0);
  EXPECT_GT(mesh_stats.timing().total_ms(), mesh_stats.timing().features_ms());

  build.set_method(v1::MAPPING_METHOD_OCTOMAP);
  build.set_resolution_m(0.1);
  build.set_unknown(v1::UNKNOWN_HANDLING_AS_OCCUPIED);
  v1::BuildMapResponse octo_stats;
  status = Build(build, &octo_stats);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(octo_stats.method(), v1::MAPPING_METHOD_OCTOMAP);
  EXPECT_GT(octo_stats.points(), 10000u);
  EXPECT_GT(octo_stats.timing().dense_stereo_ms(), 0.0);
  EXPECT_EQ(octo_stats.occupancy().unknown_voxels(), 0u) << "AS_OCCUPIED leaves no unknown";
  EXPECT_DOUBLE_EQ(octo_stats.occupancy().resolution_m(), 0.1);

  {
    grpc::ClientContext context;
    v1::MappingStatus s;
    ASSERT_TRUE(stub_->GetStatus(&context, v1::MappingGetStatusRequest(), &s).ok());
    ASSERT_EQ(s.maps_size(), 2);
    EXPECT_EQ(s.maps(0).method(), v1::MAPPING_METHOD_SPARSE_MESH);
    EXPECT_EQ(s.maps(1).method(), v1::MAPPING_METHOD_OCTOMAP);
    EXPECT_FALSE(s.building());
  }

  // Occupancy of the sparse mesh in 4 KiB chunks: a valid OctoMap with occupied leaves.
  v1::GetOccupancyRequest occupancy;
  occupancy.set_method(v1::MAPPING_METHOD_SPARSE_MESH);
  occupancy.set_chunk_size(4096);
  std::string bytes;
  int chunks = 0;
  v1::OccupancyChunk first;
  status = Occupancy(occupancy, &bytes, &chunks, &first);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_GT(chunks, 1);
  EXPECT_EQ(first.format(), v1::OCCUPANCY_FORMAT_OCTOMAP_BT);
  EXPECT_DOUBLE_EQ(first.resolution_m(), 0.05);
  EXPECT_LT(first.bounds().min().x(), first.bounds().max().x());
  {
    std::istringstream in(bytes);
    octomap::OcTree tree(0.1);
    ASSERT_TRUE(tree.readBinary(in));
    EXPECT_NEAR(tree.getResolution(), 0.05, 1e-9);
    int64_t occupied = 0;
    for (auto it = tree.begin_leafs(); it != tree.end_leafs(); ++it) {
      occupied += tree.isNodeOccupied(*it) ? 1 : 0;
    }
    EXPECT_GT(occupied, 100);
  }
  // The lossless format of the most recent build (octomap at 10 cm): parses, no unknown.
  occupancy.set_method(v1::MAPPING_METHOD_UNSPECIFIED);
  occupancy.set_format(v1::OCCUPANCY_FORMAT_MAVOCC);
  occupancy.set_chunk_size(0);
  status = Occupancy(occupancy, &bytes);
  ASSERT_TRUE(status.ok()) << status.error_message();
  {
    const std::string path = ::testing::TempDir() + "/mapping_contract.mavocc";
    ASSERT_TRUE(WriteStringToFileAtomic(path, bytes).ok());
    Result<dataset::OccupancyGrid> grid = dataset::ReadMavocc(path);
    ASSERT_TRUE(grid.ok()) << grid.status().ToString();
    EXPECT_DOUBLE_EQ(grid->resolution(), 0.1);
    EXPECT_EQ(grid->Count(dataset::VoxelState::kUnknown), 0);
    EXPECT_EQ(static_cast<uint64_t>(grid->Count(dataset::VoxelState::kOccupied)),
              octo_stats.occupancy().occupied_voxels());
  }
  occupancy.set_chunk_size(100);
  EXPECT_CODE(Occupancy(occupancy, &bytes), StatusCode::INVALID_ARGUMENT, "chunk_size");
  occupancy.set_chunk_size(0);
  occupancy.set_format(static_cast<v1::OccupancyFormat>(9));
  EXPECT_CODE(Occupancy(occupancy, &bytes), StatusCode::INVALID_ARGUMENT, "format");

  // Collision queries: half a metre in front of a keyframe's camera is observed free space; a
  // box far outside the map is unknown (a collision under the paper's convention); malformed
  // boxes name the field.
  const geometry::SE3 T_world_cam =
      TestData().frames[3].T_world_body * TestData().calibration.T_body_cam0;
  const Eigen::Vector3d c = T_world_cam * Eigen::Vector3d(0, 0, 0.5);
  v1::QueryCollisionRequest query;
  query.set_method(v1::MAPPING_METHOD_SPARSE_MESH);
  *query.add_boxes() =
      MakeBox(c.x() - 0.05, c.y() - 0.05, c.z() - 0.05, c.x() + 0.05, c.y() + 0.05, c.z() + 0.05);
  *query.add_boxes() = MakeBox(500, 500, 500, 501, 501, 501);
  v1::QueryCollisionResponse answer;
  status = Query(query, &answer);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(answer.states_size(), 2);
  EXPECT_EQ(answer.states(0), v1::COLLISION_STATE_FREE);
  EXPECT_EQ(answer.states(1), v1::COLLISION_STATE_UNKNOWN);
  EXPECT_EQ(answer.free(), 1u);
  EXPECT_EQ(answer.unknown(), 1u);
  query.set_unknown_is_collision(true);
  ASSERT_TRUE(Query(query, &answer).ok());
  EXPECT_EQ(answer.states(1), v1::COLLISION_STATE_COLLISION);
  EXPECT_EQ(answer.collisions(), 1u);

  *query.add_boxes() = MakeBox(kNaN, 0, 0, 1, 1, 1);
  EXPECT_CODE(Query(query), StatusCode::INVALID_ARGUMENT, "boxes[2].min.x: not finite");
  query.clear_boxes();
  *query.add_boxes() = MakeBox(0, 0, 3, 1, 1, 1);
  EXPECT_CODE(Query(query), StatusCode::INVALID_ARGUMENT, "boxes[0]: min.z 3 > max.z 1");
  query.clear_boxes();
  EXPECT_CODE(Query(query), StatusCode::INVALID_ARGUMENT, "boxes: no boxes");
  // Empty Box messages keep the request small (2 bytes each): the count is checked first.
  for (int i = 0; i < 50001; ++i) query.add_boxes();
  EXPECT_CODE(Query(query), StatusCode::INVALID_ARGUMENT, "at most 50000 per call");

  // The mesh as PLY (binary and ASCII), with the faces BuildMap reported.
  v1::ExportMeshRequest mesh;
  mesh.set_chunk_size(4096);
  status = Mesh(mesh, &bytes);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(bytes.rfind("ply", 0), 0u);
  Result<mapping::TriangleMesh> decoded = mapping::DecodePly(bytes, "ExportMesh");
  ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
  EXPECT_EQ(decoded->triangles.size(), mesh_stats.mesh_faces());
  mesh.set_format(v1::MESH_FORMAT_PLY_ASCII);
  ASSERT_TRUE(Mesh(mesh, &bytes).ok());
  EXPECT_NE(bytes.find("format ascii 1.0"), std::string::npos);
  mesh.set_chunk_size(5 << 20);
  EXPECT_CODE(Mesh(mesh, &bytes), StatusCode::INVALID_ARGUMENT, "chunk_size");

  // Reset forgets keyframes and maps, keeps the session.
  {
    grpc::ClientContext context;
    v1::MappingStatus s;
    ASSERT_TRUE(stub_->Reset(&context, v1::MappingResetRequest(), &s).ok());
    EXPECT_TRUE(s.session_active());
    EXPECT_EQ(s.keyframes(), 0u);
    EXPECT_EQ(s.maps_size(), 0);
  }
  query.clear_boxes();
  *query.add_boxes() = MakeBox(0, 0, 0, 1, 1, 1);
  EXPECT_CODE(Query(query), StatusCode::NOT_FOUND, "BuildMap");
  build.set_method(v1::MAPPING_METHOD_SPARSE_MESH);
  EXPECT_CODE(Build(build), StatusCode::FAILED_PRECONDITION, "empty map");
}

TEST_F(MappingContractTest, ABuildOutlivingItsDeadlineIsDeadlineExceeded) {
  ASSERT_TRUE(StartSession(SessionRequest()).ok());
  for (size_t i = 0; i < 3; ++i) ASSERT_TRUE(Insert(KeyframeRequest(i, true)).ok());
  v1::BuildMapRequest build;
  build.set_method(v1::MAPPING_METHOD_OCTOMAP);
  EXPECT_EQ(Build(build, nullptr, 0.001).error_code(), StatusCode::DEADLINE_EXCEEDED);
  // The abandoned build leaves no map, and the service builds again afterwards.
  for (int i = 0; i < 200; ++i) {
    grpc::ClientContext context;
    v1::MappingStatus s;
    ASSERT_TRUE(stub_->GetStatus(&context, v1::MappingGetStatusRequest(), &s).ok());
    if (!s.building()) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  const grpc::Status again = Build(build);
  EXPECT_TRUE(again.ok()) << again.error_message();
}

TEST_F(MappingContractTest, LoopbackPortAnswersHealthAndRpcs) {
  const std::string target = "127.0.0.1:" + std::to_string(server_->port());
  auto channel = grpc::CreateChannel(target, grpc::InsecureChannelCredentials());
  auto health = transport::CheckHealth(channel, "mav.v1.Mapping", std::chrono::seconds(2));
  ASSERT_TRUE(health.ok()) << health.status().ToString();
  EXPECT_EQ(*health, transport::HealthStatus::kServing);
  auto stub = v1::Mapping::NewStub(channel);
  grpc::ClientContext context;
  context.set_deadline(Deadline(2));
  v1::MappingStatus status;
  ASSERT_TRUE(stub->StartSession(&context, SessionRequest(), &status).ok());
  EXPECT_TRUE(status.session_active());
  grpc::ClientContext insert_context;
  insert_context.set_deadline(Deadline(20));
  v1::InsertKeyframeResponse response;
  const grpc::Status inserted =
      stub->InsertKeyframe(&insert_context, KeyframeRequest(0, true), &response);
  ASSERT_TRUE(inserted.ok()) << inserted.error_message();
  EXPECT_TRUE(response.accepted());
}

// ---- The gRPC-free pieces
// ------------------------------------------------------------------------

FrameInput Frame(int64_t t_ns) {
  FrameInput f;
  f.t_ns = t_ns;
  f.left = cv::Mat(4, 4, CV_8UC1, cv::Scalar(1));
  f.right = f.left.clone();
  return f;
}

// BuildMap runs the library's pipeline: the service's grid is the one mav-eval's code path
// (MappingPipeline::Finish) computes from the same keyframes, voxel for voxel, for both methods.
TEST_F(MappingContractTest, BuildMapGridEqualsThePipelineGridOfTheSameKeyframes) {
  ASSERT_TRUE(StartSession(SessionRequest()).ok());
  const Data& data = TestData();
  for (size_t i = 0; i < data.frames.size(); ++i) {
    ASSERT_TRUE(Insert(KeyframeRequest(i, true)).ok());
  }
  Result<camera::RigRectification> rig = camera::RigRectification::Create(data.calibration, true);
  ASSERT_TRUE(rig.ok());
  Result<mapping::MappingPipeline> pipeline = mapping::MappingPipeline::Create(rig->rig);
  ASSERT_TRUE(pipeline.ok()) << pipeline.status().ToString();
  for (const Data::Frame& f : data.frames) {
    ASSERT_TRUE(pipeline->InsertKeyframe(f.left, f.right, f.T_world_body * rig->T_body_rect0).ok());
  }
  const v1::Box bounds = MakeBox(-4.2, -4.2, -0.2, 4.2, 4.2, 3.2);
  const mapping::GridGeometry geometry =
      mapping::GridGeometry::Covering({-4.2, -4.2, -0.2}, {4.2, 4.2, 3.2}, 0.1);
  Result<mapping::MappingOutput> expected = pipeline->Finish(geometry);
  ASSERT_TRUE(expected.ok()) << expected.status().ToString();

  for (const v1::MappingMethod method :
       {v1::MAPPING_METHOD_SPARSE_MESH, v1::MAPPING_METHOD_OCTOMAP}) {
    v1::BuildMapRequest build;
    build.set_method(method);
    build.set_resolution_m(0.1);
    *build.mutable_bounds() = bounds;
    const grpc::Status built = Build(build);
    ASSERT_TRUE(built.ok()) << built.error_message();
    v1::GetOccupancyRequest occupancy;
    occupancy.set_method(method);
    occupancy.set_format(v1::OCCUPANCY_FORMAT_MAVOCC);
    std::string bytes;
    ASSERT_TRUE(Occupancy(occupancy, &bytes).ok());
    Result<dataset::OccupancyGrid> served = dataset::DecodeMavocc(bytes, "GetOccupancy");
    ASSERT_TRUE(served.ok()) << served.status().ToString();
    const dataset::OccupancyGrid& truth = method == v1::MAPPING_METHOD_SPARSE_MESH
                                              ? expected->sparse_mesh_grid
                                              : expected->octomap_grid;
    EXPECT_TRUE(served->geometry().SameAs(truth.geometry()));
    EXPECT_EQ(served->Count(dataset::VoxelState::kOccupied),
              truth.Count(dataset::VoxelState::kOccupied));
    EXPECT_GT(truth.Count(dataset::VoxelState::kOccupied), 100);
    EXPECT_TRUE(served->states() == truth.states()) << v1::MappingMethod_Name(method);
  }
}

// A flight's online map: only the sparse mesher runs (no OctoMap per keyframe), points up to
// max_depth_m, and surfaces_only keeps the mesh's surfaces without the graph cut's inside: fewer
// occupied voxels than the full grid, none where the full grid is free.
TEST_F(MappingContractTest, ASparseOnlySessionBuildsSurfaceOnlyMaps) {
  v1::StartSessionRequest session = SessionRequest();
  session.mutable_keyframes()->set_max_depth_m(0.1);
  EXPECT_CODE(StartSession(session), StatusCode::INVALID_ARGUMENT, "keyframes.max_depth_m");
  session.mutable_keyframes()->set_max_depth_m(8);
  session.set_sparse_mesh_only(true);
  ASSERT_TRUE(StartSession(session).ok());
  const Data& data = TestData();
  for (size_t i = 0; i < data.frames.size(); ++i) {
    ASSERT_TRUE(Insert(KeyframeRequest(i, true)).ok());
  }
  v1::BuildMapRequest build;
  build.set_method(v1::MAPPING_METHOD_OCTOMAP);
  build.set_resolution_m(0.1);
  *build.mutable_bounds() = MakeBox(-4.2, -4.2, -0.2, 4.2, 4.2, 3.2);
  EXPECT_CODE(Build(build), StatusCode::FAILED_PRECONDITION, "");
  auto occupied = [&](bool surfaces_only, dataset::OccupancyGrid* grid) {
    v1::BuildMapRequest b = build;
    b.set_method(v1::MAPPING_METHOD_SPARSE_MESH);
    b.set_surfaces_only(surfaces_only);
    ASSERT_TRUE(Build(b).ok());
    v1::GetOccupancyRequest occupancy;
    occupancy.set_format(v1::OCCUPANCY_FORMAT_MAVOCC);
    std::string bytes;
    ASSERT_TRUE(Occupancy(occupancy, &bytes).ok());
    Result<dataset::OccupancyGrid> served = dataset::DecodeMavocc(bytes, "GetOccupancy");
    ASSERT_TRUE(served.ok()) << served.status().ToString();
    *grid = *std::move(served);
  };
  dataset::OccupancyGrid full, surfaces;
  occupied(false, &full);
  occupied(true, &surfaces);
  ASSERT_TRUE(full.geometry().SameAs(surfaces.geometry()));
  const int64_t n_full = full.Count(dataset::VoxelState::kOccupied);
  const int64_t n_surfaces = surfaces.Count(dataset::VoxelState::kOccupied);
  EXPECT_GT(n_surfaces, 100);
  EXPECT_LT(n_surfaces, n_full) << "the inside cells are not occupied";
  EXPECT_GT(surfaces.Count(dataset::VoxelState::kUnknown),
            full.Count(dataset::VoxelState::kUnknown));
}

// The documented box limit fits the transport: 50 000 full boxes through a real port (~3 MB,
// under gRPC's 4 MiB), each answered.
TEST_F(MappingContractTest, FiftyThousandBoxesFitOneCallOverARealPort) {
  ASSERT_TRUE(StartSession(SessionRequest()).ok());
  for (size_t i = 0; i < 4; ++i) ASSERT_TRUE(Insert(KeyframeRequest(i, true)).ok());
  v1::BuildMapRequest build;
  build.set_method(v1::MAPPING_METHOD_SPARSE_MESH);
  build.set_resolution_m(0.1);
  ASSERT_TRUE(Build(build).ok());
  v1::QueryCollisionRequest query;
  for (int i = 0; i < 50000; ++i) {
    const int column = i % 100, row = i / 100 % 100, layer = i / 10000;  // five layers
    const double x = -3.0 + 6.0 * column / 100.0, y = -3.0 + 6.0 * row / 100.0;
    const double z = 1.0 + 0.25 * layer;
    *query.add_boxes() = MakeBox(x, y, z, x + 0.31, y + 0.29, z + 0.2);
  }
  auto stub = v1::Mapping::NewStub(
      grpc::CreateChannel(server_->target(), grpc::InsecureChannelCredentials()));
  grpc::ClientContext context;
  context.set_deadline(Deadline(30));
  v1::QueryCollisionResponse response;
  const grpc::Status rpc = stub->QueryCollision(&context, query, &response);
  ASSERT_TRUE(rpc.ok()) << rpc.error_message();
  EXPECT_EQ(response.states_size(), 50000);
  EXPECT_EQ(response.collisions() + response.free() + response.unknown(), 50000u);
}

// BuildMap bounds: a huge box is refused before anything is allocated and the message starts
// with the field; OctoMap's addressable volume (+-1638.4 m at 5 cm) is checked by name.
TEST_F(MappingContractTest, BuildMapBoundsAreCheckedNamingTheField) {
  ASSERT_TRUE(StartSession(SessionRequest()).ok());
  for (size_t i = 0; i < 3; ++i) ASSERT_TRUE(Insert(KeyframeRequest(i, true)).ok());
  v1::BuildMapRequest build;
  build.set_method(v1::MAPPING_METHOD_SPARSE_MESH);
  *build.mutable_bounds() = MakeBox(-1e15, -1e15, -1e15, 1e15, 1e15, 1e15);
  grpc::Status rpc = Build(build);
  EXPECT_EQ(rpc.error_code(), StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_EQ(rpc.error_message().rfind("bounds: the grid would have", 0), 0u) << rpc.error_message();
  build.set_method(v1::MAPPING_METHOD_OCTOMAP);
  for (const v1::Box& box :
       {MakeBox(2000, 2000, 0, 2001, 2001, 1), MakeBox(-1e15, -1e15, -1e15, 1e15, 1e15, 1e15)}) {
    *build.mutable_bounds() = box;
    rpc = Build(build);
    EXPECT_EQ(rpc.error_code(), StatusCode::INVALID_ARGUMENT);
    EXPECT_EQ(rpc.error_message().rfind(
                  "bounds: outside the OctoMap baseline's addressable volume, +-1638.4 m", 0),
              0u)
        << rpc.error_message();
  }
}

// An InsertKeyframe whose deadline passes while it waits changes nothing: not integrated, not
// counted, and the same frame may be sent again.
TEST_F(MappingContractTest, AnInsertPastItsDeadlineChangesNothing) {
  ASSERT_TRUE(StartSession(SessionRequest()).ok());
  // Another client keeps the worker busy, keyframe after keyframe (~100 ms each).
  std::thread other([this] {
    for (size_t i = 0; i < 6; ++i) EXPECT_TRUE(Insert(KeyframeRequest(i, true)).ok());
  });
  // Until the worker has integrated two of the other client's keyframes and runs the third:
  // then the late frame queues behind a keyframe that has just started (~100 ms). Waiting for
  // the count alone and then a fixed time let a loaded machine (the sanitizer pass) send the
  // late frame to an idle worker between two of the other client's keyframes, where it ran.
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (std::chrono::steady_clock::now() < give_up) {
    grpc::ClientContext poll;
    v1::MappingStatus s;
    // (No ASSERT here: the other thread must be joined.)
    if (!stub_->GetStatus(&poll, v1::MappingGetStatusRequest(), &s).ok() ||
        (s.keyframes() >= 2 && s.worker_busy())) {
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  // Later than all of the other client's frames, and it waits behind the one in progress.
  v1::InsertKeyframeRequest late = KeyframeRequest(9, true);
  grpc::ClientContext context;
  context.set_deadline(Deadline(0.02));
  v1::InsertKeyframeResponse response;
  const grpc::Status rpc = stub_->InsertKeyframe(&context, late, &response);
  other.join();
  EXPECT_EQ(rpc.error_code(), StatusCode::DEADLINE_EXCEEDED) << rpc.error_message();
  grpc::ClientContext status_context;
  v1::MappingStatus status;
  ASSERT_TRUE(stub_->GetStatus(&status_context, v1::MappingGetStatusRequest(), &status).ok());
  EXPECT_EQ(status.keyframes(), 6u);
  EXPECT_FALSE(status.worker_busy());
  EXPECT_EQ(status.queue_depth(), 0u);
  // The retry is accepted.
  ASSERT_TRUE(Insert(late, &response).ok());
  EXPECT_TRUE(response.accepted());
}

// Resident memory of this process, MiB (Linux /proc/self/statm).
double ResidentMiB() {
  std::ifstream statm("/proc/self/statm");
  long pages = 0, resident = 0;
  statm >> pages >> resident;
  return static_cast<double>(resident) * static_cast<double>(sysconf(_SC_PAGESIZE)) / (1 << 20);
}

// QueryCollision answers from the last built map while a rebuild runs on the worker: it never
// waits for the build (issue 26: "QueryCollision on the live map never waits for a rebuild").
TEST_F(MappingContractTest, QueriesDuringARebuildAreAnsweredFromTheLastMap) {
  ASSERT_NO_FATAL_FAILURE(InsertAll());
  v1::BuildMapRequest build;
  build.set_method(v1::MAPPING_METHOD_SPARSE_MESH);
  ASSERT_TRUE(Build(build).ok());
  v1::QueryCollisionRequest query;
  query.set_method(v1::MAPPING_METHOD_SPARSE_MESH);
  *query.add_boxes() = MakeBox(-0.5, -0.5, 0.5, 0.5, 0.5, 1.5);
  v1::QueryCollisionResponse before;
  ASSERT_TRUE(Query(query, &before).ok());

  std::atomic<bool> building{true};
  grpc::Status rebuilt;
  const int64_t build_start = MonotonicNowNs();
  std::thread rebuild([&] {
    rebuilt = Build(build);
    building = false;
  });
  std::vector<double> during_ms;
  while (building) {
    const int64_t start = MonotonicNowNs();
    v1::QueryCollisionResponse answer;
    const grpc::Status status = Query(query, &answer);
    const double ms = MsSince(start);
    if (!building) break;  // it may have waited for the end: not counted
    ASSERT_TRUE(status.ok()) << status.error_message();
    EXPECT_EQ(answer.states(0), before.states(0)) << "the same map answers";
    during_ms.push_back(ms);
  }
  rebuild.join();
  const double build_ms = MsSince(build_start);
  ASSERT_TRUE(rebuilt.ok()) << rebuilt.error_message();
  // A query that waited for the build would have ended with it: many were answered during it.
  ASSERT_GE(during_ms.size(), 10u) << "a rebuild of " << build_ms << " ms";
  const RuntimeStats stats = SummarizeRuntimes(during_ms);
  std::printf(
      "[ figures ] %zu queries during a %.0f ms rebuild: median %.3f ms, p99 %.3f ms, "
      "max %.3f ms\n",
      during_ms.size(), build_ms, stats.median_ms, stats.p99_ms, stats.max_ms);
  EXPECT_LT(stats.median_ms, build_ms / 4) << "queries waited for the rebuild";
}

// A keyframe that adds no points costs only its own data: the same textured pair at the same
// pose again and again (forced keyframes re-observing the same ~100 points) once grew the
// process by ~0.28 MB a keyframe: per-line heap blocks of the free-space lines of sight, and
// glibc carving the 0.7 MB stereo pairs out of its thread heaps. With the lines stored compactly
// (32 bytes each, capped by SparsePointsOptions::max_sight_lines) and large blocks mapped (as
// ServiceRunner sets up every service) a keyframe costs ~0.12 MB, its ~3600 lines of sight.
TEST_F(MappingContractTest, KeyframesWithoutNewPointsCostOnlyTheirData) {
  if (test_support::kUnderAddressSanitizer) {
    GTEST_SKIP() << "resident memory under ASan is its allocator's (tests/common/sanitizers.h)";
  }
  transport::UseMappedLargeBlocks();
  ASSERT_TRUE(StartSession(SessionRequest()).ok());
  const Data& data = TestData();
  v1::InsertKeyframeRequest request = KeyframeRequest(0, true);
  auto insert = [&](int i) {
    request.mutable_stereo()->set_t_ns(data.frames[0].t_ns + i);
    return Insert(request);
  };
  for (int i = 0; i < 10; ++i) ASSERT_TRUE(insert(i).ok());  // warm-up: allocator pools
  const double before = ResidentMiB();
  for (int i = 10; i < 70; ++i) ASSERT_TRUE(insert(i).ok());
  const double grown = ResidentMiB() - before;
  std::printf("60 keyframes without new points: +%.1f MiB resident\n", grown);
  EXPECT_LT(grown, 11.0);
  grpc::ClientContext context;
  v1::MappingStatus status;
  ASSERT_TRUE(stub_->GetStatus(&context, v1::MappingGetStatusRequest(), &status).ok());
  EXPECT_LT(status.points(), 200u) << "the repeated pair must not add points";
}

// BuildMapRequest.prefer sets every choice of the map preference (mapping::BuildOptions::For).
TEST(MappingConvertTest, ThePreferenceSetsTheBuildRequest) {
  v1::BuildMapRequest request;
  request.set_method(v1::MAPPING_METHOD_SPARSE_MESH);
  Result<BuildRequest> safety = BuildFromProto(request);  // unspecified = safety
  ASSERT_TRUE(safety.ok()) << safety.status().ToString();
  EXPECT_GT(safety->meshing.weak_surface_weight, 0.0);
  EXPECT_TRUE(safety->mesh_to_grid.occupy_surface_voxels);
  EXPECT_FALSE(safety->keep_unchecked_points);
  EXPECT_TRUE(safety->occlusion_check.enabled);
  request.set_prefer(v1::MAP_PREFERENCE_MCC);
  Result<BuildRequest> mcc = BuildFromProto(request);
  ASSERT_TRUE(mcc.ok()) << mcc.status().ToString();
  EXPECT_EQ(mcc->meshing.weak_surface_weight, 0.0);
  EXPECT_FALSE(mcc->mesh_to_grid.occupy_surface_voxels);
  EXPECT_TRUE(mcc->keep_unchecked_points);
  EXPECT_FALSE(mcc->occlusion_check.enabled);
}

TEST(MapperTest, LiveFramesWithGroundTruthBecomeKeyframes) {
  const Data& data = TestData();
  Mapper mapper;
  SessionConfig config;
  config.calibration = data.calibration;
  config.calibration_rectified = true;
  config.pose_source = PoseSource::kGroundTruth;
  ASSERT_TRUE(mapper.StartSession(config).ok());
  for (const Data::Frame& f : data.frames) {
    mapper.SubmitPose(f.t_ns - 5'000'000, f.T_world_body);
    FrameInput input{f.t_ns, f.left, f.right, true};
    mapper.SubmitLiveFrame(input);
    mapper.SubmitPose(f.t_ns + 5'000'000, f.T_world_body);
  }
  FrameInput wrong = Frame(1);  // 4x4: not the rig's size
  mapper.SubmitLiveFrame(wrong);
  // Up to 2 minutes for the worker to map the queued keyframes: the ASan build sharing 2 cores with
  // another test took over 30 s in a fresh-clone CI run. The loop ends as soon as they are done.
  for (int i = 0; i < 2400; ++i) {
    const MapperStatus s = mapper.GetStatus();
    if (s.queue_depth == 0 && s.keyframes == s.keyframes_selected) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  const MapperStatus status = mapper.GetStatus();
  EXPECT_EQ(status.frames_seen, data.frames.size() + 1);
  EXPECT_EQ(status.frames_rejected, 1u);
  EXPECT_EQ(status.frames_without_pose, 0u);
  EXPECT_GE(status.keyframes, 3u);
  EXPECT_EQ(status.keyframes, status.keyframes_selected);
  EXPECT_EQ(status.frames_dropped, 0u);
  EXPECT_GT(status.points, 200u);
  mapper.Shutdown();
}

TEST(MappingDdsTest, StereoFramesAreCheckedNamingTheField) {
  test_support::DdsStereoFrame sample(4, 3, 3, 4);
  mav_dds_StereoFrame& frame = sample.sample();
  EXPECT_TRUE(service_common::CheckStereoFrame(frame).ok());
  const FrameInput input = service_common::StereoFromDds(frame);
  EXPECT_EQ(input.left.cols, 4);
  EXPECT_EQ(input.right.at<uint8_t>(2, 3), 4);
  frame.crc32 ^= 1;
  EXPECT_NE(service_common::CheckStereoFrame(frame).message().find("crc32"), std::string::npos);
  frame.right._length = 11;
  EXPECT_NE(service_common::CheckStereoFrame(frame).message().find("right: 11 bytes"),
            std::string::npos);
}

}  // namespace
}  // namespace mav::mapping_service
