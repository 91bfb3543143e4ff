// The closed loop in the stack: the mav-simulator and mav-control binaries on free loopback ports
// and a private DDS domain, lock-stepped over DDS (the simulator publishes each step's poses, IMU
// and ground truth on mav/localization/pose, mav/sensors/imu, mav/sim/ground_truth and waits for
// the command mav-control answers on mav/control/actuators). The test plays the contest's mission
// client over gRPC: t3_1 (paper controller) is hovered inside the contest's limits (the
// simulator's own score of the ground truth), then a hand-made collision-free rest-to-rest quintic
// is flown in the open space through SetTrajectory, and tracked (ground truth against the
// spline, read here from mav/sim/ground_truth) with zero collisions. Then the contest's t4_3 in the
// power plant with mav-planning as a third process: the first leg planned by PlanPath on
// maps/power_plant.bt and flown through SetTrajectory{plan} (mav-control fetches it with
// Planning.GetPlan), with zero collisions against the plant, tracked, and ending at the goal.
//
// Figures it prints (docs/services.md quotes them): the hover's position and angular-rate RMS,
// the lock-step speed (simulated s per wall s), the simulator's wait for each command and the
// control service's step and loop times.

#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <map>
#include <optional>
#include <string>
#include <thread>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>

#include "mav/common/time.h"
#include "mav/sim/flight_task.h"
#include "mav/transport/dds.h"
#include "mav/v1/control.grpc.pb.h"
#include "mav/v1/planning.grpc.pb.h"
#include "mav/v1/simulator.grpc.pb.h"
#include "mav_state.h"
#include "services/control/convert.h"
#include "tests/common/build_paths.h"
#include "tests/common/stack_process.h"
#include "tests/common/test_domain.h"

namespace mav {
namespace {

const std::string kBinDir = mav::testing::BinaryDir() + "/bin";

using ::mav::test_support::Child;
using ::mav::test_support::FreeTcpPort;
using ::mav::test_support::TestDomain;
using ::mav::test_support::WaitServing;

std::chrono::system_clock::time_point Deadline(double seconds) {
  return std::chrono::system_clock::now() +
         std::chrono::milliseconds(static_cast<int64_t>(seconds * 1000));
}

// The hover task, 15 s longer so that the leg is flown after the scored window (15-25 s).
constexpr char kTaskYaml[] = "base: t3_1\nname: t3_1_then_leg\nduration_s: 40\n";
constexpr double kLegStartS = 25.0;
constexpr double kLegDurationS = 4.0;
const Eigen::Vector3d kLegFrom(0, 0, 1);
const Eigen::Vector3d kLegTo(3, 2, 2.5);

// p(tau) = a + (b - a) (10 u^3 - 15 u^4 + 6 u^5), u = tau / T.
Eigen::Vector3d LegAt(double tau_s) {
  const double u = std::clamp(tau_s / kLegDurationS, 0.0, 1.0);
  return kLegFrom + (kLegTo - kLegFrom) * (u * u * u * (10 - 15 * u + 6 * u * u));
}

v1::PolynomialTrajectory Leg() {
  v1::PolynomialTrajectory out;
  v1::PolynomialSegment* s = out.add_segments();
  const double t = kLegDurationS;
  s->set_duration_s(t);
  google::protobuf::RepeatedField<double>* axes[3] = {s->mutable_x(), s->mutable_y(),
                                                      s->mutable_z()};
  for (int k = 0; k < 3; ++k) {
    const double d = kLegTo[k] - kLegFrom[k];
    for (double c : {kLegFrom[k], 0.0, 0.0, 10 * d / std::pow(t, 3), -15 * d / std::pow(t, 4),
                     6 * d / std::pow(t, 5)}) {
      axes[k]->Add(c);
    }
  }
  out.set_duration_s(t);
  return out;
}

class ControlStackTest : public ::testing::Test {
 protected:
  void SetUp() override {
    domain_ = TestDomain(41);
    const int sim_port = FreeTcpPort();
    int ctl_port = FreeTcpPort();
    while (ctl_port == sim_port) ctl_port = FreeTcpPort();
    sim_target_ = "127.0.0.1:" + std::to_string(sim_port);
    ctl_target_ = "127.0.0.1:" + std::to_string(ctl_port);
    const std::string logs = mav::testing::BinaryDir() + "/Testing";
    std::system(("mkdir -p " + logs).c_str());
    const std::string tag = std::to_string(::getpid());
    sim_log_ = logs + "/control-stack-simulator-" + tag + ".log";
    ctl_log_ = logs + "/control-stack-control-" + tag + ".log";
    simulator_ = std::make_unique<Child>(
        std::vector<std::string>{kBinDir + "/mav-simulator", "--port", std::to_string(sim_port),
                                 "--dds-domain", std::to_string(domain_)},
        sim_log_);
    control_ = std::make_unique<Child>(
        std::vector<std::string>{kBinDir + "/mav-control", "--port", std::to_string(ctl_port),
                                 "--dds-domain", std::to_string(domain_)},
        ctl_log_);
    ASSERT_TRUE(simulator_->running() && control_->running());
    ASSERT_TRUE(WaitServing(sim_target_, "mav.v1.Simulator")) << "see " << sim_log_;
    ASSERT_TRUE(WaitServing(ctl_target_, "mav.v1.Control")) << "see " << ctl_log_;
    sim_ = v1::Simulator::NewStub(
        grpc::CreateChannel(sim_target_, grpc::InsecureChannelCredentials()));
    ctl_ =
        v1::Control::NewStub(grpc::CreateChannel(ctl_target_, grpc::InsecureChannelCredentials()));
  }

  v1::FlightStatus FlightStatus() {
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    v1::FlightStatus s;
    EXPECT_TRUE(sim_->GetFlightStatus(&context, v1::GetFlightStatusRequest(), &s).ok());
    return s;
  }
  v1::ControlStatus ControlStatus() {
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    v1::ControlStatus s;
    EXPECT_TRUE(ctl_->GetStatus(&context, v1::ControlGetStatusRequest(), &s).ok());
    return s;
  }
  // Starts the flight and waits (at most 30 s) until it pauses or ends.
  v1::FlightStatus Run(double until_s, bool pause_on_goal) {
    {
      v1::StartFlightRequest request;
      request.set_run_until_s(until_s);
      request.set_pause_on_goal(pause_on_goal);
      grpc::ClientContext context;
      context.set_deadline(Deadline(5));
      v1::FlightStatus s;
      const grpc::Status rpc = sim_->StartFlight(&context, request, &s);
      EXPECT_TRUE(rpc.ok()) << rpc.error_message();
    }
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    v1::FlightStatus s = FlightStatus();
    while (s.state() == v1::FLIGHT_STATE_RUNNING && std::chrono::steady_clock::now() < give_up) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      s = FlightStatus();
    }
    EXPECT_NE(s.state(), v1::FLIGHT_STATE_RUNNING) << "still running after 30 s";
    EXPECT_TRUE(s.last_error().empty()) << s.last_error() << " (see " << sim_log_ << ")";
    return s;
  }
  // mav-control configured with what the contest told the teams about the task.
  void ConfigureFor(const std::string& task_name, bool lockstep) {
    Result<dataset::FlightTask> task =
        sim::FlightTaskFromSpec(task_name, sim::DefaultPlantMapPath());
    ASSERT_TRUE(task.ok()) << task.status().ToString();
    v1::ControlConfigureRequest request;
    control_service::ToProto(
        control_service::ConfigForFlightTask(*task, control::ControllerType::kPaper, lockstep),
        &request);
    grpc::ClientContext context;
    context.set_deadline(Deadline(10));
    v1::ControlStatus s;
    const grpc::Status rpc = ctl_->Configure(&context, request, &s);
    ASSERT_TRUE(rpc.ok()) << rpc.error_message();
    ASSERT_TRUE(s.dds_input());
  }
  // Waits (15 s at most) until the simulator and the controller have matched each other's writers
  // and readers, then a moment more for the pose reader (Cyclone matches the readers of one
  // participant one after the other).
  void WaitForDiscovery() {
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(15);
    while (std::chrono::steady_clock::now() < give_up) {
      grpc::ClientContext context;
      context.set_deadline(Deadline(5));
      v1::SimulatorStatus replay;
      ASSERT_TRUE(sim_->GetStatus(&context, v1::SimulatorGetStatusRequest(), &replay).ok());
      if (replay.imu_subscribers() >= 1 && FlightStatus().actuator_writers() >= 1 &&
          ControlStatus().actuator_subscribers() >= 1) {
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  // This test's ground-truth subscriber (every sample, kept until taken).
  void SubscribeGroundTruth() {
    transport::DdsOptions options;
    options.domain = domain_;
    auto participant = transport::Participant::Create(options);
    ASSERT_TRUE(participant.ok()) << participant.status().ToString();
    participant_.emplace(std::move(*participant));
    auto topic = transport::Topic<mav_dds_GroundTruthState>::Create(
        *participant_, transport::kGroundTruthTopic, &mav_dds_GroundTruthState_desc);
    ASSERT_TRUE(topic.ok());
    gt_topic_.emplace(std::move(*topic));
    auto reader = transport::Reader<mav_dds_GroundTruthState>::Create(
        *participant_, *gt_topic_, transport::Qos::State().KeepAll());
    ASSERT_TRUE(reader.ok());
    gt_reader_.emplace(std::move(*reader));
    ASSERT_TRUE(gt_reader_->WaitForWriters(1, 15 * kNsPerSecond).ok());
  }
  // Every ground-truth position received so far, by time stamp.
  std::map<int64_t, Eigen::Vector3d> TakeGroundTruth() {
    std::map<int64_t, Eigen::Vector3d> truth;
    while (true) {
      auto samples = gt_reader_->Take(512);
      EXPECT_TRUE(samples.ok());
      if (!samples.ok()) break;
      for (int32_t i = 0; i < samples->size(); ++i) {
        if (!samples->valid(i)) continue;
        const mav_dds_GroundTruthState& g = (*samples)[i];
        truth[g.t_ns] = Eigen::Vector3d(g.position.x, g.position.y, g.position.z);
      }
      if (samples->size() < 512) break;
    }
    return truth;
  }
  // Loads a flight task into the simulator.
  void LoadFlightTask(const v1::LoadFlightTaskRequest& request, double deadline_s,
                      v1::FlightStatus* loaded) {
    grpc::ClientContext context;
    context.set_deadline(Deadline(deadline_s));
    const grpc::Status rpc = sim_->LoadFlightTask(&context, request, loaded);
    ASSERT_TRUE(rpc.ok()) << rpc.error_message();
  }
  // Hands mav-control a leg to fly, which it must take (trajectory mode).
  void SetTrajectory(const v1::SetTrajectoryRequest& request) {
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    v1::ControlStatus leg;
    const grpc::Status rpc = ctl_->SetTrajectory(&context, request, &leg);
    ASSERT_TRUE(rpc.ok()) << rpc.error_message();
    EXPECT_EQ(leg.mode(), v1::CONTROL_MODE_TRAJECTORY);
  }
  // Arms, takes off to `p` and flies until the task publishes its first goal: the flight pauses
  // there (*s).
  void TakeOffUntilTheFirstGoal(const Eigen::Vector3d& p, v1::FlightStatus* s) {
    ASSERT_NO_FATAL_FAILURE(Arm());
    ASSERT_TRUE(Hover(p).ok());
    *s = Run(0, true);
    ASSERT_EQ(s->state(), v1::FLIGHT_STATE_PAUSED);
    ASSERT_EQ(s->goal_index(), 0) << s->pause_reason();
  }
  void Arm() {
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    v1::ControlStatus armed;
    const grpc::Status rpc = ctl_->Arm(&context, v1::ArmRequest(), &armed);
    ASSERT_TRUE(rpc.ok()) << rpc.error_message();
  }
  grpc::Status Hover(const Eigen::Vector3d& p) {
    v1::HoverRequest request;
    request.mutable_position()->set_x(p.x());
    request.mutable_position()->set_y(p.y());
    request.mutable_position()->set_z(p.z());
    // mav-eval's take-off limits (eval::FlightMissionOptions::takeoff_limits).
    request.mutable_limits()->set_max_speed_mps(1.5);
    request.mutable_limits()->set_max_accel_mps2(2.0);
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    v1::ControlStatus s;
    return ctl_->Hover(&context, request, &s);
  }

  // Real time: loads `request`, configures mav-control for t3_1, starts the flight once the two
  // have discovered each other, arms as soon as the estimator has converged and takes off to
  // `hover` (by `give_up` at the latest).
  void FlyInRealTime(const v1::LoadFlightTaskRequest& request, const Eigen::Vector3d& hover,
                     std::chrono::steady_clock::time_point give_up) {
    v1::FlightStatus loaded;
    ASSERT_NO_FATAL_FAILURE(LoadFlightTask(request, 10, &loaded));
    ConfigureFor("t3_1", /*lockstep=*/false);
    while (FlightStatus().actuator_writers() == 0 && std::chrono::steady_clock::now() < give_up) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(300));  // the IMU and pose readers
    {
      grpc::ClientContext context;
      context.set_deadline(Deadline(5));
      v1::FlightStatus s;
      ASSERT_TRUE(sim_->StartFlight(&context, v1::StartFlightRequest(), &s).ok());
    }
    while (!ControlStatus().estimator_converged() && std::chrono::steady_clock::now() < give_up) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    ASSERT_NO_FATAL_FAILURE(Arm());
    ASSERT_TRUE(Hover(hover).ok());
  }
  // Kills the simulator and waits (wall clock) until mav-control reports the loss: the estimate
  // stale, not converged, no IMU publisher alive, last_error naming it, and (lock-step or not)
  // disarmed. Returns the wall seconds it took (<= 1 s expected), or a large value.
  double KillTheSimulatorAndTimeTheReport() {
    simulator_->Signal(SIGKILL);
    const int64_t killed_ns = MonotonicNowNs();
    v1::ControlStatus c;
    while (NsToSeconds(MonotonicNowNs() - killed_ns) < 5.0) {
      c = ControlStatus();
      if (c.estimator_stale() && !c.armed()) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    const double took_s = NsToSeconds(MonotonicNowNs() - killed_ns);
    EXPECT_TRUE(c.estimator_stale());
    EXPECT_FALSE(c.estimator_converged()) << "a stale estimate is not claimed converged";
    EXPECT_EQ(c.imu_publishers_alive(), 0u);
    EXPECT_FALSE(c.armed());
    EXPECT_NE(c.last_error().find("gone"), std::string::npos) << c.last_error();
    EXPECT_LT(c.last_error_age_s(), 5.0);
    return took_s;
  }

  int64_t domain_ = 0;
  std::string sim_target_, ctl_target_, sim_log_, ctl_log_;
  std::unique_ptr<Child> simulator_, control_;
  std::unique_ptr<v1::Simulator::Stub> sim_;
  std::unique_ptr<v1::Control::Stub> ctl_;
  std::optional<transport::Participant> participant_;
  std::optional<transport::Topic<mav_dds_GroundTruthState>> gt_topic_;
  std::optional<transport::Reader<mav_dds_GroundTruthState>> gt_reader_;
};

TEST_F(ControlStackTest, HoverInsideTheContestLimitsThenFlyALegWithoutCollision) {
  const int64_t test_start_ns = MonotonicNowNs();
  {
    v1::LoadFlightTaskRequest request;
    request.set_yaml(kTaskYaml);
    request.set_seed(1000);
    request.set_lockstep(true);
    v1::FlightStatus loaded;
    ASSERT_NO_FATAL_FAILURE(LoadFlightTask(request, 10, &loaded));
    ASSERT_EQ(loaded.task().pose_sensors_size(), 1);
  }
  ConfigureFor("t3_1", /*lockstep=*/true);  // the yaml changes only the duration

  SubscribeGroundTruth();
  if (HasFatalFailure()) return;

  // Discovery both ways before the first step: the simulator sees the controller's command
  // writer, the controller sees the simulator's IMU and pose writers.
  WaitForDiscovery();

  const int64_t flight_start_ns = MonotonicNowNs();
  // The mission, as mav-eval's script: arm once converged (4 s after the first pose), take off,
  // hover at the set point when it is published (10 s).
  v1::FlightStatus s = Run(5.0, false);
  ASSERT_EQ(s.state(), v1::FLIGHT_STATE_PAUSED);
  ASSERT_EQ(s.steps(), 500u);
  v1::ControlStatus c = ControlStatus();
  ASSERT_TRUE(c.estimator_converged()) << c.DebugString();
  ASSERT_NO_FATAL_FAILURE(TakeOffUntilTheFirstGoal(Eigen::Vector3d(0, 0, 1), &s));
  ASSERT_TRUE(s.lifted_off());
  ASSERT_TRUE(Hover(Eigen::Vector3d(0, 0, 1)).ok());
  s = Run(kLegStartS, false);
  ASSERT_EQ(s.state(), v1::FLIGHT_STATE_PAUSED);
  {
    v1::SetTrajectoryRequest request;
    *request.mutable_trajectory() = Leg();
    ASSERT_NO_FATAL_FAILURE(SetTrajectory(request));
  }
  s = Run(0, false);
  const double flight_wall_s = NsToSeconds(MonotonicNowNs() - flight_start_ns);
  ASSERT_EQ(s.state(), v1::FLIGHT_STATE_FINISHED) << s.pause_reason();

  // The contest's hover score, on the simulator's ground truth.
  ASSERT_TRUE(s.has_score());
  const v1::FlightScore& score = s.score();
  EXPECT_EQ(score.collisions(), 0u);
  EXPECT_EQ(s.collisions_size(), 0);
  EXPECT_LT(score.position_rms_m(), 0.2) << "the contest's limit";
  EXPECT_LT(score.angular_rate_rms_radps(), 0.2) << "the contest's limit";
  EXPECT_GT(score.points(), 0);
  // Every step answered: no timeout, nothing stale or rejected, one command per IMU sample.
  EXPECT_EQ(s.steps(), 4000u);
  EXPECT_EQ(s.commands_rejected(), 0u);
  EXPECT_EQ(s.stale_steps(), 0u);
  c = ControlStatus();
  EXPECT_EQ(c.imu_repeated(), 0u);
  EXPECT_EQ(c.imu_rejected(), 0u);
  EXPECT_EQ(c.poses_rejected(), 0u);
  EXPECT_EQ(c.poses_dropped(), 0u);
  EXPECT_EQ(c.imu_samples(), s.imu_published());
  EXPECT_EQ(c.commands(), s.imu_published());
  EXPECT_EQ(c.poses(), s.poses_published());
  EXPECT_EQ(c.mode(), v1::CONTROL_MODE_HOVER) << "the leg ended, holding its end";

  // The leg, tracked: ground truth against the spline, and where it ended.
  const std::map<int64_t, Eigen::Vector3d> truth = TakeGroundTruth();
  EXPECT_EQ(truth.size(), s.ground_truth_published()) << "every ground-truth sample arrived";
  double max_leg_error = 0, sum_sq = 0;
  int leg_samples = 0;
  for (const auto& [t_ns, p] : truth) {
    const double tau = NsToSeconds(t_ns) - kLegStartS;
    if (tau < 0 || tau > kLegDurationS + 1.0) continue;
    const double e = (p - LegAt(tau)).norm();
    max_leg_error = std::max(max_leg_error, e);
    sum_sq += e * e;
    ++leg_samples;
  }
  ASSERT_GT(leg_samples, 400);
  EXPECT_LT(max_leg_error, 0.25);
  EXPECT_NEAR((truth.rbegin()->second - kLegTo).norm(), 0.0, 0.1);
  EXPECT_NEAR(
      (Eigen::Vector3d(s.position().x(), s.position().y(), s.position().z()) - kLegTo).norm(), 0.0,
      0.1);

  const double simulated_s = NsToSeconds(s.t_ns());
  std::cout << "hover (t3_1, seed 1000): position RMS " << score.position_rms_m()
            << " m, angular-rate RMS " << score.angular_rate_rms_radps() << " rad/s, "
            << score.points() << " of " << score.max_points() << " points\n"
            << "leg (" << (kLegTo - kLegFrom).norm() << " m in " << kLegDurationS
            << " s): ground truth vs spline RMS " << std::sqrt(sum_sq / leg_samples) << " m, max "
            << max_leg_error << " m; 0 collisions\n"
            << "lock-step over DDS: " << simulated_s << " s simulated in " << flight_wall_s
            << " s wall incl. the mission's RPCs (" << simulated_s / flight_wall_s
            << "x); last run " << s.speed_factor() << "x; command wait mean "
            << s.command_wait_ms().mean_ms() << " ms, p95 " << s.command_wait_ms().p95_ms()
            << " ms, max " << s.command_wait_ms().max_ms() << " ms\n"
            << "mav-control: step mean " << c.step_ms().mean_ms() << " ms, p95 "
            << c.step_ms().p95_ms() << " ms; loop (sample in -> command written) mean "
            << c.loop_ms().mean_ms() << " ms, p95 " << c.loop_ms().p95_ms() << " ms\n"
            << "test wall time " << NsToSeconds(MonotonicNowNs() - test_start_ns) << " s\n";
  // A lock-stepped controller whose simulator vanished (not paused) says so within 1 s.
  const double report_s = KillTheSimulatorAndTimeTheReport();
  EXPECT_LT(report_s, 1.0);
  std::cout << "lock-step: the simulator SIGKILLed, mav-control reported it in " << report_s
            << " s\n";
  RecordProperty("hover_position_rms_m", std::to_string(score.position_rms_m()));
  RecordProperty("hover_angular_rate_rms_radps", std::to_string(score.angular_rate_rms_radps()));
  RecordProperty("lockstep_speed_factor", std::to_string(s.speed_factor()));
}

// t4_3's first leg through the whole stack: mav-planning (a third process) plans it on the
// contest's map from the take-off point to the first goal with the Firefly's limits, mav-control
// fetches the plan by its id and flies it, mav-simulator flies the vehicle in the OctoMap world
// and reports any contact. The leg must be flown without a collision, tracked (ground truth
// against the plan's own samples) and end in the goal's 0.1 m ball.
TEST_F(ControlStackTest, PlannedT4_3LegFlownThroughThePlanningService) {
  // mav-planning's default, given explicitly: the roadmap file below was built with it.
  constexpr double kPlannerRobotRadiusM = 0.5;
  const int64_t test_start_ns = MonotonicNowNs();
  int plan_port = FreeTcpPort();
  while ("127.0.0.1:" + std::to_string(plan_port) == sim_target_ ||
         "127.0.0.1:" + std::to_string(plan_port) == ctl_target_) {
    plan_port = FreeTcpPort();
  }
  const std::string plan_target = "127.0.0.1:" + std::to_string(plan_port);
  const std::string plan_log = mav::testing::BinaryDir() + "/Testing/control-stack-planning-" +
                               std::to_string(::getpid()) + ".log";
  // A 20 000-milestone roadmap, built once into build/Testing and loaded afterwards (~3 s to
  // build on 2 cores; the default 100 000 takes ~15 s).
  Child planning(
      {kBinDir + "/mav-planning", "--port", std::to_string(plan_port), "--map",
       sim::DefaultPlantMapPath(), "--robot-radius", std::to_string(kPlannerRobotRadiusM),
       "--roadmap", mav::testing::BinaryDir() + "/Testing/control_stack_plant_20k.mavprm",
       "--roadmap-milestones", "20000"},
      plan_log);
  ASSERT_TRUE(planning.running());
  ASSERT_TRUE(WaitServing(plan_target, "mav.v1.Planning")) << "see " << plan_log;
  auto planner =
      v1::Planning::NewStub(grpc::CreateChannel(plan_target, grpc::InsecureChannelCredentials()));

  {
    v1::LoadFlightTaskRequest request;
    request.set_builtin("t4_3");
    request.set_seed(1002);
    request.set_lockstep(true);
    v1::FlightStatus loaded;
    ASSERT_NO_FATAL_FAILURE(LoadFlightTask(request, 20, &loaded));
  }
  ConfigureFor("t4_3", /*lockstep=*/true);
  SubscribeGroundTruth();
  if (HasFatalFailure()) return;
  WaitForDiscovery();

  // The mission as mav-eval flies it: arm once converged, take off to (0, 0, 2), and when the
  // first goal is published (10 s) plan the leg from the reference to it.
  v1::FlightStatus s = Run(5.0, false);
  ASSERT_EQ(s.state(), v1::FLIGHT_STATE_PAUSED);
  const Eigen::Vector3d takeoff(0, 0, 2);
  ASSERT_NO_FATAL_FAILURE(TakeOffUntilTheFirstGoal(takeoff, &s));
  ASSERT_EQ(s.collisions_size(), 0) << s.collisions(0).what();
  const Eigen::Vector3d goal(2, -27, 15);  // t4_3's first goal (docs/control.md)
  const double leg_start_s = NsToSeconds(s.t_ns());

  v1::PlanPathRequest plan_request;
  plan_request.mutable_start()->set_x(takeoff.x());
  plan_request.mutable_start()->set_y(takeoff.y());
  plan_request.mutable_start()->set_z(takeoff.z());
  plan_request.mutable_goal()->set_x(goal.x());
  plan_request.mutable_goal()->set_y(goal.y());
  plan_request.mutable_goal()->set_z(goal.z());
  plan_request.set_sample_dt_s(0.01);
  v1::PlanPathResponse plan;
  {
    grpc::ClientContext context;
    context.set_deadline(Deadline(10));
    const grpc::Status rpc = planner->PlanPath(&context, plan_request, &plan);
    ASSERT_TRUE(rpc.ok()) << rpc.error_message();
  }
  ASSERT_EQ(plan.status(), v1::PLAN_STATUS_SUCCESS) << plan.message();
  ASSERT_FALSE(plan.plan_id().empty());
  ASSERT_GT(plan.samples_size(), 100);
  // The leg keeps the robot radius the planner was given at every 1 cm check sample.
  EXPECT_GE(plan.trajectory_min_clearance_m(), kPlannerRobotRadiusM);
  {
    v1::SetTrajectoryRequest request;
    request.mutable_plan()->set_planning_address(plan_target);
    request.mutable_plan()->set_plan_id(plan.plan_id());
    ASSERT_NO_FATAL_FAILURE(SetTrajectory(request));
  }
  // The leg and 6 s of hover at its end.
  s = Run(leg_start_s + plan.duration_s() + 6.0, false);
  ASSERT_EQ(s.state(), v1::FLIGHT_STATE_PAUSED) << s.pause_reason();
  EXPECT_EQ(s.collisions_size(), 0)
      << (s.collisions_size() > 0 ? s.collisions(0).what() : std::string());
  EXPECT_EQ(s.stale_steps(), 0u);
  EXPECT_EQ(s.commands_rejected(), 0u);
  const Eigen::Vector3d end(s.position().x(), s.position().y(), s.position().z());
  EXPECT_LT((end - goal).norm(), 0.1) << "the leg ends in the goal's ball";
  const v1::ControlStatus c = ControlStatus();
  EXPECT_EQ(c.mode(), v1::CONTROL_MODE_HOVER) << "the leg ended, holding its end";

  // Tracking: the ground truth of the leg against the plan's samples (the leg starts at the
  // next control step after SetTrajectory, i.e. at leg_start_s).
  const std::map<int64_t, Eigen::Vector3d> truth = TakeGroundTruth();
  EXPECT_EQ(truth.size(), s.ground_truth_published()) << "every ground-truth sample arrived";
  const double dt_s = plan_request.sample_dt_s();
  double max_error = 0, sum_sq = 0, peak_speed = 0;
  int n = 0;
  for (const auto& [t_ns, p] : truth) {
    const double tau = NsToSeconds(t_ns) - leg_start_s;
    if (tau < 0 || tau > plan.duration_s()) continue;
    const int i = std::min(static_cast<int>(std::lround(tau / dt_s)), plan.samples_size() - 1);
    const v1::TrajectorySample& q = plan.samples(i);
    const double e =
        (p - Eigen::Vector3d(q.position().x(), q.position().y(), q.position().z())).norm();
    max_error = std::max(max_error, e);
    sum_sq += e * e;
    ++n;
  }
  for (const v1::TrajectorySample& q : plan.samples()) {
    peak_speed = std::max(
        peak_speed, Eigen::Vector3d(q.velocity().x(), q.velocity().y(), q.velocity().z()).norm());
  }
  ASSERT_GT(n, 100);
  // One control step of timing slack at 10 m/s is 0.1 m; the paper controller tracks within cm.
  EXPECT_LT(max_error, 0.3);
  std::cout << "t4_3 leg 1 (seed 1002): planned " << plan.trajectory_length_m() << " m in "
            << plan.duration_s() << " s (mean " << plan.mean_speed_mps() << " m/s, peak "
            << peak_speed << " m/s, min clearance " << plan.trajectory_min_clearance_m() << " m, "
            << plan.timings().total_ms() << " ms); ground truth vs plan RMS "
            << std::sqrt(sum_sq / n) << " m, max " << max_error << " m; ended "
            << (end - goal).norm() << " m from the goal, " << s.collisions_size()
            << " collisions; test wall time " << NsToSeconds(MonotonicNowNs() - test_start_ns)
            << " s\n";
}

// Real time: the simulator flies the newest command; when mav-control dies, its last command goes
// stale after 100 ms (simulated) and the vehicle's own failsafe takes over: level, 0.4 m/s down,
// a landing, motors off (docs/contracts.md). Before the failsafe the vehicle fell and hit the
// ground at ~4 m/s.
TEST_F(ControlStackTest, InRealTimeAKilledControllerLeavesTheVehicleToItsFailsafe) {
  v1::LoadFlightTaskRequest request;
  request.set_builtin("t3_1");
  request.set_seed(1001);
  request.set_real_time_factor(5);
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(15);
  ASSERT_NO_FATAL_FAILURE(FlyInRealTime(request, Eigen::Vector3d(0, 0, 1), give_up));
  auto wait_for_time = [&](double t_s) {
    v1::FlightStatus s = FlightStatus();
    while (NsToSeconds(s.t_ns()) < t_s && s.state() == v1::FLIGHT_STATE_RUNNING &&
           std::chrono::steady_clock::now() < give_up) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      s = FlightStatus();
    }
    return s;
  };
  v1::FlightStatus s = wait_for_time(8.0);
  ASSERT_EQ(s.state(), v1::FLIGHT_STATE_RUNNING);
  ASSERT_TRUE(s.lifted_off());
  EXPECT_NEAR(s.position().z(), 1.0, 0.15) << "hovering in real time";
  const uint64_t stale_before = s.stale_steps();
  EXPECT_EQ(s.failsafe_engagements(), 0u);
  control_->Signal(SIGKILL);
  s = wait_for_time(NsToSeconds(s.t_ns()) + 1.0);
  EXPECT_TRUE(s.failsafe_active()) << "a second after the controller died";
  EXPECT_GT(s.stale_steps(), stale_before + 80);
  EXPECT_GT(s.position().z(), 0.4) << "descending, not falling";
  s = wait_for_time(NsToSeconds(s.t_ns()) + 2.5);
  EXPECT_FALSE(s.failsafe_active()) << "landed";
  EXPECT_EQ(s.failsafe_engagements(), 1u);
  EXPECT_LT(s.position().z(), 0.1) << "on its legs";
  EXPECT_EQ(s.collisions_size(), 0)
      << "a landing, not a collision: " << (s.collisions_size() > 0 ? s.collisions(0).what() : "");
  std::cout << "real time x5: the controller killed at 1 m; the failsafe flew " << s.failsafe_s()
            << " s and landed the vehicle, z = " << s.position().z() << " m, no collision\n";
}

// Real time (x1): hovering at 2 m, mav-control SIGKILLed; the vehicle's failsafe descends it; 1 s
// later mav-control is restarted with --task t3_1 --takeover: it initialises its estimator from
// the live streams and arms in the air. The vehicle must never come near the ground and hover
// again within 3 s of the restart. Then the simulator is killed: mav-control reports the loss
// (stale, not converged) within 1 s.
TEST_F(ControlStackTest, InRealTimeARestartedControllerTakesOverTheVehicleInTheAir) {
  v1::LoadFlightTaskRequest request;
  request.set_yaml(kTaskYaml);
  request.set_seed(1003);
  request.set_real_time_factor(1);
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(40);
  ASSERT_NO_FATAL_FAILURE(FlyInRealTime(request, Eigen::Vector3d(0, 0, 2), give_up));
  v1::FlightStatus s = FlightStatus();
  while (NsToSeconds(s.t_ns()) < 11.0 && std::chrono::steady_clock::now() < give_up) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    s = FlightStatus();
  }
  ASSERT_EQ(s.state(), v1::FLIGHT_STATE_RUNNING);
  ASSERT_NEAR(s.position().z(), 2.0, 0.15) << "hovering at 2 m";

  control_->Signal(SIGKILL);
  const double killed_at_s = NsToSeconds(s.t_ns());
  double min_z = s.position().z();
  auto watch_until = [&](double wall_s) {
    const int64_t until_ns = MonotonicNowNs() + static_cast<int64_t>(wall_s * 1e9);
    while (MonotonicNowNs() < until_ns) {
      s = FlightStatus();
      min_z = std::min(min_z, s.position().z());
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  };
  watch_until(1.0);
  EXPECT_TRUE(s.failsafe_active()) << "the vehicle's own failsafe flies it";
  ASSERT_EQ(control_->Wait(std::chrono::milliseconds(1000)), 128 + SIGKILL);
  const int ctl_port = std::stoi(ctl_target_.substr(ctl_target_.rfind(':') + 1));
  control_ = std::make_unique<Child>(
      std::vector<std::string>{kBinDir + "/mav-control", "--port", std::to_string(ctl_port),
                               "--dds-domain", std::to_string(domain_), "--task", "t3_1",
                               "--takeover"},
      ctl_log_ + ".restarted");
  const double restarted_at_s = NsToSeconds(FlightStatus().t_ns());
  watch_until(3.0);
  const double z_back = s.position().z();
  const Eigen::Vector3d v(s.truth().velocity().x(), s.truth().velocity().y(),
                          s.truth().velocity().z());
  const v1::ControlStatus c = ControlStatus();
  EXPECT_TRUE(c.armed()) << c.last_error() << " (see " << ctl_log_ << ".restarted)";
  EXPECT_EQ(c.mode(), v1::CONTROL_MODE_HOVER);
  EXPECT_FALSE(c.takeover_pending());
  EXPECT_FALSE(c.estimator_stale());
  v1::ControlState state;
  {
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    ASSERT_TRUE(ctl_->GetState(&context, v1::ControlGetStateRequest(), &state).ok());
  }
  EXPECT_FALSE(state.moving()) << "the stop trajectory is flown: holding";
  const Eigen::Vector3d hold(state.reference().position().x(), state.reference().position().y(),
                             state.reference().position().z());
  const Eigen::Vector3d p_true(s.position().x(), s.position().y(), s.position().z());
  EXPECT_LT((p_true - hold).norm(), 0.15) << "at the hold point";
  EXPECT_FALSE(s.failsafe_active()) << "the restarted controller flies it";
  EXPECT_EQ(s.failsafe_engagements(), 1u);
  EXPECT_LT(v.norm(), 0.15) << "hovering again 3 s after the restart";
  EXPECT_GT(min_z, 0.6) << "never near the ground";
  EXPECT_EQ(s.collisions_size(), 0);
  std::cout << "real time x1: mav-control killed at " << killed_at_s << " s at 2 m, restarted at "
            << restarted_at_s << " s (--takeover); the failsafe flew " << s.failsafe_s()
            << " s; lowest " << min_z << " m; 3 s after the restart at " << z_back << " m, "
            << (p_true - hold).norm() << " m from the hold, speed " << v.norm() << " m/s\n";
  RecordProperty("takeover_min_z_m", std::to_string(min_z));

  const double report_s = KillTheSimulatorAndTimeTheReport();
  EXPECT_LT(report_s, 1.0);
  std::cout << "real time: the simulator SIGKILLed, mav-control reported it in " << report_s
            << " s\n";
}

}  // namespace
}  // namespace mav
