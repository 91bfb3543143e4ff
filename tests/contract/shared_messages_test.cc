// The messages several services take get one verdict (services/common/proto_codec.h): the same
// bad trajectory, vector, box or pose is refused by every service that takes it, with the same
// code and the same words after the field path the request gives it. Each service runs in process
// behind a real gRPC server (in-process channel); the DDS pose decoders of mav-control and
// mav-mapping are called directly. Also: every enum table of every service covers its enum.

#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include "mav/v1/control.grpc.pb.h"
#include "mav/v1/localization.grpc.pb.h"
#include "mav/v1/mapping.grpc.pb.h"
#include "mav/v1/planning.grpc.pb.h"

#include "mav/transport/grpc_server.h"
#include "services/common/file_stream.h"
#include "services/common/proto_codec.h"
#include "services/control/control_service.h"
#include "services/control/convert.h"
#include "services/control/dds_io.h"
#include "services/localization/convert.h"
#include "services/localization/dds_io.h"
#include "services/localization/localization_service.h"
#include "services/mapping/convert.h"
#include "services/mapping/dds_io.h"
#include "services/mapping/mapping_service.h"
#include "services/planning/convert.h"
#include "services/planning/planning_service.h"

namespace mav {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::chrono::system_clock::time_point Deadline() {
  return std::chrono::system_clock::now() + std::chrono::seconds(10);
}

// The message after the field path the caller gave (`field` + "." or ": "), so that a verdict
// reached under "trajectory" and one under "plan.trajectory" compare.
std::string AfterField(const grpc::Status& status, const std::string& field) {
  const std::string& m = status.error_message();
  EXPECT_EQ(m.rfind(field, 0), 0u) << "'" << m << "' does not start with '" << field << "'";
  return m.rfind(field, 0) == 0 ? m.substr(field.size()) : m;
}

class NullCommandSink : public control_service::CommandSink {
 public:
  Status PublishCommand(const control_service::ActuatorOutput&) override { return Status::Ok(); }
};
// The live input the services switch (DDS in production): never on here.
class NullInput : public service_common::InputControl {
 public:
  Status SetInput(bool) override { return Status::Ok(); }
  bool input_enabled() const override { return false; }
};
class NullPoseSink : public localization_service::PoseSink {
 public:
  Status PublishPose(const localization_service::RigPose&, localization::OutputFrame) override {
    return Status::Ok();
  }
};

// The four services that take shared messages, each behind its own in-process server.
class SharedMessagesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    planner_ =
        std::make_unique<planning_service::PlannerCore>(planning_service::PlannerCoreOptions{});
    planning_ = std::make_unique<planning_service::PlanningService>(
        planner_.get(), planning_service::PlanningServiceOptions{});
    control_core_ = std::make_unique<control_service::ControlCore>(&command_sink_);
    control_ = std::make_unique<control_service::ControlService>(
        control_core_.get(), &control_input_, control_service::ControlServiceOptions{});
    mapper_ = std::make_unique<mapping_service::Mapper>();
    mapping_ = std::make_unique<mapping_service::MappingService>(
        mapper_.get(), nullptr, mapping_service::MappingServiceOptions{});
    localizer_ = std::make_unique<localization_service::Localizer>(&pose_sink_);
    localization_ = std::make_unique<localization_service::LocalizationService>(
        localizer_.get(), &localization_input_);
    transport::ServerOptions options;
    options.port = 0;
    auto server = transport::GrpcServer::Start(
        options, {planning_.get(), control_.get(), mapping_.get(), localization_.get()},
        {v1::Planning::service_full_name(), v1::Control::service_full_name(),
         v1::Mapping::service_full_name(), v1::Localization::service_full_name()});
    ASSERT_TRUE(server.ok()) << server.status().ToString();
    server_ = std::move(*server);
    planning_stub_ = v1::Planning::NewStub(server_->InProcessChannel());
    control_stub_ = v1::Control::NewStub(server_->InProcessChannel());
    mapping_stub_ = v1::Mapping::NewStub(server_->InProcessChannel());
    localization_stub_ = v1::Localization::NewStub(server_->InProcessChannel());
  }
  void TearDown() override {
    if (server_) server_->Shutdown();
    if (planner_) planner_->Shutdown();
    if (localizer_) localizer_->Shutdown();
  }

  grpc::Status SampleTrajectory(const v1::PolynomialTrajectory& t) {
    v1::SampleTrajectoryRequest request;
    *request.mutable_trajectory() = t;
    request.set_dt_s(0.1);
    grpc::ClientContext context;
    context.set_deadline(Deadline());
    v1::SampleTrajectoryResponse response;
    return planning_stub_->SampleTrajectory(&context, request, &response);
  }
  grpc::Status SetTrajectory(const v1::PolynomialTrajectory& t) {
    v1::SetTrajectoryRequest request;
    *request.mutable_trajectory() = t;
    grpc::ClientContext context;
    context.set_deadline(Deadline());
    v1::ControlStatus response;
    return control_stub_->SetTrajectory(&context, request, &response);
  }

  NullCommandSink command_sink_;
  NullInput control_input_;
  NullPoseSink pose_sink_;
  NullInput localization_input_;
  std::unique_ptr<planning_service::PlannerCore> planner_;
  std::unique_ptr<planning_service::PlanningService> planning_;
  std::unique_ptr<control_service::ControlCore> control_core_;
  std::unique_ptr<control_service::ControlService> control_;
  std::unique_ptr<mapping_service::Mapper> mapper_;
  std::unique_ptr<mapping_service::MappingService> mapping_;
  std::unique_ptr<localization_service::Localizer> localizer_;
  std::unique_ptr<localization_service::LocalizationService> localization_;
  std::unique_ptr<transport::GrpcServer> server_;
  std::unique_ptr<v1::Planning::Stub> planning_stub_;
  std::unique_ptr<v1::Control::Stub> control_stub_;
  std::unique_ptr<v1::Mapping::Stub> mapping_stub_;
  std::unique_ptr<v1::Localization::Stub> localization_stub_;
};

// A rest-to-rest move of 2 s along x, one segment, as a planner would send it.
v1::PolynomialTrajectory GoodTrajectory() {
  v1::PolynomialTrajectory t;
  v1::PolynomialSegment* s = t.add_segments();
  s->set_duration_s(2);
  for (double c : {0.0, 0.0, 0.0, 1.25, -0.9375, 0.1875}) s->add_x(c);
  for (int k = 0; k < 6; ++k) {
    s->add_y(0);
    s->add_z(k == 0 ? 1.0 : 0.0);
  }
  t.set_duration_s(2);
  return t;
}

struct BadTrajectory {
  const char* what;
  void (*spoil)(v1::PolynomialTrajectory*);
  const char* verdict;  // the message after "trajectory"
};

const BadTrajectory kBadTrajectories[] = {
    {"no segments", [](v1::PolynomialTrajectory* t) { t->clear_segments(); },
     ".segments: no segments"},
    {"too many segments",
     [](v1::PolynomialTrajectory* t) {
       const v1::PolynomialSegment s = t->segments(0);
       for (int i = 0; i < service_common::kMaxTrajectorySegments; ++i) *t->add_segments() = s;
       t->set_duration_s(0);
     },
     ".segments: 10001 segments, at most 10000"},
    {"unknown yaw policy",
     [](v1::PolynomialTrajectory* t) { t->set_yaw_policy(static_cast<v1::YawPolicy>(9)); },
     ".yaw_policy: unknown value 9 (known: CONSTANT=1, ALONG_PATH=2, SEGMENT=3)"},
    {"start yaw not finite", [](v1::PolynomialTrajectory* t) { t->set_start_yaw_rad(kNaN); },
     ".start_yaw_rad: not finite"},
    {"zero duration",
     [](v1::PolynomialTrajectory* t) { t->mutable_segments(0)->set_duration_s(0); },
     ".segments[0].duration_s: must be > 0 and finite, got 0"},
    {"five coefficients",
     [](v1::PolynomialTrajectory* t) { t->mutable_segments(0)->mutable_y()->RemoveLast(); },
     ".segments[0].y: 5 coefficients, expected 6 (a quintic, ascending powers)"},
    {"coefficient not finite",
     [](v1::PolynomialTrajectory* t) { t->mutable_segments(0)->set_z(3, kNaN); },
     ".segments[0].z[3]: not finite"},
    {"three yaw coefficients",
     [](v1::PolynomialTrajectory* t) {
       for (int k = 0; k < 3; ++k) t->mutable_segments(0)->add_yaw(0);
     },
     ".segments[0].yaw: 3 coefficients, expected 6 (a quintic, ascending powers)"},
    {"segment yaw without coefficients",
     [](v1::PolynomialTrajectory* t) { t->set_yaw_policy(v1::YAW_POLICY_SEGMENT); },
     ".segments[0].yaw: YAW_POLICY_SEGMENT needs 6 yaw coefficients"},
    {"total duration not the sum", [](v1::PolynomialTrajectory* t) { t->set_duration_s(3); },
     ".duration_s: 3 s is not the sum of the segment durations, 2 s"},
};

TEST_F(SharedMessagesTest, ABadTrajectoryGetsOneVerdictFromPlanningAndControl) {
  ASSERT_TRUE(SampleTrajectory(GoodTrajectory()).ok());
  for (const BadTrajectory& bad : kBadTrajectories) {
    SCOPED_TRACE(bad.what);
    v1::PolynomialTrajectory t = GoodTrajectory();
    bad.spoil(&t);
    const grpc::Status planning = SampleTrajectory(t);
    const grpc::Status control = SetTrajectory(t);
    EXPECT_EQ(planning.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_EQ(control.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_EQ(AfterField(planning, "trajectory"), bad.verdict);
    EXPECT_EQ(AfterField(control, "trajectory"), bad.verdict);
  }
}

TEST_F(SharedMessagesTest, AVectorNotFiniteGetsOneVerdict) {
  for (int axis = 0; axis < 3; ++axis) {
    SCOPED_TRACE(axis);
    v1::Vector3 v;
    v.set_x(axis == 0 ? kNaN : 1);
    v.set_y(axis == 1 ? -std::numeric_limits<double>::infinity() : 1);
    v.set_z(axis == 2 ? kNaN : 1);
    const std::string verdict = std::string(".") + "xyz"[axis] + ": not finite";

    v1::PlanPathRequest plan;
    *plan.mutable_start() = v;
    *plan.mutable_goal() = v;
    grpc::ClientContext c1;
    c1.set_deadline(Deadline());
    v1::PlanPathResponse plan_response;
    const grpc::Status planning = planning_stub_->PlanPath(&c1, plan, &plan_response);

    v1::HoverRequest hover;
    *hover.mutable_position() = v;
    grpc::ClientContext c2;
    c2.set_deadline(Deadline());
    v1::ControlStatus control_response;
    const grpc::Status control = control_stub_->Hover(&c2, hover, &control_response);

    EXPECT_EQ(planning.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_EQ(control.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_EQ(AfterField(planning, "start"), verdict);
    EXPECT_EQ(AfterField(control, "position"), verdict);
  }
}

TEST_F(SharedMessagesTest, ABadBoxGetsOneVerdictFromMappingAndPlanning) {
  struct Case {
    Eigen::Vector3d min, max;
    const char* verdict;  // after the box's field
  };
  const Case cases[] = {
      {{kNaN, 0, 0}, {5, 5, 5}, ".min.x: not finite"},
      {{0, 0, 0}, {5, kNaN, 5}, ".max.y: not finite"},
      {{1, 6, 1}, {5, 5, 5}, ": min.y 6 > max.y 5"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.verdict);
    v1::Box box;
    service_common::ToProto(Eigen::AlignedBox3d(c.min, c.max), &box);
    // The corners as given, not as Eigen's box would reorder or extend them.
    service_common::ToProto(c.min, box.mutable_min());
    service_common::ToProto(c.max, box.mutable_max());

    v1::QueryCollisionRequest query;
    *query.add_boxes() = box;
    grpc::ClientContext c1;
    c1.set_deadline(Deadline());
    v1::QueryCollisionResponse query_response;
    const grpc::Status mapping = mapping_stub_->QueryCollision(&c1, query, &query_response);

    v1::LoadMapRequest load;
    load.mutable_file()->set_path("/nonexistent/map.bt");
    *load.mutable_options()->mutable_bounds() = box;
    grpc::ClientContext c2;
    c2.set_deadline(Deadline());
    v1::MapInfo load_response;
    const grpc::Status planning = planning_stub_->LoadMap(&c2, load, &load_response);

    EXPECT_EQ(mapping.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_EQ(planning.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_EQ(AfterField(mapping, "boxes[0]"), c.verdict);
    EXPECT_EQ(AfterField(planning, "options.bounds"), c.verdict);
  }
}

TEST_F(SharedMessagesTest, ABadPoseGetsOneVerdictOverGrpcAndOverDds) {
  struct Case {
    double p[3];
    double q[4];  // w x y z
    const char* grpc_verdict;
    const char* dds_verdict;
  };
  const Case cases[] = {
      {{0, kNaN, 0}, {1, 0, 0, 0}, ".position: not finite", "position.y: not finite"},
      {{0, 0, 0},
       {2, 0, 0, 0},
       ".orientation: norm 2, expected a unit quaternion (w first)",
       "orientation: norm 2, expected a unit quaternion (w first)"},
      {{0, 0, 0},
       {0, 0, 0, 0},
       ".orientation: norm 0, expected a unit quaternion (w first)",
       "orientation: norm 0, expected a unit quaternion (w first)"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.dds_verdict);
    // gRPC: mav-localization's Reset (initial_pose); the same decoder serves mapping's
    // InsertKeyframe and control's pose sources.
    v1::LocalizationResetRequest reset;
    v1::Pose* pose = reset.mutable_initial_pose();
    pose->mutable_position()->set_x(c.p[0]);
    pose->mutable_position()->set_y(c.p[1]);
    pose->mutable_position()->set_z(c.p[2]);
    pose->mutable_orientation()->set_w(c.q[0]);
    pose->mutable_orientation()->set_x(c.q[1]);
    pose->mutable_orientation()->set_y(c.q[2]);
    pose->mutable_orientation()->set_z(c.q[3]);
    grpc::ClientContext context;
    context.set_deadline(Deadline());
    v1::LocalizationStatus status;
    const grpc::Status localization = localization_stub_->Reset(&context, reset, &status);
    EXPECT_EQ(localization.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_EQ(AfterField(localization, "initial_pose"), c.grpc_verdict);

    // DDS: the same pose sample read by mav-control and by mav-mapping (both sources).
    mav_dds_PoseWithCovariance sample{};
    sample.tracking_state = mav_dds_TRACKING_STATE_OK;
    std::snprintf(sample.child_frame_id, sizeof(sample.child_frame_id), "body");
    sample.position = {c.p[0], c.p[1], c.p[2]};
    sample.orientation = {c.q[0], c.q[1], c.q[2], c.q[3]};
    Result<control_service::PoseInput> control = control_service::FromDds(sample);
    Result<std::optional<geometry::SE3>> mapping =
        mapping_service::BodyPoseFromDds(sample, geometry::SE3::Identity());
    mav_dds_GroundTruthState truth{};
    truth.position = sample.position;
    truth.orientation = sample.orientation;
    Result<geometry::SE3> mapping_truth = mapping_service::PoseFromDds(truth);
    ASSERT_FALSE(control.ok());
    ASSERT_FALSE(mapping.ok());
    ASSERT_FALSE(mapping_truth.ok());
    EXPECT_EQ(control.status().message(), c.dds_verdict);
    EXPECT_EQ(mapping.status().message(), c.dds_verdict);
    EXPECT_EQ(mapping_truth.status().message(), c.dds_verdict);
  }
}

TEST(EnumCodecs, EveryTableCoversItsEnum) {
  EXPECT_TRUE(service_common::CheckEnumCodec(service_common::kYawPolicyCodec).ok());
  EXPECT_TRUE(service_common::CheckEnumCodec(service_common::kOccupancyFormatCodec).ok());
  EXPECT_TRUE(service_common::CheckEnumCodec(planning_service::kDistanceMethodCodec).ok());
  EXPECT_TRUE(service_common::CheckEnumCodec(planning_service::kMappingMethodRefCodec).ok());
  EXPECT_TRUE(service_common::CheckEnumCodec(control_service::kControllerCodec).ok());
  EXPECT_TRUE(service_common::CheckEnumCodec(control_service::kImuLossPolicyCodec).ok());
  EXPECT_TRUE(service_common::CheckEnumCodec(mapping_service::kMappingMethodCodec).ok());
  EXPECT_TRUE(service_common::CheckEnumCodec(mapping_service::kPoseSourceCodec).ok());
  EXPECT_TRUE(service_common::CheckEnumCodec(mapping_service::kUnknownHandlingCodec).ok());
  EXPECT_TRUE(service_common::CheckEnumCodec(mapping_service::kMapPreferenceCodec).ok());
  EXPECT_TRUE(service_common::CheckEnumCodec(mapping_service::kMeshFormatCodec).ok());
  EXPECT_TRUE(service_common::CheckEnumCodec(localization_service::kMethodCodec).ok());
}

TEST(EnumCodecs, RefusalsAreWordedFromTheDescriptor) {
  Result<geometry::YawPolicy> unknown = service_common::kYawPolicyCodec.FromProto(7, "f");
  ASSERT_FALSE(unknown.ok());
  EXPECT_EQ(unknown.status().message(),
            "f: unknown value 7 (known: CONSTANT=1, ALONG_PATH=2, SEGMENT=3)");
  Result<localization::Method> not_set = localization_service::kMethodCodec.FromProto(0, "method");
  ASSERT_FALSE(not_set.ok());
  EXPECT_EQ(not_set.status().message(),
            "method: not set (LOCALIZATION_METHOD_UNSPECIFIED); use SPARSE_PIXEL, SPARSE_SUBPIXEL "
            "or DENSE");
  // A table missing a value is caught: ALONG_PATH left out.
  constexpr auto kPartial = service_common::MakeEnumCodec<v1::YawPolicy, geometry::YawPolicy>(
      v1::YawPolicy_descriptor,
      {{v1::YAW_POLICY_CONSTANT, geometry::YawPolicy::kConstant},
       {v1::YAW_POLICY_SEGMENT, geometry::YawPolicy::kSegment}},
      geometry::YawPolicy::kConstant);
  const Status check = service_common::CheckEnumCodec(kPartial);
  EXPECT_FALSE(check.ok());
  EXPECT_NE(check.message().find("ALONG_PATH"), std::string::npos) << check.message();
}

}  // namespace
}  // namespace mav
