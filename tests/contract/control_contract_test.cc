// Contract of mav.v1.Control (protos/mav/v1/control.proto, docs/contracts.md "Control"): every RPC
// with good and bad input (the field named) through an in-process channel and a real loopback
// port, deadlines (a call whose deadline passed changes nothing), SetTrajectory's plan_id path
// against a small fake Planning service (found, unknown, failed plan, unreachable, too slow), the
// data-plane rules of the core (one command per IMU sample stamped with its t_ns, repeated and old
// stamps, unknown pose frames) and the failsafes (pose timeout, the IMU watchdog and lock-step).
// The vehicle is libs/sim's FlightSimulation of t3_1, fed to the core directly (the DDS read loop
// is tests/integration/control_stack_test.cc's).

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>

#include "mav/common/time.h"
#include "mav/sim/flight_simulation.h"
#include "mav/sim/flight_task.h"
#include "mav/transport/grpc_server.h"
#include "mav/v1/control.grpc.pb.h"
#include "mav/v1/planning.grpc.pb.h"
#include "services/common/proto_codec.h"
#include "services/control/control_core.h"
#include "services/control/control_service.h"
#include "services/control/convert.h"
#include "services/control/dds_io.h"
#include "tests/common/contract_server.h"
#include "tests/common/fake_input_control.h"
#include "tests/common/grpc_expect.h"

namespace mav::control_service {
namespace {

using grpc::StatusCode;

using ::mav::test_support::FakeInputControl;  // tests/common/fake_input_control.h
using ::mav::test_support::StartOnFreePort;   // tests/common/contract_server.h

using ::mav::test_support::ExpectInvalidArgument;  // tests/common/grpc_expect.h
using ::mav::test_support::StartsWith;

std::chrono::system_clock::time_point Deadline(double seconds) {
  return std::chrono::system_clock::now() +
         std::chrono::milliseconds(static_cast<int64_t>(seconds * 1000));
}

class RecordingSink : public CommandSink {
 public:
  Status PublishCommand(const ActuatorOutput& command) override {
    std::lock_guard<std::mutex> lock(mutex_);
    commands_.push_back(command);
    return Status::Ok();
  }
  std::vector<ActuatorOutput> commands() {
    std::lock_guard<std::mutex> lock(mutex_);
    return commands_;
  }
  ActuatorOutput last() {
    std::lock_guard<std::mutex> lock(mutex_);
    return commands_.empty() ? ActuatorOutput() : commands_.back();
  }

 private:
  std::mutex mutex_;
  std::vector<ActuatorOutput> commands_;
};

// A rest-to-rest quintic from `a` to `b` in `t` seconds, one segment.
v1::PolynomialTrajectory Quintic(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double t) {
  v1::PolynomialTrajectory out;
  v1::PolynomialSegment* s = out.add_segments();
  s->set_duration_s(t);
  google::protobuf::RepeatedField<double>* axes[3] = {s->mutable_x(), s->mutable_y(),
                                                      s->mutable_z()};
  for (int k = 0; k < 3; ++k) {
    const double d = b[k] - a[k];
    for (double c : {a[k], 0.0, 0.0, 10 * d / std::pow(t, 3), -15 * d / std::pow(t, 4),
                     6 * d / std::pow(t, 5)}) {
      axes[k]->Add(c);
    }
  }
  out.set_duration_s(t);
  return out;
}

// The planning service's GetPlan, as the control service sees it.
class FakePlanning final : public v1::Planning::Service {
 public:
  grpc::Status GetPlan(grpc::ServerContext*, const v1::GetPlanRequest* request,
                       v1::PlanPathResponse* response) override {
    if (request->plan_id() == "slow") std::this_thread::sleep_for(std::chrono::milliseconds(800));
    if (request->plan_id() == "nopath") {
      response->set_status(v1::PLAN_STATUS_NO_PATH);
      response->set_message("the roadmap does not connect the goal");
      return grpc::Status::OK;
    }
    if (request->plan_id() == "leg" || request->plan_id() == "slow") {
      response->set_status(v1::PLAN_STATUS_SUCCESS);
      response->set_plan_id(request->plan_id());
      *response->mutable_trajectory() =
          Quintic(Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(1, 0.5, 1.5), 3.0);
      return grpc::Status::OK;
    }
    return grpc::Status(grpc::StatusCode::NOT_FOUND,
                        "plan_id: unknown '" + request->plan_id() + "' (last 16 plans kept)");
  }
};

class ControlContractTest : public ::testing::Test {
 protected:
  void SetUp() override {
    core_ = std::make_unique<ControlCore>(&sink_);
    ControlServiceOptions options;
    options.planning_timeout_ms = 300;
    service_ = std::make_unique<ControlService>(core_.get(), &input_, options);
    server_ = StartOnFreePort<v1::Control>(service_.get());
    ASSERT_NE(server_, nullptr);
    stub_ = v1::Control::NewStub(server_->InProcessChannel());
    Result<dataset::FlightTask> task = sim::BuiltinFlightTask("t3_1");
    ASSERT_TRUE(task.ok());
    task_ = *task;
  }
  void TearDown() override {
    if (server_ != nullptr) server_->Shutdown();
  }

  // What the contest told the teams about t3_1.
  v1::ControlConfigureRequest TaskRequest(bool lockstep = false) {
    v1::ControlConfigureRequest request;
    ToProto(ConfigForFlightTask(task_, control::ControllerType::kPaper, lockstep), &request);
    return request;
  }
  grpc::Status Configure(const v1::ControlConfigureRequest& request,
                         v1::ControlStatus* out = nullptr) {
    grpc::ClientContext context;
    context.set_deadline(Deadline(10));
    v1::ControlStatus local;
    return stub_->Configure(&context, request, out != nullptr ? out : &local);
  }
  grpc::Status Arm(v1::ControlStatus* out = nullptr, bool in_air = false) {
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    v1::ControlStatus local;
    v1::ArmRequest request;
    request.set_in_air(in_air);
    return stub_->Arm(&context, request, out != nullptr ? out : &local);
  }
  grpc::Status Disarm() {
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    v1::ControlStatus local;
    return stub_->Disarm(&context, v1::DisarmRequest(), &local);
  }
  grpc::Status Hover(const v1::HoverRequest& request, v1::ControlStatus* out = nullptr) {
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    v1::ControlStatus local;
    return stub_->Hover(&context, request, out != nullptr ? out : &local);
  }
  grpc::Status SetTrajectory(const v1::SetTrajectoryRequest& request,
                             v1::ControlStatus* out = nullptr, double deadline_s = 5) {
    grpc::ClientContext context;
    context.set_deadline(Deadline(deadline_s));
    v1::ControlStatus local;
    return stub_->SetTrajectory(&context, request, out != nullptr ? out : &local);
  }
  grpc::Status SetGains(const v1::SetGainsRequest& request, v1::ControlStatus* out = nullptr) {
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    v1::ControlStatus local;
    return stub_->SetGains(&context, request, out != nullptr ? out : &local);
  }
  v1::ControlStatus GetStatus() {
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    v1::ControlStatus status;
    EXPECT_TRUE(stub_->GetStatus(&context, v1::ControlGetStatusRequest(), &status).ok());
    return status;
  }
  v1::ControlState GetState() {
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    v1::ControlState state;
    EXPECT_TRUE(stub_->GetState(&context, v1::ControlGetStateRequest(), &state).ok());
    return state;
  }
  void ExpectInvalid(const grpc::Status& status, const std::string& field) {
    ExpectInvalidArgument(status, field);
  }
  void ExpectConfigureInvalid(const std::function<void(v1::ControlConfigureRequest*)>& edit,
                              const std::string& field) {
    v1::ControlConfigureRequest request = TaskRequest();
    edit(&request);
    ExpectInvalid(Configure(request), field);
  }

  // Flies the simulated t3_1 for `seconds` on the core's own commands (the closed loop without
  // the network): each step's poses, then its IMU sample, then the command the core published.
  void Fly(double seconds, bool poses = true) {
    if (!sim_.has_value()) {
      Result<sim::FlightSimulation> sim = sim::FlightSimulation::Create(task_, 11);
      ASSERT_TRUE(sim.ok());
      sim_.emplace(std::move(*sim));
      out_ = &sim_->Initial();
    }
    const int64_t end_ns = out_->t_ns + SecondsToNs(seconds);
    while (out_->t_ns < end_ns) {
      if (poses) {
        for (const sim::PoseSample& p : out_->poses) {
          core_->OnPose("pose_sensor" + std::to_string(p.sensor), p.t_ns, p.T_world_sensor);
        }
      }
      core_->OnImu({out_->imu.t_ns, out_->imu.gyro, out_->imu.accel});
      const ActuatorOutput command = sink_.last();
      ASSERT_EQ(command.t_ns, out_->imu.t_ns) << "every IMU sample gets its command";
      sim::RotorVector w = sim::RotorVector::Zero(6);
      if (command.armed) {
        for (int i = 0; i < 6; ++i) w[i] = command.rotor_speeds_radps[i];
      }
      out_ = &sim_->Step(w);
    }
  }
  // Configured for t3_1, converged, armed and hovering at (0, 0, 1) after the take-off.
  void Airborne(bool lockstep = false) {
    ASSERT_TRUE(Configure(TaskRequest(lockstep)).ok());
    Fly(5.0);
    ASSERT_TRUE(Arm().ok());
    v1::HoverRequest hover;
    hover.mutable_position()->set_z(1.0);
    ASSERT_TRUE(Hover(hover).ok());
    Fly(4.0);
  }

  RecordingSink sink_;
  FakeInputControl input_;
  std::unique_ptr<ControlCore> core_;
  std::unique_ptr<ControlService> service_;
  std::unique_ptr<transport::GrpcServer> server_;
  std::unique_ptr<v1::Control::Stub> stub_;
  dataset::FlightTask task_;
  std::optional<sim::FlightSimulation> sim_;
  const sim::FlightStep* out_ = nullptr;
};

// ---- GetStatus / GetState / Configure
// -------------------------------------------------------------

TEST_F(ControlContractTest, StatusAndStateBeforeTheConfiguration) {
  const v1::ControlStatus status = GetStatus();
  EXPECT_FALSE(status.configured());
  EXPECT_FALSE(status.armed());
  EXPECT_EQ(status.mode(), v1::CONTROL_MODE_DISARMED);
  EXPECT_FALSE(status.dds_input());
  const v1::ControlState state = GetState();
  EXPECT_FALSE(state.configured());
  EXPECT_FALSE(state.has_estimate());
  // Unconfigured, IMU samples are not answered.
  core_->OnImu({10, Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, 9.81)});
  EXPECT_TRUE(sink_.commands().empty());
}

TEST_F(ControlContractTest, ConfigureFillsTheDefaultsAndSwitchesTheInput) {
  v1::ControlConfigureRequest empty;
  v1::ControlStatus status;
  ASSERT_TRUE(Configure(empty, &status).ok());
  EXPECT_TRUE(status.configured());
  EXPECT_TRUE(status.dds_input());
  const v1::ControlConfigureRequest& c = status.config();
  EXPECT_DOUBLE_EQ(c.vehicle().mass_kg(), 1.568);
  EXPECT_EQ(c.vehicle().rotor_count(), 6u);
  EXPECT_EQ(c.vehicle().rotor_angles_deg_size(), 6);
  EXPECT_DOUBLE_EQ(c.vehicle().motor_time_constant_down_s(), 0.025);
  ASSERT_EQ(c.estimator().pose_sources_size(), 1);
  EXPECT_EQ(c.estimator().pose_sources(0).frame_id(), "pose_sensor0");
  EXPECT_DOUBLE_EQ(c.estimator().pose_sources(0).t_body_sensor().orientation().w(), 1.0);
  EXPECT_DOUBLE_EQ(c.estimator().imu_rate_hz(), 100);
  EXPECT_DOUBLE_EQ(c.estimator().buffer_s(), 1.0);
  EXPECT_DOUBLE_EQ(c.gains().attitude_omega_radps(), 12.0);
  EXPECT_DOUBLE_EQ(c.lee_gains().velocity_gain().x(), 4.7);
  EXPECT_EQ(c.controller(), v1::CONTROLLER_TYPE_PAPER);
  EXPECT_DOUBLE_EQ(c.disturbance_observer_s(), 0.15);
  EXPECT_DOUBLE_EQ(c.correction_blend_s(), 0.2);
  EXPECT_DOUBLE_EQ(c.imu_timeout_s(), 0.1);
  EXPECT_FALSE(c.lockstep());
  // The task's configuration: two sources for t4_2, their mountings, the Lee controller; the
  // observer switched off explicitly (0 is "off", unset is "default").
  Result<dataset::FlightTask> t4_2 = sim::BuiltinFlightTask("t4_2");
  ASSERT_TRUE(t4_2.ok());
  v1::ControlConfigureRequest request;
  ToProto(ConfigForFlightTask(*t4_2, control::ControllerType::kLee, true), &request);
  request.set_disturbance_observer_s(0);
  request.set_disable_dds_input(true);
  ASSERT_TRUE(Configure(request, &status).ok());
  EXPECT_FALSE(status.dds_input());
  EXPECT_EQ(status.controller(), v1::CONTROLLER_TYPE_LEE);
  ASSERT_EQ(status.config().estimator().pose_sources_size(), 2);
  EXPECT_EQ(status.config().estimator().pose_sources(1).frame_id(), "pose_sensor1");
  EXPECT_DOUBLE_EQ(status.config().estimator().pose_sources(1).rate_hz(), 20);
  EXPECT_NEAR(status.config().estimator().pose_sources(1).t_body_sensor().position().y(), 0.08,
              1e-12);
  EXPECT_DOUBLE_EQ(status.config().disturbance_observer_s(), 0.0);
  EXPECT_TRUE(status.config().lockstep());
}

TEST_F(ControlContractTest, ConfigureRejectsBadInputNamingTheField) {
  using R = v1::ControlConfigureRequest;
  ExpectConfigureInvalid([](R* r) { r->mutable_vehicle()->set_rotor_count(3); },
                         "vehicle.rotor_count");
  ExpectConfigureInvalid(
      [](R* r) {
        r->mutable_vehicle()->set_rotor_count(4);  // six angles given
      },
      "vehicle.rotor_angles_deg");
  ExpectConfigureInvalid([](R* r) { r->mutable_vehicle()->set_mass_kg(-1); }, "vehicle.mass_kg");
  ExpectConfigureInvalid([](R* r) { r->mutable_vehicle()->set_mass_kg(std::nan("")); },
                         "vehicle.mass_kg: not finite");
  ExpectConfigureInvalid([](R* r) { r->mutable_vehicle()->set_rotor_directions(2, 3); },
                         "vehicle.rotor_directions[2]");
  // The vehicle's own field is named, not the allocation's minimum that depends on it.
  ExpectConfigureInvalid([](R* r) { r->mutable_vehicle()->set_max_rotor_speed_radps(-1); },
                         "vehicle.max_rotor_speed_radps");
  ExpectConfigureInvalid([](R* r) { r->mutable_estimator()->set_imu_rate_hz(5); },
                         "estimator.imu_rate_hz");
  ExpectConfigureInvalid([](R* r) { r->mutable_estimator()->set_buffer_s(20); },
                         "estimator.buffer_s");
  ExpectConfigureInvalid(
      [](R* r) { r->mutable_estimator()->mutable_pose_sources(0)->set_delay_s(2); },
      "estimator.pose_sources[0].delay_s");
  ExpectConfigureInvalid(
      [](R* r) {
        r->mutable_estimator()
            ->mutable_pose_sources(0)
            ->mutable_t_body_sensor()
            ->mutable_orientation()
            ->set_w(3);
      },
      "estimator.pose_sources[0].t_body_sensor.orientation");
  ExpectConfigureInvalid(
      [](R* r) { *r->mutable_estimator()->add_pose_sources() = r->estimator().pose_sources(0); },
      "estimator.pose_sources[1].frame_id");
  ExpectConfigureInvalid(
      [](R* r) { r->mutable_estimator()->mutable_explicit_weights()->set_position(2); },
      "estimator.explicit_weights.position");
  ExpectConfigureInvalid([](R* r) { r->mutable_gains()->mutable_position_zeta()->set_y(5); },
                         "gains.position_zeta.y");
  ExpectConfigureInvalid([](R* r) { r->mutable_gains()->mutable_integral_gain()->set_x(1e6); },
                         "gains.integral_gain.x");
  ExpectConfigureInvalid([](R* r) { r->mutable_gains()->set_attitude_zeta(4); },
                         "gains.attitude_zeta");
  ExpectConfigureInvalid([](R* r) { r->mutable_lee_gains()->mutable_position_gain()->set_x(-1); },
                         "lee_gains.position_gain");
  ExpectConfigureInvalid([](R* r) { r->set_controller(static_cast<v1::ControllerType>(7)); },
                         "controller:");
  ExpectConfigureInvalid([](R* r) { r->set_imu_loss_policy(static_cast<v1::ImuLossPolicy>(9)); },
                         "imu_loss_policy:");
  ExpectConfigureInvalid([](R* r) { r->set_disturbance_observer_s(10); }, "disturbance_observer_s");
  ExpectConfigureInvalid([](R* r) { r->mutable_goto_limits()->set_max_speed_mps(-1); },
                         "goto_limits.max_speed_mps");
  ExpectConfigureInvalid([](R* r) { r->set_min_rotor_speed_radps(900); }, "min_rotor_speed_radps");
  ExpectConfigureInvalid([](R* r) { r->set_max_tilt_rad(2); }, "max_tilt_rad");
  ExpectConfigureInvalid([](R* r) { r->mutable_estimator()->set_pose_gate_m(-0.1); },
                         "estimator.pose_gate_m");
  ExpectConfigureInvalid([](R* r) { r->mutable_estimator()->set_pose_gate_rad(std::nan("")); },
                         "estimator.pose_gate_rad");
  ExpectConfigureInvalid(
      [](R* r) {  // a lock-stepped source needs a lock-stepped clock
        r->mutable_estimator()->mutable_pose_sources(0)->set_lockstep_latency_s(0.05);
      },
      "estimator.pose_sources[0].lockstep_latency_s: needs lockstep");
  ExpectConfigureInvalid(
      [](R* r) {
        r->set_lockstep(true);
        r->mutable_estimator()->mutable_pose_sources(0)->set_lockstep_latency_s(2);
      },
      "estimator.pose_sources[0].lockstep_latency_s");
  ExpectConfigureInvalid(
      [](R* r) {
        r->set_lockstep(true);
        r->mutable_estimator()->mutable_pose_sources(0)->set_lockstep_latency_s(0.05);
        r->mutable_estimator()->mutable_pose_sources(0)->set_lockstep_wait_s(100);
      },
      "estimator.pose_sources[0].lockstep_wait_s");
  ExpectConfigureInvalid(
      [](R* r) { r->mutable_estimator()->mutable_pose_sources(0)->set_tilt_sigma_rad(-0.1); },
      "estimator.pose_sources[0].tilt_sigma_rad");
  ExpectConfigureInvalid(
      [](R* r) { r->mutable_estimator()->mutable_pose_sources(0)->set_align_tilt_s(std::nan("")); },
      "estimator.pose_sources[0].align_tilt_s");
  ExpectConfigureInvalid(
      [](R* r) { r->mutable_estimator()->mutable_pose_sources(0)->set_align_tilt_s(-1); },
      "estimator.pose_sources[0].align_tilt_s");
  EXPECT_FALSE(GetStatus().configured()) << "nothing of this was applied";
}

// A source whose frame is tipped against gravity (a VO's tilt drift), with the gravity
// alignment on: the estimate's config echoes it, and GetState reports the frame the estimator
// turned it by (a restarted VO is seeded through it); a plain source reports the identity.
TEST_F(ControlContractTest, TiltAlignedSourceReportsItsCorrectedFrame) {
  const Eigen::Quaterniond tip(Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitX()));
  auto fly_tipped = [&](double align_tilt_s) {
    v1::ControlConfigureRequest request = TaskRequest();
    v1::ControlPoseSource* source = request.mutable_estimator()->mutable_pose_sources(0);
    source->set_frame_id("body");
    source->set_rate_hz(20);
    source->set_tilt_sigma_rad(0.17);
    source->set_align_tilt_s(align_tilt_s);
    EXPECT_TRUE(Configure(request).ok());
    // 10 s level at rest, a pose every 50 ms: true for the first 5 s (the estimate converges,
    // learning its offsets against the source's tilt), then tipped.
    for (int k = 0; k <= 2000; ++k) {
      const int64_t t_ns = SecondsToNs(0.005 * k);
      core_->OnImu(control::ImuMeasurement{t_ns, Eigen::Vector3d::Zero(),
                                           Eigen::Vector3d(0, 0, control::kGravity)});
      const Eigen::Quaterniond q = k < 1000 ? Eigen::Quaterniond::Identity() : tip;
      if (k % 10 == 0) core_->OnPose("body", t_ns, geometry::SE3(q, Eigen::Vector3d(0, 0, 1)));
    }
    const v1::ControlStatus status = GetStatus();
    EXPECT_DOUBLE_EQ(status.config().estimator().pose_sources(0).align_tilt_s(), align_tilt_s);
    EXPECT_DOUBLE_EQ(status.config().estimator().pose_sources(0).tilt_sigma_rad(), 0.17);
    const v1::ControlState state = GetState();
    EXPECT_EQ(state.estimate().source_frames_size(), 1);
    const Result<geometry::SE3> frame =
        service_common::PoseFromProto(state.estimate().source_frames(0), "source_frames[0]");
    EXPECT_TRUE(frame.ok());
    return frame.ok() ? geometry::AngleBetween(frame->Rotation(), Eigen::Quaterniond::Identity())
                      : -1.0;
  };
  EXPECT_LT(fly_tipped(0), 1e-9) << "a plain source: the identity";
  // Turned back toward level by most of the 0.05 rad tip (time constant 1 s, 5 s tipped).
  const double turned = fly_tipped(1.0);
  EXPECT_GT(turned, 0.03);
  EXPECT_LT(turned, 0.06);
}

// A lock-stepped camera-rate source (a localization service answering every frame of a
// simulator's mission flight): its poses are merged at stamp + latency whenever they arrive, the
// data plane is told to wait for a frame due and not answered, a LOST answer answers, and a
// source that stays silent is given up (counted) until it answers again.
TEST_F(ControlContractTest, LockstepPoseSourceMergesAtStampPlusLatencyAndWaitsForDueFrames) {
  v1::ControlConfigureRequest request = TaskRequest(/*lockstep=*/true);
  v1::ControlPoseSource* source = request.mutable_estimator()->mutable_pose_sources(0);
  source->set_frame_id("body");
  source->set_rate_hz(20);
  source->set_lockstep_latency_s(0.05);
  source->set_lockstep_wait_s(0.5);
  ASSERT_TRUE(Configure(request).ok());
  v1::ControlStatus status = GetStatus();
  EXPECT_DOUBLE_EQ(status.config().estimator().pose_sources(0).lockstep_latency_s(), 0.05);
  const control::ImuMeasurement still{0, Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, 9.81)};
  auto imu_at = [&](double t_s) {
    control::ImuMeasurement imu = still;
    imu.t_ns = SecondsToNs(t_s);
    return imu;
  };
  const geometry::SE3 pose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 0.1));
  EXPECT_FALSE(core_->AwaitingPose(0)) << "frame 0 is due at 0.05 s";
  core_->OnImu(imu_at(0));
  EXPECT_TRUE(core_->AwaitingPose(SecondsToNs(0.05)));
  core_->OnPose("body", 0, pose);  // frame 0 answered early...
  EXPECT_FALSE(core_->AwaitingPose(SecondsToNs(0.05)));
  core_->OnImu(imu_at(0.045));
  EXPECT_FALSE(GetState().estimate().initialized()) << "...but held until its stamp + 50 ms";
  core_->OnImu(imu_at(0.05));
  EXPECT_TRUE(GetState().estimate().initialized());
  EXPECT_EQ(GetState().estimate().last_pose_arrival_t_ns(), SecondsToNs(0.045))
      << "merged before the IMU sample at 0.05 s (the autopilot's clock is the previous one)";
  // Frame 1 (0.05 s) answered LOST: answered, not merged.
  EXPECT_TRUE(core_->AwaitingPose(SecondsToNs(0.1)));
  core_->OnPoseAnswer("body", SecondsToNs(0.05), "tracking_state: 3 is not OK/INITIALIZING");
  EXPECT_FALSE(core_->AwaitingPose(SecondsToNs(0.1)));
  // Frame 2 never answered: given up, silent, counted; an answer brings the wait back.
  EXPECT_TRUE(core_->AwaitingPose(SecondsToNs(0.15)));
  EXPECT_EQ(core_->LockstepWaitNs(), SecondsToNs(0.5));
  core_->GiveUpWaiting(SecondsToNs(0.15));
  EXPECT_FALSE(core_->AwaitingPose(SecondsToNs(0.3)));
  status = GetStatus();
  EXPECT_EQ(status.lockstep_frames_missed(), 1u);
  EXPECT_TRUE(status.lockstep_source_silent());
  core_->OnPose("body", SecondsToNs(0.3), pose);
  EXPECT_FALSE(GetStatus().lockstep_source_silent());
  EXPECT_TRUE(core_->AwaitingPose(SecondsToNs(0.4))) << "frame 0.35 s is due again";
}

// ---- Arm / Disarm and the data plane
// --------------------------------------------------------------

TEST_F(ControlContractTest, ArmNeedsAConvergedEstimatorAndAFreshPose) {
  EXPECT_EQ(Arm().error_code(), StatusCode::FAILED_PRECONDITION);  // not configured
  ASSERT_TRUE(Configure(TaskRequest()).ok());
  grpc::Status s = Arm();
  EXPECT_EQ(s.error_code(), StatusCode::FAILED_PRECONDITION);
  EXPECT_NE(s.error_message().find("not converged"), std::string::npos) << s.error_message();
  Fly(2.0);  // converges converge_s = 4 s after the first pose
  EXPECT_EQ(Arm().error_code(), StatusCode::FAILED_PRECONDITION);
  Fly(3.0);
  EXPECT_TRUE(GetStatus().estimator_converged());
  v1::ControlStatus armed;
  ASSERT_TRUE(Arm(&armed).ok()) << Arm().error_message();
  EXPECT_TRUE(armed.armed());
  EXPECT_EQ(armed.mode(), v1::CONTROL_MODE_HOVER);
  s = Arm();
  EXPECT_EQ(s.error_code(), StatusCode::FAILED_PRECONDITION);
  EXPECT_NE(s.error_message().find("already armed"), std::string::npos);
  s = Configure(TaskRequest());
  EXPECT_EQ(s.error_code(), StatusCode::FAILED_PRECONDITION) << "no Configure while armed";
  ASSERT_TRUE(Disarm().ok());
  EXPECT_FALSE(GetStatus().armed());
  EXPECT_TRUE(Configure(TaskRequest()).ok());
}

// Arm{in_air} (a restarted controller taking over a flying vehicle; flown in the air by
// control_autopilot_test and control_stack_test): refused without the ground's height, before
// the estimate settled, and on the ground, each saying why.
TEST_F(ControlContractTest, ArmInTheAirNeedsTheGroundASettledEstimateAndAnAirborneVehicle) {
  v1::ControlConfigureRequest request = TaskRequest();
  EXPECT_NEAR(request.rest_z_m(), task_.spawn_position.z(), 1e-12) << "the task's spawn height";
  request.clear_rest_z_m();
  ASSERT_TRUE(Configure(request).ok());
  Fly(1.0);
  grpc::Status s = Arm(nullptr, /*in_air=*/true);
  EXPECT_EQ(s.error_code(), StatusCode::FAILED_PRECONDITION);
  EXPECT_NE(s.error_message().find("rest_z_m"), std::string::npos) << s.error_message();
  EXPECT_EQ(core_->SetTakeover(true).code(), mav::StatusCode::kFailedPrecondition);

  v1::ControlStatus configured;
  ASSERT_TRUE(Configure(TaskRequest(), &configured).ok());
  EXPECT_TRUE(configured.config().has_rest_z_m());
  EXPECT_NEAR(configured.config().takeover_settle_s(), 0.5, 1e-12);
  EXPECT_NEAR(configured.config().takeover_min_height_m(), 0.3, 1e-12);
  Fly(0.2);
  s = Arm(nullptr, /*in_air=*/true);
  EXPECT_EQ(s.error_code(), StatusCode::FAILED_PRECONDITION);
  EXPECT_NE(s.error_message().find("merged poses for 0.5"), std::string::npos) << s.error_message();
  Fly(0.6);
  s = Arm(nullptr, /*in_air=*/true);
  EXPECT_EQ(s.error_code(), StatusCode::FAILED_PRECONDITION);
  EXPECT_NE(s.error_message().find("not airborne"), std::string::npos) << s.error_message();
  EXPECT_FALSE(GetStatus().armed());
  // A pending takeover on the ground gives up once and stays disarmed.
  ASSERT_TRUE(Configure(TaskRequest()).ok());
  ASSERT_TRUE(core_->SetTakeover(true).ok());
  EXPECT_TRUE(GetStatus().takeover_pending());
  Fly(1.0);
  v1::ControlStatus status = GetStatus();
  EXPECT_FALSE(status.takeover_pending());
  EXPECT_FALSE(status.armed());
  EXPECT_NE(status.last_error().find("takeover: in the air: the vehicle is"), std::string::npos)
      << status.last_error();
  ExpectConfigureInvalid([](v1::ControlConfigureRequest* r) { r->set_takeover_settle_s(11); },
                         "takeover_settle_s");
}

TEST_F(ControlContractTest, EveryImuSampleGetsOneCommandStampedWithIt) {
  ASSERT_TRUE(Configure(TaskRequest()).ok());
  Fly(5.0);
  std::vector<ActuatorOutput> commands = sink_.commands();
  ASSERT_EQ(commands.size(), 500u);
  for (size_t i = 0; i < commands.size(); ++i) {
    EXPECT_EQ(commands[i].t_ns, static_cast<int64_t>(i) * 10'000'000);
    EXPECT_FALSE(commands[i].armed);
    EXPECT_EQ(commands[i].sequence, i);
    ASSERT_EQ(commands[i].rotor_speeds_radps.size(), 6);
    EXPECT_EQ(commands[i].rotor_speeds_radps.norm(), 0.0);
  }
  ASSERT_TRUE(Arm().ok());
  Fly(0.5);
  const ActuatorOutput armed = sink_.last();
  EXPECT_TRUE(armed.armed);
  EXPECT_GT(armed.rotor_speeds_radps.minCoeff(), 100.0);
  // A repeated stamp (a lock-stepped simulator resuming) gets the same command again; an older
  // one is refused.
  const size_t before = sink_.commands().size();
  core_->OnImu({armed.t_ns, out_->imu.gyro, out_->imu.accel});
  ASSERT_EQ(sink_.commands().size(), before + 1);
  EXPECT_EQ(sink_.last().t_ns, armed.t_ns);
  EXPECT_EQ(sink_.last().rotor_speeds_radps, armed.rotor_speeds_radps);
  core_->OnImu({armed.t_ns - 20'000'000, out_->imu.gyro, out_->imu.accel});
  EXPECT_EQ(sink_.commands().size(), before + 1);
  const v1::ControlStatus status = GetStatus();
  EXPECT_EQ(status.imu_repeated(), 1u);
  EXPECT_EQ(status.imu_rejected(), 1u);
  EXPECT_EQ(status.commands(), before + 1);
  EXPECT_EQ(status.imu_samples(), 550u);
  EXPECT_GE(status.poses(), 50u);
  EXPECT_GT(status.step_ms().count(), 0u);
  EXPECT_GT(status.loop_ms().count(), 0u);
  EXPECT_NE(status.last_error().find("older than the previous"), std::string::npos);
}

TEST_F(ControlContractTest, PosesOfAnUnknownFrameOrMalformedAreRejected) {
  ASSERT_TRUE(Configure(TaskRequest()).ok());
  core_->OnImu({0, Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, 9.81)});
  core_->OnPose("body", 0, geometry::SE3::Identity());
  v1::ControlStatus status = GetStatus();
  EXPECT_EQ(status.poses_rejected(), 1u);
  EXPECT_EQ(status.poses(), 0u);
  EXPECT_NE(status.last_error().find("unknown child_frame_id 'body'"), std::string::npos)
      << status.last_error();
  // The transport's checks.
  mav_dds_PoseWithCovariance lost{};
  lost.orientation.w = 1;
  lost.tracking_state = mav_dds_TRACKING_STATE_LOST;
  EXPECT_TRUE(StartsWith(FromDds(lost).status().message(), "tracking_state:"));
  mav_dds_PoseWithCovariance skew = lost;
  skew.tracking_state = mav_dds_TRACKING_STATE_OK;
  skew.orientation.w = 2;
  EXPECT_TRUE(StartsWith(FromDds(skew).status().message(), "orientation:"));
  mav_dds_PoseWithCovariance far = lost;
  far.tracking_state = mav_dds_TRACKING_STATE_OK;
  far.position.y = std::nan("");
  EXPECT_TRUE(StartsWith(FromDds(far).status().message(), "position.y: not finite"));
  std::strncpy(far.child_frame_id, "pose_sensor0", sizeof(far.child_frame_id));
  far.position.y = 1;
  far.t_ns = 5;
  Result<PoseInput> good = FromDds(far);
  ASSERT_TRUE(good.ok());
  EXPECT_EQ(good->frame_id, "pose_sensor0");
  EXPECT_DOUBLE_EQ(good->T_world_sensor.Translation().y(), 1.0);
  mav_dds_ImuSample imu{};
  imu.gyro.y = std::numeric_limits<double>::infinity();
  EXPECT_TRUE(StartsWith(FromDds(imu).status().message(), "gyro.y: not finite"));
  // Commands on the wire.
  ActuatorOutput command;
  command.sequence = 3;
  command.t_ns = 42;
  command.armed = true;
  command.rotor_speeds_radps = control::RotorVector::Constant(6, 500);
  double speeds[mav_dds_kMaxRotors] = {};
  const mav_dds_ActuatorCommand sample = ToDds(command, 7, speeds);
  EXPECT_EQ(sample.sequence_number, 3u);
  EXPECT_EQ(sample.t_ns, 42);
  EXPECT_EQ(sample.publish_t_ns, 7);
  EXPECT_TRUE(sample.armed);
  ASSERT_EQ(sample.rotor_speeds._length, 6u);
  EXPECT_DOUBLE_EQ(sample.rotor_speeds._buffer[5], 500);
  EXPECT_FALSE(sample.rotor_speeds._release);
}

// A pose with its frame's stamps adds to ControlStatus.pose_latency, hop by hop; one without
// them (a pose sensor's) or of an unknown frame does not.
TEST_F(ControlContractTest, VisionPoseLatencyIsCountedHopByHop) {
  ASSERT_TRUE(Configure(TaskRequest()).ok());
  core_->OnImu({0, Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, 9.81)});
  const int64_t now = WallNowNs();
  const int64_t ms = 1'000'000;
  const PoseStamps stamps{now - 12 * ms, now - 10 * ms, now - 2 * ms, now - 1 * ms};
  core_->OnPose("pose_sensor0", 0, geometry::SE3::Identity(), stamps);
  core_->OnPose("pose_sensor0", SecondsToNs(0.005), geometry::SE3::Identity());  // no stamps
  core_->OnPose("body", SecondsToNs(0.01), geometry::SE3::Identity(), stamps);   // rejected
  const v1::PoseLatency latency = GetStatus().pose_latency();
  ASSERT_EQ(latency.total().count(), 1u);
  EXPECT_NEAR(latency.frame_transport().median_ms(), 2.0, 1e-9);
  EXPECT_NEAR(latency.localization().median_ms(), 8.0, 1e-9);
  EXPECT_NEAR(latency.pose_transport().median_ms(), 1.0, 1e-9);
  EXPECT_GE(latency.merge().median_ms(), 0.0);
  EXPECT_LT(latency.merge().median_ms(), 1000.0);
  EXPECT_NEAR(latency.total().median_ms(), 11.0 + latency.merge().median_ms(), 1e-6);
  // Configure starts the windows afresh.
  ASSERT_TRUE(Configure(TaskRequest()).ok());
  EXPECT_EQ(GetStatus().pose_latency().total().count(), 0u);
}

// ---- Hover
// ----------------------------------------------------------------------------------------

TEST_F(ControlContractTest, HoverChecksItsInputAndTheState) {
  v1::HoverRequest hover;
  hover.mutable_position()->set_z(1.0);
  EXPECT_EQ(Hover(hover).error_code(), StatusCode::FAILED_PRECONDITION);  // not configured
  ASSERT_TRUE(Configure(TaskRequest()).ok());
  EXPECT_EQ(Hover(hover).error_code(), StatusCode::FAILED_PRECONDITION);  // disarmed
  ExpectInvalid(Hover(v1::HoverRequest()), "position: not set");
  v1::HoverRequest bad = hover;
  bad.mutable_position()->set_y(std::nan(""));
  ExpectInvalid(Hover(bad), "position.y: not finite");
  bad = hover;
  bad.set_yaw_rad(std::numeric_limits<double>::infinity());
  ExpectInvalid(Hover(bad), "yaw_rad:");
  bad = hover;
  bad.mutable_limits()->set_max_speed_mps(-2);
  ExpectInvalid(Hover(bad), "limits.max_speed_mps");
  Fly(5.0);
  ASSERT_TRUE(Arm().ok());
  v1::ControlStatus status;
  ASSERT_TRUE(Hover(hover, &status).ok());
  EXPECT_EQ(status.mode(), v1::CONTROL_MODE_HOVER);
  Fly(0.5);
  v1::ControlState state = GetState();
  EXPECT_GT(state.trajectory_duration_s(), 0.5) << "a smooth move, not a jump";
  EXPECT_LT(state.reference().position().z(), 0.9);
  Fly(4.0);
  state = GetState();
  EXPECT_NEAR(state.reference().position().z(), 1.0, 1e-9);
  EXPECT_NEAR(state.estimate().t_world_body().position().z(), 1.0, 0.1);
  EXPECT_NEAR(state.estimate().last_pose_delay_ms(), 100, 1e-6);  // the contest's 100 ms
  // immediate: the reference jumps to the hold point at once.
  v1::HoverRequest hold;
  hold.mutable_position()->set_x(0.2);
  hold.mutable_position()->set_z(1.1);
  hold.set_immediate(true);
  ASSERT_TRUE(Hover(hold).ok());
  Fly(0.01);
  EXPECT_NEAR(GetState().reference().position().x(), 0.2, 1e-12);
}

// ---- SetTrajectory
// --------------------------------------------------------------------------------

TEST_F(ControlContractTest, SetTrajectoryRejectsBadTrajectoriesNamingTheField) {
  Airborne();
  const v1::PolynomialTrajectory good =
      Quintic(Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(1, 0, 1), 2.0);
  v1::SetTrajectoryRequest r;
  ExpectInvalid(SetTrajectory(r), "trajectory: set trajectory or plan");
  r.mutable_trajectory();
  ExpectInvalid(SetTrajectory(r), "trajectory.segments: no segments");
  *r.mutable_trajectory() = good;
  r.mutable_trajectory()->mutable_segments(0)->set_duration_s(0);
  ExpectInvalid(SetTrajectory(r), "trajectory.segments[0].duration_s");
  *r.mutable_trajectory() = good;
  r.mutable_trajectory()->mutable_segments(0)->mutable_x()->RemoveLast();
  ExpectInvalid(SetTrajectory(r), "trajectory.segments[0].x: 5 coefficients");
  *r.mutable_trajectory() = good;
  r.mutable_trajectory()->mutable_segments(0)->set_y(2, std::nan(""));
  ExpectInvalid(SetTrajectory(r), "trajectory.segments[0].y[2]: not finite");
  *r.mutable_trajectory() = good;
  r.mutable_trajectory()->set_duration_s(3.0);
  ExpectInvalid(SetTrajectory(r), "trajectory.duration_s");
  *r.mutable_trajectory() = good;
  r.mutable_trajectory()->set_yaw_policy(v1::YAW_POLICY_SEGMENT);
  ExpectInvalid(SetTrajectory(r), "trajectory.segments[0].yaw");
  *r.mutable_trajectory() = good;
  r.set_start_t_ns(-1);
  ExpectInvalid(SetTrajectory(r), "start_t_ns");
  r.set_start_t_ns(0);
  r.mutable_offset()->set_z(std::nan(""));
  ExpectInvalid(SetTrajectory(r), "offset.z: not finite");
  r.mutable_offset()->set_z(0);
  *r.mutable_trajectory() = Quintic(Eigen::Vector3d(5, 0, 1), Eigen::Vector3d(6, 0, 1), 2.0);
  ExpectInvalid(SetTrajectory(r), "trajectory: starts");  // 5 m from the reference
  EXPECT_EQ(GetStatus().mode(), v1::CONTROL_MODE_HOVER) << "nothing of this was applied";
}

TEST_F(ControlContractTest, SetTrajectoryFliesAnInlineSplineThenHovers) {
  v1::SetTrajectoryRequest r;
  *r.mutable_trajectory() = Quintic(Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(1, 0.5, 1.5), 3.0);
  EXPECT_EQ(SetTrajectory(r).error_code(), StatusCode::FAILED_PRECONDITION);  // not configured
  Airborne();
  v1::ControlStatus status;
  ASSERT_TRUE(SetTrajectory(r, &status).ok());
  EXPECT_EQ(status.mode(), v1::CONTROL_MODE_TRAJECTORY);
  Fly(1.5);
  v1::ControlState state = GetState();
  EXPECT_EQ(state.mode(), v1::CONTROL_MODE_TRAJECTORY);
  EXPECT_NEAR(state.trajectory_duration_s(), 3.0, 1e-12);
  EXPECT_NEAR(state.reference().position().x(), 0.5, 0.02);  // half way at half time
  Fly(4.0);
  state = GetState();
  EXPECT_EQ(state.mode(), v1::CONTROL_MODE_HOVER);
  EXPECT_NEAR(state.reference().position().y(), 0.5, 1e-9);
  EXPECT_NEAR(out_->truth.p_world.x(), 1.0, 0.1);
  EXPECT_NEAR(out_->truth.p_world.z(), 1.5, 0.1);
  EXPECT_TRUE(sim_->collisions().empty());
}

TEST_F(ControlContractTest, SetTrajectoryFetchesAPlanFromThePlanningService) {
  FakePlanning planning;
  transport::ServerOptions options;
  options.port = 0;
  auto server =
      transport::GrpcServer::Start(options, {&planning}, {v1::Planning::service_full_name()});
  ASSERT_TRUE(server.ok());
  const std::string address = (*server)->target();
  v1::SetTrajectoryRequest r;
  r.mutable_plan()->set_planning_address(address);
  r.mutable_plan()->set_plan_id("leg");
  EXPECT_EQ(SetTrajectory(r).error_code(), StatusCode::FAILED_PRECONDITION);  // not configured
  Airborne();
  v1::ControlStatus status;
  const grpc::Status ok = SetTrajectory(r, &status);
  ASSERT_TRUE(ok.ok()) << ok.error_message();
  EXPECT_EQ(status.mode(), v1::CONTROL_MODE_TRAJECTORY);
  Fly(0.1);
  EXPECT_NEAR(GetState().trajectory_duration_s(), 3.0, 1e-12);

  r.mutable_plan()->set_plan_id("nope");
  grpc::Status s = SetTrajectory(r);
  EXPECT_EQ(s.error_code(), StatusCode::NOT_FOUND) << s.error_message();
  EXPECT_TRUE(StartsWith(s.error_message(), "plan.plan_id:")) << s.error_message();
  r.mutable_plan()->set_plan_id("nopath");
  s = SetTrajectory(r);
  EXPECT_EQ(s.error_code(), StatusCode::FAILED_PRECONDITION) << s.error_message();
  EXPECT_NE(s.error_message().find("PLAN_STATUS_NO_PATH"), std::string::npos);
  r.mutable_plan()->set_plan_id("");
  ExpectInvalid(SetTrajectory(r), "plan.plan_id: empty");
  r.mutable_plan()->set_plan_id("leg");
  r.mutable_plan()->set_planning_address("");
  ExpectInvalid(SetTrajectory(r), "plan.planning_address: empty");
  // Too slow (800 ms against the service's 300 ms): UNAVAILABLE, not the client's deadline.
  r.mutable_plan()->set_planning_address(address);
  r.mutable_plan()->set_plan_id("slow");
  // The fake answers a plan after 800 ms with success: UNAVAILABLE shows that the service gave up
  // at its own timeout; a service that waited would have taken the plan (OK).
  s = SetTrajectory(r);
  EXPECT_EQ(s.error_code(), StatusCode::UNAVAILABLE) << s.error_message();
  EXPECT_NEAR(GetState().trajectory_duration_s(), 3.0, 1e-12) << "the flown leg is unchanged";
  // Nobody listening there.
  (*server)->Shutdown();
  server->reset();
  r.mutable_plan()->set_plan_id("leg");
  s = SetTrajectory(r);
  EXPECT_EQ(s.error_code(), StatusCode::UNAVAILABLE) << s.error_message();
  EXPECT_TRUE(StartsWith(s.error_message(), "plan: Planning.GetPlan at " + address))
      << s.error_message();
  EXPECT_EQ(GetState().trajectory_duration_s(), 3.0) << "the first plan is still flown";
}

// ---- SetGains
// -------------------------------------------------------------------------------------

TEST_F(ControlContractTest, SetGainsReplacesTheConfiguredControllersGains) {
  v1::SetGainsRequest r;
  ExpectInvalid(SetGains(r), "gains: set exactly one");
  r.mutable_gains()->set_attitude_omega_radps(14);
  EXPECT_EQ(SetGains(r).error_code(), StatusCode::FAILED_PRECONDITION);  // not configured
  ASSERT_TRUE(Configure(TaskRequest()).ok());
  v1::ControlStatus status;
  ASSERT_TRUE(SetGains(r, &status).ok());
  EXPECT_DOUBLE_EQ(status.config().gains().attitude_omega_radps(), 14);
  EXPECT_DOUBLE_EQ(status.config().gains().yaw_zeta(), 1.0) << "0 = the default";
  r.mutable_gains()->set_attitude_zeta(-1);
  ExpectInvalid(SetGains(r), "gains.attitude_zeta");
  r.mutable_gains()->set_attitude_zeta(0);
  r.mutable_lee_gains();
  ExpectInvalid(SetGains(r), "gains: set exactly one");
  r.clear_lee_gains();
  v1::SetGainsRequest lee;
  lee.mutable_lee_gains()->mutable_position_gain()->set_x(7);
  EXPECT_EQ(SetGains(lee).error_code(), StatusCode::FAILED_PRECONDITION);  // paper configured
  v1::ControlConfigureRequest lee_config = TaskRequest();
  lee_config.set_controller(v1::CONTROLLER_TYPE_LEE);
  ASSERT_TRUE(Configure(lee_config).ok());
  ASSERT_TRUE(SetGains(lee, &status).ok());
  EXPECT_DOUBLE_EQ(status.config().lee_gains().position_gain().x(), 7);
  EXPECT_DOUBLE_EQ(status.config().lee_gains().position_gain().y(), 6) << "0 = RotorS' value";
  EXPECT_EQ(SetGains(r).error_code(), StatusCode::FAILED_PRECONDITION);
  lee.mutable_lee_gains()->mutable_attitude_gain()->set_z(-0.1);
  ExpectInvalid(SetGains(lee), "lee_gains.attitude_gain");
}

// ---- Failsafes
// ------------------------------------------------------------------------------------

TEST_F(ControlContractTest, PosesStoppingMeansFailsafeAndADescent) {
  Airborne();
  const double z0 = out_->truth.p_world.z();
  Fly(2.0, /*poses=*/false);
  v1::ControlStatus status = GetStatus();
  EXPECT_EQ(status.mode(), v1::CONTROL_MODE_FAILSAFE);
  EXPECT_EQ(status.pose_timeouts(), 1u);
  EXPECT_TRUE(status.armed());
  EXPECT_LT(out_->truth.p_world.z(), z0 - 0.1) << "descending on the IMU";
  // Hover leaves the failsafe only with fresh poses.
  v1::HoverRequest hover;
  hover.mutable_position()->set_z(1.0);
  EXPECT_EQ(Hover(hover).error_code(), StatusCode::FAILED_PRECONDITION);
  Fly(0.3);
  ASSERT_TRUE(Hover(hover).ok());
  EXPECT_EQ(GetStatus().mode(), v1::CONTROL_MODE_HOVER);
}

TEST_F(ControlContractTest, TheImuWatchdogRunsOnTheWallClockUnlessLockstepped) {
  Airborne(/*lockstep=*/false);
  const size_t before = sink_.commands().size();
  // 50 ms without IMU: nothing; 150 ms: the motors-off policy disarms, and says so on the wire.
  core_->OnPoll(MonotonicNowNs() + 50'000'000, 1);
  EXPECT_TRUE(GetStatus().armed());
  core_->OnPoll(MonotonicNowNs() + 150'000'000, 1);
  v1::ControlStatus status = GetStatus();
  EXPECT_FALSE(status.armed());
  EXPECT_EQ(status.imu_timeouts(), 1u);
  ASSERT_EQ(sink_.commands().size(), before + 1);
  EXPECT_FALSE(sink_.last().armed);
  EXPECT_NE(status.last_error().find("no IMU sample"), std::string::npos);
  // Lock-step: a paused simulator is not a lost IMU.
  TearDown();
  SetUp();
  sim_.reset();
  Airborne(/*lockstep=*/true);
  core_->OnPoll(MonotonicNowNs() + 10'000'000'000, 1);
  status = GetStatus();
  EXPECT_TRUE(status.armed());
  EXPECT_EQ(status.imu_timeouts(), 0u);
  EXPECT_TRUE(status.config().lockstep());
  EXPECT_FALSE(status.estimator_stale()) << "paused";
  EXPECT_TRUE(status.estimator_converged());
  EXPECT_EQ(status.imu_publishers_alive(), 1u);
  // ... but a vanished one is (its IMU writer's DDS liveliness lapsed): stale, and the policy.
  core_->OnPoll(MonotonicNowNs(), 0);
  status = GetStatus();
  EXPECT_TRUE(status.estimator_stale());
  EXPECT_FALSE(status.estimator_converged());
  EXPECT_FALSE(status.armed());
  EXPECT_EQ(status.imu_timeouts(), 1u);
  EXPECT_NE(status.last_error().find("the IMU's publisher (the simulator) is gone"),
            std::string::npos)
      << status.last_error();
  EXPECT_GE(status.last_error_age_s(), 0.0);
  EXPECT_LT(status.last_error_age_s(), 5.0);
  EXPECT_TRUE(status.has_imu_age_s());
  EXPECT_TRUE(status.has_pose_age_s());
  EXPECT_FALSE(sink_.last().armed) << "said on the wire";
}

// ---- Deadlines and the loopback port
// --------------------------------------------------------------

TEST_F(ControlContractTest, ACallWhoseDeadlinePassedChangesNothing) {
  ASSERT_TRUE(Configure(TaskRequest()).ok());
  Fly(5.0);
  auto late = [](grpc::ClientContext* context) {
    context->set_deadline(std::chrono::system_clock::now() - std::chrono::seconds(1));
  };
  v1::ControlStatus ignored;
  {
    grpc::ClientContext context;
    late(&context);
    EXPECT_EQ(stub_->Arm(&context, v1::ArmRequest(), &ignored).error_code(),
              StatusCode::DEADLINE_EXCEEDED);
  }
  EXPECT_FALSE(GetStatus().armed());
  {
    grpc::ClientContext context;
    late(&context);
    v1::ControlConfigureRequest lee = TaskRequest();
    lee.set_controller(v1::CONTROLLER_TYPE_LEE);
    EXPECT_EQ(stub_->Configure(&context, lee, &ignored).error_code(),
              StatusCode::DEADLINE_EXCEEDED);
  }
  EXPECT_EQ(GetStatus().controller(), v1::CONTROLLER_TYPE_PAPER);
  ASSERT_TRUE(Arm().ok());
  for (int rpc = 0; rpc < 4; ++rpc) {
    grpc::ClientContext context;
    late(&context);
    grpc::Status s;
    if (rpc == 0) {
      v1::HoverRequest r;
      r.mutable_position()->set_z(3);
      s = stub_->Hover(&context, r, &ignored);
    } else if (rpc == 1) {
      v1::SetTrajectoryRequest r;
      *r.mutable_trajectory() = Quintic(Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, 1), 2);
      r.set_allow_jump(true);
      s = stub_->SetTrajectory(&context, r, &ignored);
    } else if (rpc == 2) {
      v1::SetGainsRequest r;
      r.mutable_gains()->set_attitude_omega_radps(14);
      s = stub_->SetGains(&context, r, &ignored);
    } else {
      s = stub_->Disarm(&context, v1::DisarmRequest(), &ignored);
    }
    EXPECT_EQ(s.error_code(), StatusCode::DEADLINE_EXCEEDED) << rpc;
  }
  Fly(0.1);
  const v1::ControlStatus status = GetStatus();
  EXPECT_TRUE(status.armed());
  EXPECT_EQ(status.mode(), v1::CONTROL_MODE_HOVER);
  EXPECT_DOUBLE_EQ(status.config().gains().attitude_omega_radps(), 12.0);
  EXPECT_EQ(GetState().trajectory_duration_s(), 0.0) << "holding where it armed, no move";
}

TEST_F(ControlContractTest, LoopbackPortAnswersHealthChecksAndRpcs) {
  auto channel = grpc::CreateChannel(server_->target(), grpc::InsecureChannelCredentials());
  auto health = transport::CheckHealth(channel, "mav.v1.Control", std::chrono::seconds(5));
  ASSERT_TRUE(health.ok()) << health.status().ToString();
  EXPECT_EQ(*health, transport::HealthStatus::kServing);
  auto stub = v1::Control::NewStub(channel);
  {
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    v1::ControlStatus status;
    const grpc::Status rpc = stub->Configure(&context, TaskRequest(true), &status);
    ASSERT_TRUE(rpc.ok()) << rpc.error_message();
    EXPECT_TRUE(status.configured());
  }
  {
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    v1::ControlStatus status;
    const grpc::Status rpc = stub->Arm(&context, v1::ArmRequest(), &status);
    EXPECT_EQ(rpc.error_code(), StatusCode::FAILED_PRECONDITION);
  }
  {
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    v1::ControlState state;
    ASSERT_TRUE(stub->GetState(&context, v1::ControlGetStateRequest(), &state).ok());
    EXPECT_TRUE(state.configured());
  }
  server_->Shutdown();
  auto after = transport::CheckHealth(channel, "", std::chrono::seconds(2));
  if (after.ok()) {
    EXPECT_NE(*after, transport::HealthStatus::kServing);
  }
}

}  // namespace
}  // namespace mav::control_service
