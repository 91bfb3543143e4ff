// Contract of mav.v1.Simulator's flight mode (protos/mav/v1/simulator.proto, docs/contracts.md
// "Simulator: flight mode"): LoadFlightTask, StartFlight, PauseFlight, GetFlightStatus with good
// and bad input through an in-process channel and a real loopback port, deadlines, the lock-step
// wait and its timeout, stale and malformed commands, and the score at the end. The DDS side is
// replaced by a fake FlightIo that records what is published and plays the controller: silent,
// motors off, malformed, or libs/control's Autopilot with mav-eval's mission script, so that the
// service's flight can be compared with eval::FlyTask on the same seed (the same code path: the
// same score to the last bit). tests/integration/control_stack_test.cc flies it over DDS.

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>

#include "mav/common/time.h"
#include "mav/control/autopilot.h"
#include "mav/eval/flight_mission.h"
#include "mav/sim/flight_task.h"
#include "mav/sim/scenario_source.h"
#include "mav/transport/grpc_server.h"
#include "mav/v1/simulator.grpc.pb.h"
#include "services/simulator/dds_io.h"
#include "services/simulator/simulator_service.h"
#include "tests/common/contract_server.h"
#include "tests/common/grpc_expect.h"
#include "tests/common/null_stream_sink.h"

namespace mav::simulator_service {
namespace {

using grpc::StatusCode;

using ::mav::test_support::NullStreamSink;   // tests/common/null_stream_sink.h
using ::mav::test_support::StartOnFreePort;  // tests/common/contract_server.h

using ::mav::test_support::ExpectInvalidArgument;  // tests/common/grpc_expect.h
using ::mav::test_support::StartsWith;

// mav-eval's mission script (eval::FlyTask) for the hover tasks, so that a flight through the
// service can be compared with FlyTask's.
struct Mission {
  const dataset::FlightTask* task = nullptr;
  control::GoToLimits limits = eval::FlightMissionOptions().takeoff_limits;
  bool took_off = false;
  int applied_goal = -1;

  void Update(int64_t t_ns, control::Autopilot* ap) {
    int goal = -1;
    for (size_t i = 0; i < task->goals.size(); ++i) {
      if (task->goals[i].publish_s <= NsToSeconds(t_ns) + 1e-9) goal = static_cast<int>(i);
    }
    if (!ap->armed()) {
      if (took_off || !ap->estimator().converged()) return;
      ASSERT_TRUE(ap->Arm().ok());
      ASSERT_TRUE(ap->Hover(task->takeoff_position, task->spawn_yaw_rad, &limits).ok());
      took_off = true;
      return;
    }
    if (goal > applied_goal && !(applied_goal < 0 && ap->moving())) {
      applied_goal = goal;
      const dataset::FlightGoal& g = task->goals[static_cast<size_t>(goal)];
      ASSERT_TRUE(ap->Hover(g.position, g.yaw_rad, &limits).ok());
    }
  }
};

// Records what the flight publishes and answers its IMU samples as `mode` says.
class FakeFlightIo : public FlightIo {
 public:
  enum class Mode { kSilent, kMotorsOff, kWrongSize, kNotFinite, kStale, kFuture, kAutopilot };
  struct Event {
    char kind;  // 'i' imu, 'p' pose, 'g' ground truth, 's' stereo
    int64_t t_ns;
    std::string frame;
  };

  void SetMode(Mode mode) {
    std::lock_guard<std::mutex> lock(mutex_);
    mode_ = mode;
  }
  // kAutopilot: the controller and its mission (not owned).
  void SetAutopilot(control::Autopilot* ap, Mission* mission) {
    std::lock_guard<std::mutex> lock(mutex_);
    ap_ = ap;
    mission_ = mission;
  }

  Status PublishFlightStereo(const sim::RenderedFrame& frame) override {
    std::lock_guard<std::mutex> lock(mutex_);
    events_.push_back({'s', frame.t_ns, std::to_string(frame.index)});
    return Status::Ok();
  }
  uint32_t StereoReaders() override { return 0; }
  Status PublishFlightImu(uint64_t, const dataset::ImuSample& s) override {
    std::lock_guard<std::mutex> lock(mutex_);
    events_.push_back({'i', s.t_ns, ""});
    ActuatorInput c;
    c.t_ns = s.t_ns;
    c.sequence = sequence_++;
    c.armed = true;
    c.rotor_speeds_radps.assign(6, 0.0);
    switch (mode_) {
      case Mode::kSilent:
        return Status::Ok();
      case Mode::kMotorsOff:
        c.armed = false;
        break;
      case Mode::kWrongSize:
        c.rotor_speeds_radps.assign(4, 400.0);
        break;
      case Mode::kNotFinite:
        c.rotor_speeds_radps[2] = std::nan("");
        break;
      case Mode::kStale:
        c.t_ns -= 200'000'000;
        c.rotor_speeds_radps.assign(6, 800.0);
        break;
      case Mode::kFuture:  // e.g. a late answer to an earlier flight, 20 s further on
        c.t_ns += 20'000'000'000;
        break;
      case Mode::kAutopilot: {
        const control::RotorVector& w = ap_->FeedImu({s.t_ns, s.gyro, s.accel});
        c.armed = ap_->armed();
        for (int i = 0; i < w.size(); ++i) c.rotor_speeds_radps[static_cast<size_t>(i)] = w[i];
        mission_->Update(s.t_ns, ap_);
        break;
      }
    }
    pending_.push_back(c);
    cv_.notify_all();
    return Status::Ok();
  }
  Status PublishFlightPose(uint64_t, const sim::PoseSample& pose, const std::string& frame_id,
                           double, double) override {
    std::lock_guard<std::mutex> lock(mutex_);
    events_.push_back({'p', pose.t_ns, frame_id});
    if (mode_ == Mode::kAutopilot) {
      (void)ap_->FeedPose({pose.t_ns, pose.sensor, pose.T_world_sensor});
    }
    return Status::Ok();
  }
  Status PublishFlightGroundTruth(uint64_t, const dataset::GroundTruthState& s) override {
    std::lock_guard<std::mutex> lock(mutex_);
    events_.push_back({'g', s.t_ns, ""});
    return Status::Ok();
  }
  void DiscardCommands() override {
    std::lock_guard<std::mutex> lock(mutex_);
    pending_.clear();
  }
  std::optional<ActuatorInput> WaitForCommand(int64_t min_t_ns, int64_t max_t_ns,
                                              int64_t timeout_ns, uint64_t* received) override {
    std::unique_lock<std::mutex> lock(mutex_);
    auto in_range = [&](const ActuatorInput& c) {
      return c.t_ns >= min_t_ns && c.t_ns <= max_t_ns;
    };
    cv_.wait_for(lock, std::chrono::nanoseconds(std::max<int64_t>(timeout_ns, 0)), [&] {
      for (const ActuatorInput& c : pending_) {
        if (in_range(c)) return true;
      }
      return false;
    });
    std::optional<ActuatorInput> best;
    for (const ActuatorInput& c : pending_) {
      ++*received;
      if (in_range(c) && (!best || c.t_ns >= best->t_ns)) best = c;
    }
    pending_.clear();
    return best;
  }
  uint32_t ActuatorWriters() override { return 1; }
  uint32_t ImuReaders() override { return 1; }
  uint32_t domain() const override { return 0; }

  std::vector<Event> events() {
    std::lock_guard<std::mutex> lock(mutex_);
    return events_;
  }
  void ClearEvents() {
    std::lock_guard<std::mutex> lock(mutex_);
    events_.clear();
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  Mode mode_ = Mode::kMotorsOff;
  control::Autopilot* ap_ = nullptr;
  Mission* mission_ = nullptr;
  uint64_t sequence_ = 0;
  std::deque<ActuatorInput> pending_;
  std::vector<Event> events_;
};

std::chrono::system_clock::time_point Deadline(double seconds) {
  return std::chrono::system_clock::now() +
         std::chrono::milliseconds(static_cast<int64_t>(seconds * 1000));
}

class SimulatorFlightContractTest : public ::testing::Test {
 protected:
  void SetUp() override {
    service_ = std::make_unique<SimulatorService>(&stream_sink_, SimulatorServiceOptions{}, &io_);
    server_ = StartOnFreePort<v1::Simulator>(service_.get());
    ASSERT_NE(server_, nullptr);
    stub_ = v1::Simulator::NewStub(server_->InProcessChannel());
  }
  void TearDown() override {
    if (server_ != nullptr) server_->Shutdown();
    service_->Shutdown();
  }

  grpc::Status Load(const v1::LoadFlightTaskRequest& request, v1::FlightStatus* out = nullptr,
                    double deadline_s = 20) {
    grpc::ClientContext context;
    context.set_deadline(Deadline(deadline_s));
    v1::FlightStatus local;
    return stub_->LoadFlightTask(&context, request, out != nullptr ? out : &local);
  }
  grpc::Status LoadBuiltin(const std::string& name, bool lockstep = true,
                           double lockstep_timeout_s = 0) {
    v1::LoadFlightTaskRequest request;
    request.set_builtin(name);
    request.set_seed(7);
    request.set_lockstep(lockstep);
    request.set_lockstep_timeout_s(lockstep_timeout_s);
    if (!lockstep) request.set_real_time_factor(50);
    return Load(request);
  }
  grpc::Status Start(double until_s, bool pause_on_goal = false, v1::FlightStatus* out = nullptr) {
    v1::StartFlightRequest request;
    request.set_run_until_s(until_s);
    request.set_pause_on_goal(pause_on_goal);
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    v1::FlightStatus local;
    return stub_->StartFlight(&context, request, out != nullptr ? out : &local);
  }
  grpc::Status Pause(v1::FlightStatus* out = nullptr) {
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    v1::FlightStatus local;
    return stub_->PauseFlight(&context, v1::PauseFlightRequest(), out != nullptr ? out : &local);
  }
  v1::FlightStatus Get() {
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    v1::FlightStatus status;
    EXPECT_TRUE(stub_->GetFlightStatus(&context, v1::GetFlightStatusRequest(), &status).ok());
    return status;
  }
  // Waits (at most 60 s) until the flight is no longer RUNNING.
  v1::FlightStatus WaitStopped() {
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    v1::FlightStatus s = Get();
    while (s.state() == v1::FLIGHT_STATE_RUNNING && std::chrono::steady_clock::now() < give_up) {
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
      s = Get();
    }
    return s;
  }
  void ExpectInvalid(const grpc::Status& status, const std::string& field) {
    ExpectInvalidArgument(status, field);
  }

  // The fake answers every IMU sample with the paper controller flying `task`'s mission.
  void FlyWithTheAutopilot(const std::string& task) {
    Result<dataset::FlightTask> loaded = sim::BuiltinFlightTask(task);
    ASSERT_TRUE(loaded.ok());
    task_ = std::make_unique<dataset::FlightTask>(*loaded);
    Result<control::Autopilot> ap = control::Autopilot::Create(
        eval::AutopilotOptionsForTask(*task_, control::ControllerType::kPaper));
    ASSERT_TRUE(ap.ok());
    autopilot_ = std::make_unique<control::Autopilot>(std::move(*ap));
    mission_.task = task_.get();
    io_.SetAutopilot(autopilot_.get(), &mission_);
    io_.SetMode(FakeFlightIo::Mode::kAutopilot);
  }

  // Declared before io_, which points at them: destroyed after it.
  std::unique_ptr<dataset::FlightTask> task_;
  std::unique_ptr<control::Autopilot> autopilot_;
  Mission mission_;
  NullStreamSink stream_sink_;
  FakeFlightIo io_;
  std::unique_ptr<SimulatorService> service_;
  std::unique_ptr<transport::GrpcServer> server_;
  std::unique_ptr<v1::Simulator::Stub> stub_;
};

// ---- LoadFlightTask / GetFlightStatus
// -------------------------------------------------------------

TEST_F(SimulatorFlightContractTest, GetFlightStatusIsIdleAtFirst) {
  const v1::FlightStatus s = Get();
  EXPECT_EQ(s.state(), v1::FLIGHT_STATE_IDLE);
  EXPECT_FALSE(s.has_task());
  EXPECT_EQ(s.goal_index(), -1);
}

TEST_F(SimulatorFlightContractTest, LoadFlightTaskRejectsBadInputNamingTheField) {
  ExpectInvalid(Load(v1::LoadFlightTaskRequest()), "task:");
  v1::LoadFlightTaskRequest r;
  r.set_builtin("t9_9");
  ExpectInvalid(Load(r), "builtin:");
  r.set_builtin("");
  ExpectInvalid(Load(r), "builtin:");
  r.set_yaml("");
  ExpectInvalid(Load(r), "yaml:");
  r.set_yaml("base: t3_1\nforces:\n  - {magnitude_n: 2, direction: [1, 0, 0], start_s: x}\n");
  ExpectInvalid(Load(r), "yaml: forces[0].start_s");
  r.set_yaml("duraton_s: 3\n");
  ExpectInvalid(Load(r), "yaml: duraton_s");
  r.set_path("");
  ExpectInvalid(Load(r), "path:");
  r.set_path("/nonexistent/task.yaml");
  EXPECT_EQ(Load(r).error_code(), StatusCode::NOT_FOUND);

  v1::LoadFlightTaskRequest ok;
  ok.set_builtin("t3_1");
  v1::LoadFlightTaskRequest bad = ok;
  bad.set_real_time_factor(-1);
  ExpectInvalid(Load(bad), "real_time_factor:");
  bad = ok;
  bad.set_real_time_factor(1000);
  ExpectInvalid(Load(bad), "real_time_factor:");
  bad = ok;
  bad.set_lockstep_timeout_s(1000);
  ExpectInvalid(Load(bad), "lockstep_timeout_s:");
  bad = ok;
  bad.set_command_stale_s(std::nan(""));
  ExpectInvalid(Load(bad), "command_stale_s:");
  bad = ok;
  bad.set_map_path("/nonexistent/map.bt");
  EXPECT_EQ(Load(bad).error_code(), StatusCode::NOT_FOUND);
  // More steps than the flight record holds (7000 s at 1 kHz).
  v1::LoadFlightTaskRequest longest;
  longest.set_yaml("duration_s: 7000\nimu: {rate_hz: 1000}\n");
  const grpc::Status s = Load(longest);
  EXPECT_EQ(s.error_code(), StatusCode::RESOURCE_EXHAUSTED) << s.error_message();
  EXPECT_TRUE(StartsWith(s.error_message(), "duration_s:")) << s.error_message();
  // Nothing of this was loaded.
  EXPECT_EQ(Get().state(), v1::FLIGHT_STATE_IDLE);
}

TEST_F(SimulatorFlightContractTest, LoadFlightTaskSummarizesTheTask) {
  v1::LoadFlightTaskRequest r;
  r.set_builtin("t4_2");
  r.set_seed(3);
  r.set_lockstep(true);
  v1::FlightStatus s;
  ASSERT_TRUE(Load(r, &s).ok());
  EXPECT_EQ(s.state(), v1::FLIGHT_STATE_LOADED);
  EXPECT_EQ(s.t_ns(), 0);
  const v1::FlightTaskSummary& t = s.task();
  EXPECT_EQ(t.name(), "t4_2");
  EXPECT_EQ(t.kind(), "waypoints");
  EXPECT_EQ(t.seed(), 3u);
  EXPECT_TRUE(t.lockstep());
  EXPECT_DOUBLE_EQ(t.lockstep_timeout_s(), 2.0);
  EXPECT_DOUBLE_EQ(t.command_stale_s(), 0.1);
  EXPECT_EQ(t.rotor_count(), 6u);
  EXPECT_DOUBLE_EQ(t.imu_rate_hz(), 100);
  ASSERT_EQ(t.pose_sensors_size(), 2);
  EXPECT_EQ(t.pose_sensors(0).frame_id(), "pose_sensor0");
  EXPECT_EQ(t.pose_sensors(1).frame_id(), "pose_sensor1");
  EXPECT_DOUBLE_EQ(t.pose_sensors(1).rate_hz(), 20);
  EXPECT_DOUBLE_EQ(t.pose_sensors(0).t_body_sensor().position().y(), -0.07);
  ASSERT_EQ(t.goals_size(), 4);
  EXPECT_DOUBLE_EQ(t.goals(1).position().y(), 20);
  // A task file's text over its base, with a map_path override that does not exist.
  v1::LoadFlightTaskRequest yaml;
  yaml.set_yaml("base: t3_2\nname: windy\nduration_s: 50\n");
  ASSERT_TRUE(Load(yaml, &s).ok());
  EXPECT_EQ(s.task().name(), "windy");
  EXPECT_EQ(s.task().kind(), "disturbance");
  EXPECT_DOUBLE_EQ(s.task().duration_s(), 50);
  EXPECT_FALSE(s.task().lockstep());
  EXPECT_DOUBLE_EQ(s.task().real_time_factor(), 1.0);
}

TEST_F(SimulatorFlightContractTest, ACallWhoseDeadlinePassedChangesNothing) {
  ASSERT_TRUE(LoadBuiltin("t3_1").ok());
  ASSERT_TRUE(Start(0.5).ok());
  ASSERT_EQ(WaitStopped().state(), v1::FLIGHT_STATE_PAUSED);
  const v1::FlightStatus before = Get();
  // Deadlines already in the past: nothing is loaded, started or paused.
  for (int rpc = 0; rpc < 3; ++rpc) {
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() - std::chrono::seconds(1));
    v1::FlightStatus ignored;
    grpc::Status s;
    if (rpc == 0) {
      v1::LoadFlightTaskRequest r;
      r.set_builtin("t4_1");
      s = stub_->LoadFlightTask(&context, r, &ignored);
    } else if (rpc == 1) {
      s = stub_->StartFlight(&context, v1::StartFlightRequest(), &ignored);
    } else {
      s = stub_->PauseFlight(&context, v1::PauseFlightRequest(), &ignored);
    }
    EXPECT_EQ(s.error_code(), StatusCode::DEADLINE_EXCEEDED) << rpc;
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  const v1::FlightStatus after = Get();
  EXPECT_EQ(after.task().name(), "t3_1");
  EXPECT_EQ(after.state(), v1::FLIGHT_STATE_PAUSED);
  EXPECT_EQ(after.steps(), before.steps());
}

TEST_F(SimulatorFlightContractTest, ALoadWhoseDeadlinePassesOnTheServerKeepsThePreviousTask) {
  ASSERT_TRUE(LoadBuiltin("t3_1").ok());
  // The handler's own path with a deadline that has passed by the time the new simulation is
  // built (the client-side case above never reaches the server).
  v1::LoadFlightTaskRequest r;
  r.set_builtin("t4_1");
  v1::FlightStatus ignored;
  const grpc::Status s =
      service_->ApplyLoadFlightTask(r, Termination::AtMonotonicNs(MonotonicNowNs()), &ignored);
  EXPECT_EQ(s.error_code(), StatusCode::DEADLINE_EXCEEDED) << s.error_message();
  EXPECT_EQ(Get().task().name(), "t3_1");
  EXPECT_EQ(Get().state(), v1::FLIGHT_STATE_LOADED);
}

// ---- StartFlight / PauseFlight
// --------------------------------------------------------------------

TEST_F(SimulatorFlightContractTest, StartAndPauseCheckTheStateAndTheirInput) {
  EXPECT_EQ(Start(0).error_code(), StatusCode::FAILED_PRECONDITION);
  EXPECT_EQ(Pause().error_code(), StatusCode::FAILED_PRECONDITION);
  ASSERT_TRUE(LoadBuiltin("t3_1").ok());
  EXPECT_EQ(Pause().error_code(), StatusCode::FAILED_PRECONDITION);
  ExpectInvalid(Start(-1), "run_until_s:");
  ExpectInvalid(Start(std::nan("")), "run_until_s:");
  ExpectInvalid(Start(std::numeric_limits<double>::infinity()), "run_until_s:");
  ASSERT_TRUE(Start(1.0).ok());
  ASSERT_EQ(WaitStopped().state(), v1::FLIGHT_STATE_PAUSED);
  ExpectInvalid(Start(0.5), "run_until_s:");  // not after the flight's 1 s
  ExpectInvalid(Start(1.0), "run_until_s:");
  // A slow controller keeps it running; a second start is refused, pause stops it.
  io_.SetMode(FakeFlightIo::Mode::kSilent);
  ASSERT_TRUE(Start(0).ok());
  EXPECT_EQ(Start(0).error_code(), StatusCode::FAILED_PRECONDITION);
  v1::FlightStatus paused;
  ASSERT_TRUE(Pause(&paused).ok());
  EXPECT_EQ(paused.state(), v1::FLIGHT_STATE_PAUSED);
  EXPECT_EQ(paused.pause_reason(), "PauseFlight");
}

TEST_F(SimulatorFlightContractTest, LockstepPublishesEachStepAndWaitsForItsCommand) {
  ASSERT_TRUE(LoadBuiltin("t3_1").ok());
  v1::FlightStatus s;
  ASSERT_TRUE(Start(1.0, false, &s).ok());
  // In process the fake answers at once: the 100 steps may be over before the reply is built.
  EXPECT_TRUE(s.state() == v1::FLIGHT_STATE_RUNNING || s.state() == v1::FLIGHT_STATE_PAUSED);
  s = WaitStopped();
  ASSERT_EQ(s.state(), v1::FLIGHT_STATE_PAUSED);
  EXPECT_TRUE(StartsWith(s.pause_reason(), "run_until_s 1 s reached")) << s.pause_reason();
  // Steps 0..99 were published and answered; step 100 (t = 1 s) waits for the next start.
  EXPECT_EQ(s.steps(), 100u);
  EXPECT_EQ(s.t_ns(), 1'000'000'000);
  EXPECT_EQ(s.imu_published(), 100u);
  EXPECT_EQ(s.ground_truth_published(), 100u);
  EXPECT_EQ(s.commands_received(), 100u);
  EXPECT_EQ(s.commands_rejected(), 0u);
  EXPECT_EQ(s.stale_steps(), 0u);
  EXPECT_EQ(s.poses_published(), 9u);  // 10 Hz, 100 ms late: stamps 0 ... 0.8 s by t = 0.99 s
  EXPECT_EQ(s.command_wait_ms().count(), 100u);
  EXPECT_FALSE(s.lifted_off());
  EXPECT_GT(s.speed_factor(), 1.0);
  // Each step: its poses, then its IMU, then its ground truth; every pose 100 ms late.
  const std::vector<FakeFlightIo::Event> events = io_.events();
  int64_t expect_imu_t = 0;
  for (size_t i = 0; i < events.size(); ++i) {
    const FakeFlightIo::Event& e = events[i];
    if (e.kind == 'i') {
      EXPECT_EQ(e.t_ns, expect_imu_t);
      expect_imu_t += 10'000'000;
      ASSERT_LT(i + 1, events.size());
      EXPECT_EQ(events[i + 1].kind, 'g');
    } else if (e.kind == 'p') {
      EXPECT_EQ(e.frame, "pose_sensor0");
      ASSERT_LT(i + 1, events.size());
      EXPECT_EQ(events[i + 1].kind, 'i');
      EXPECT_EQ(events[i + 1].t_ns - e.t_ns, 100'000'000) << "a pose is 100 ms late";
    }
  }
  EXPECT_EQ(expect_imu_t, 1'000'000'000);
}

// A mission flight (LoadFlightTask's MissionFlight): the mission's vehicle in its world, the
// forward stereo camera rendered from the flown state and published at 20 Hz stamped with the
// capture time (frame k at k x 50 ms, out once the state over its shutter is known, before that
// step's IMU sample); the true state in the status; calibration and ground-truth occupancy of
// the mission's rig and world; a malformed mission or option refused naming the line or field.
TEST_F(SimulatorFlightContractTest, AMissionFlightRendersItsCameraAndAnswersForItsWorld) {
  constexpr char kMission[] =
      "world: room-easy\nstart: [-2.0, 2.4, 0.0]\naltitude: 1.2\ngoals:\n  - [2.2, -0.8, "
      "1.0]\n";
  v1::LoadFlightTaskRequest request;
  request.mutable_mission()->set_yaml(kMission);
  request.mutable_mission()->set_source_name("room.yaml");
  request.set_seed(3);
  request.set_lockstep(true);
  // Refusals name the line, the field or the world; nothing is loaded.
  v1::LoadFlightTaskRequest bad = request;
  bad.mutable_mission()->set_yaml("world: room-easy\nstart: [0, 0]\ngoals:\n  - [1, 1, 1]\n");
  ExpectInvalid(Load(bad), "room.yaml:2");
  bad = request;
  bad.mutable_mission()->set_yaml("world: attic\nstart: [0, 0, 0]\ngoals:\n  - [1, 1, 1]\n");
  ExpectInvalid(Load(bad), "room.yaml: world:");
  bad = request;
  bad.mutable_mission()->set_pose_source("gps");
  ExpectInvalid(Load(bad), "mission.pose_source");
  bad = request;
  bad.mutable_mission()->set_camera_pitch_rad(2);
  ExpectInvalid(Load(bad), "mission.camera_pitch_rad");
  bad = request;
  bad.set_map_path("maps/power_plant.bt");
  ExpectInvalid(Load(bad), "map_path");
  EXPECT_EQ(Get().state(), v1::FLIGHT_STATE_IDLE);

  v1::FlightStatus loaded;
  ASSERT_TRUE(Load(request, &loaded).ok());
  EXPECT_EQ(loaded.state(), v1::FLIGHT_STATE_LOADED);
  EXPECT_NEAR(loaded.truth().t_world_body().position().x(), -2.0, 1e-9);
  EXPECT_NEAR(loaded.truth().t_world_body().position().z(), 0.08, 1e-9) << "on its legs";
  EXPECT_EQ(loaded.task().imu_rate_hz(), 200);
  v1::FlightStatus s;
  ASSERT_TRUE(Start(0.3, false, &s).ok());
  s = WaitStopped();
  ASSERT_EQ(s.state(), v1::FLIGHT_STATE_PAUSED);
  EXPECT_EQ(s.steps(), 60u);
  EXPECT_FALSE(s.has_score()) << "a mission keeps no contest score";
  // Frames 0..5 (0 ... 0.25 s); the 0.3 s one needs the state over its shutter.
  EXPECT_EQ(s.frames_published(), 6u);
  EXPECT_EQ(s.render_ms().count(), 6u);
  const std::vector<FakeFlightIo::Event> events = io_.events();
  int64_t frame = 0;
  for (size_t i = 0; i < events.size(); ++i) {
    if (events[i].kind != 's') continue;
    EXPECT_EQ(events[i].frame, std::to_string(frame));
    EXPECT_EQ(events[i].t_ns, frame * 50'000'000);
    ASSERT_LT(i + 1, events.size());
    EXPECT_EQ(events[i + 1].kind, 'i') << "a frame goes out before its step's IMU sample";
    EXPECT_GT(events[i + 1].t_ns, events[i].t_ns) << "after its capture";
    EXPECT_LE(events[i + 1].t_ns - events[i].t_ns, 15'000'000) << "at most a shutter later";
    ++frame;
  }
  EXPECT_EQ(frame, 6);

  grpc::ClientContext context;
  context.set_deadline(Deadline(5));
  v1::GetCalibrationResponse calibration;
  ASSERT_TRUE(stub_->GetCalibration(&context, v1::GetCalibrationRequest(), &calibration).ok());
  EXPECT_EQ(calibration.stereo().left().intrinsics().width(), 752u);
  EXPECT_EQ(calibration.stereo().left().rate_hz(), 20);
  EXPECT_FALSE(calibration.stereo().rectified()) << "the EuRoC raw rig";
  EXPECT_NEAR(calibration.t_body_imu().position().z(), -0.12, 1e-9)
      << "the vehicle's IMU 12 cm behind the rig (the rig's z looks forward)";
  grpc::ClientContext occupancy_context;
  occupancy_context.set_deadline(Deadline(60));
  v1::GetGroundTruthOccupancyRequest occupancy;
  occupancy.set_resolution_m(0.2);
  auto reader = stub_->GetGroundTruthOccupancy(&occupancy_context, occupancy);
  v1::OccupancyChunk chunk;
  size_t bytes = 0;
  while (reader->Read(&chunk)) bytes += chunk.chunk().data().size();
  ASSERT_TRUE(reader->Finish().ok());
  EXPECT_GT(bytes, 1000u) << "the room's occupancy";
}

TEST_F(SimulatorFlightContractTest, ALockstepTimeoutPausesAndTheStepIsPublishedAgain) {
  io_.SetMode(FakeFlightIo::Mode::kSilent);
  ASSERT_TRUE(LoadBuiltin("t3_1", true, 0.2).ok());
  ASSERT_TRUE(Start(0).ok());
  v1::FlightStatus s = WaitStopped();
  ASSERT_EQ(s.state(), v1::FLIGHT_STATE_PAUSED);
  EXPECT_EQ(s.steps(), 0u);
  EXPECT_TRUE(
      StartsWith(s.last_error(), "lock-step: no valid actuator command for step 0 (t_ns 0)"))
      << s.last_error();
  EXPECT_TRUE(StartsWith(s.pause_reason(), "lock-step timeout")) << s.pause_reason();
  EXPECT_GT(s.last_error_age_s(), 0.0);
  EXPECT_LT(s.last_error_age_s(), 10.0);
  // The controller is back: the step is published again and the flight goes on.
  io_.SetMode(FakeFlightIo::Mode::kMotorsOff);
  ASSERT_TRUE(Start(0.5).ok());
  s = WaitStopped();
  ASSERT_EQ(s.state(), v1::FLIGHT_STATE_PAUSED) << s.last_error();
  EXPECT_EQ(s.last_error(), "") << "the next run clears the previous run's error";
  EXPECT_EQ(s.last_error_age_s(), 0.0);
  EXPECT_EQ(s.steps(), 50u);
  EXPECT_EQ(s.imu_published(), 51u);  // step 0 twice
  int step0 = 0;
  for (const FakeFlightIo::Event& e : io_.events()) step0 += e.kind == 'i' && e.t_ns == 0;
  EXPECT_EQ(step0, 2);
}

TEST_F(SimulatorFlightContractTest, MalformedCommandsAreRejectedNamingTheField) {
  io_.SetMode(FakeFlightIo::Mode::kWrongSize);
  ASSERT_TRUE(LoadBuiltin("t3_1", true, 0.1).ok());
  ASSERT_TRUE(Start(0).ok());
  v1::FlightStatus s = WaitStopped();
  ASSERT_EQ(s.state(), v1::FLIGHT_STATE_PAUSED);
  EXPECT_EQ(s.steps(), 0u);  // never flown
  EXPECT_GE(s.commands_rejected(), 1u);
  EXPECT_NE(s.last_error().find("the last one was rejected: actuator command 0 (t_ns 0) "
                                "rejected: rotor_speeds: 4 values, the vehicle has 6 rotors"),
            std::string::npos)
      << s.last_error();
  io_.SetMode(FakeFlightIo::Mode::kFuture);
  ASSERT_TRUE(LoadBuiltin("t3_1", true, 0.1).ok());
  ASSERT_TRUE(Start(0).ok());
  s = WaitStopped();
  EXPECT_EQ(s.steps(), 0u) << "lock-step flies only the command stamped with its step";
  EXPECT_GE(s.commands_received(), 1u);
  io_.SetMode(FakeFlightIo::Mode::kNotFinite);
  ASSERT_TRUE(LoadBuiltin("t3_1", true, 0.1).ok());
  ASSERT_TRUE(Start(0).ok());
  s = WaitStopped();
  EXPECT_EQ(s.steps(), 0u);
  EXPECT_GE(s.commands_rejected(), 1u);
  EXPECT_NE(s.last_error().find("rotor_speeds[2]: not finite"), std::string::npos)
      << s.last_error();
  EXPECT_EQ(s.stale_steps(), 0u);
  // The pause reason is the timeout; the rejection is named in the command counters above.
  EXPECT_TRUE(StartsWith(s.pause_reason(), "lock-step timeout")) << s.pause_reason();
}

TEST_F(SimulatorFlightContractTest, RealTimeStaleOrMissingCommandsMeanMotorsOff) {
  io_.SetMode(FakeFlightIo::Mode::kStale);  // full throttle, but 200 ms old
  ASSERT_TRUE(LoadBuiltin("t3_1", /*lockstep=*/false).ok());
  const auto start = std::chrono::steady_clock::now();
  ASSERT_TRUE(Start(1.0).ok());
  v1::FlightStatus s = WaitStopped();
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_EQ(s.state(), v1::FLIGHT_STATE_PAUSED);
  EXPECT_EQ(s.steps(), 100u);
  EXPECT_EQ(s.stale_steps(), 100u);
  EXPECT_FALSE(s.lifted_off());
  EXPECT_NEAR(s.position().z(), 0.08, 1e-6);
  EXPECT_EQ(s.command_wait_ms().count(), 0u);  // real time does not wait
  EXPECT_GT(wall_s, 0.015);                    // 1 s at 50x is paced: >= 20 ms
  io_.SetMode(FakeFlightIo::Mode::kSilent);
  ASSERT_TRUE(Start(1.5).ok());
  s = WaitStopped();
  EXPECT_EQ(s.stale_steps(), 150u);
}

// The vehicle's own failsafe (mav/sim/failsafe.h): real time, the autopilot hovering at the
// take-off point (1 m) falls silent at 10 s; the failsafe takes over after command_stale_s, holds
// the vehicle level and lands it (a landing, not a ground collision), then stops the motors; the
// status says so. Disarmed commands (a restarted controller not armed yet) do not hand the
// vehicle back: only armed ones would.
TEST_F(SimulatorFlightContractTest, RealTimeSilenceInTheAirIsFlownByTheFailsafe) {
  ASSERT_NO_FATAL_FAILURE(FlyWithTheAutopilot("t3_1"));
  ASSERT_TRUE(LoadBuiltin("t3_1", /*lockstep=*/false).ok());
  ASSERT_TRUE(Start(10).ok());
  v1::FlightStatus s = WaitStopped();
  ASSERT_EQ(s.state(), v1::FLIGHT_STATE_PAUSED) << s.last_error();
  ASSERT_TRUE(s.lifted_off());
  ASSERT_GT(s.position().z(), 0.8);
  EXPECT_FALSE(s.failsafe_active());
  EXPECT_EQ(s.failsafe_engagements(), 0u);

  io_.SetMode(FakeFlightIo::Mode::kSilent);  // the controller dies
  ASSERT_TRUE(Start(11).ok());
  s = WaitStopped();
  EXPECT_TRUE(s.failsafe_active()) << "a second of silence in the air";
  EXPECT_EQ(s.failsafe_engagements(), 1u);
  EXPECT_NEAR(s.failsafe_s(), 0.9, 0.05);  // from 100 ms after the last command
  EXPECT_NEAR(s.truth().velocity().z(), -0.4, 0.15);
  io_.SetMode(FakeFlightIo::Mode::kMotorsOff);  // a controller that is not armed
  ASSERT_TRUE(Start(11.5).ok());
  s = WaitStopped();
  EXPECT_TRUE(s.failsafe_active()) << "disarmed commands do not stop the rotors in the air";
  EXPECT_EQ(s.failsafe_engagements(), 1u);
  EXPECT_NEAR(s.truth().velocity().z(), -0.4, 0.15) << "descending, not falling";
  ASSERT_TRUE(Start(16).ok());
  s = WaitStopped();
  EXPECT_FALSE(s.failsafe_active()) << "landed: the failsafe is done, motors off";
  EXPECT_NEAR(s.position().z(), 0.08, 0.01) << "on its legs";
  EXPECT_EQ(s.collisions_size(), 0) << "a landing, not a ground collision";
  const double flown = s.failsafe_s();
  EXPECT_GT(flown, 1.5);
  EXPECT_LT(flown, 4.0);
}

// ---- A flight through the service equals mav-eval's
// -----------------------------------------------

TEST_F(SimulatorFlightContractTest, AHoverFlownThroughTheServiceScoresAsFlyTask) {
  ASSERT_NO_FATAL_FAILURE(FlyWithTheAutopilot("t3_1"));
  ASSERT_TRUE(LoadBuiltin("t3_1").ok());
  // pause_on_goal pauses once, at the set point's publication (10 s); the mission reacts inside
  // the fake, so the flight just goes on.
  ASSERT_TRUE(Start(0, true).ok());
  v1::FlightStatus s = WaitStopped();
  ASSERT_EQ(s.state(), v1::FLIGHT_STATE_PAUSED);
  EXPECT_EQ(s.pause_reason(), "goal 0 published at 10 s");
  EXPECT_EQ(s.t_ns(), 10'000'000'000);
  EXPECT_EQ(s.goal_index(), 0);
  ASSERT_TRUE(Start(0, true).ok());
  s = WaitStopped();
  ASSERT_EQ(s.state(), v1::FLIGHT_STATE_FINISHED) << s.pause_reason() << s.last_error();
  ASSERT_TRUE(s.has_score());
  EXPECT_EQ(s.collisions_size(), 0);
  EXPECT_TRUE(s.lifted_off());
  EXPECT_EQ(s.steps(), 3000u);

  eval::FlightMissionOptions options;
  options.seed = 7;
  Result<eval::FlightRecord> record = eval::FlyTask(*task_, options);
  ASSERT_TRUE(record.ok()) << record.status().ToString();
  const eval::TaskScore expected = eval::ScoreFlight(*task_, *record);
  const v1::FlightScore& got = s.score();
  EXPECT_DOUBLE_EQ(got.points(), expected.points);
  EXPECT_DOUBLE_EQ(got.max_points(), expected.max_points);
  EXPECT_DOUBLE_EQ(got.position_rms_m(), expected.position_rms_m);
  EXPECT_DOUBLE_EQ(got.angular_rate_rms_radps(), expected.angular_rate_rms_radps);
  ASSERT_EQ(got.goals_size(), 1);
  EXPECT_DOUBLE_EQ(got.goals(0).window_start_s(), 15.0);
  EXPECT_LT(got.position_rms_m(), 0.2);
  EXPECT_LT(got.angular_rate_rms_radps(), 0.2);
  // A finished flight does not start again.
  EXPECT_EQ(Start(0).error_code(), StatusCode::FAILED_PRECONDITION);
}

// ---- The two modes share the IMU topic
// -----------------------------------------------------------

TEST_F(SimulatorFlightContractTest, StartingTheFlightPausesARunningReplay) {
  sim::PresetRequest preset;
  preset.name = "room-easy";
  preset.frames = 3;
  Result<std::unique_ptr<sim::ScenarioSource>> source = sim::OpenPreset(preset);
  ASSERT_TRUE(source.ok()) << source.status().ToString();
  ASSERT_TRUE(service_->player().Load(std::move(*source)).ok());
  Pacing pacing;
  pacing.real_time_factor = 0.001;  // a frame every 50 s: still running below
  ASSERT_TRUE(service_->player().Start(pacing).ok());
  ASSERT_TRUE(LoadBuiltin("t3_1").ok());
  EXPECT_EQ(service_->player().GetStatus().state,
            PlayerState::kRunning);  // loading publishes nothing
  ASSERT_TRUE(Start(0.2).ok());
  EXPECT_EQ(service_->player().GetStatus().state, PlayerState::kPaused);
  EXPECT_EQ(WaitStopped().state(), v1::FLIGHT_STATE_PAUSED);
  // ... and the replay pauses a running flight.
  io_.SetMode(FakeFlightIo::Mode::kSilent);
  ASSERT_TRUE(Start(0).ok());
  grpc::ClientContext context;
  context.set_deadline(Deadline(5));
  v1::SimulatorStartRequest replay;
  replay.set_real_time_factor(0.001);
  v1::SimulatorStatus replay_status;
  ASSERT_TRUE(stub_->Start(&context, replay, &replay_status).ok());
  const v1::FlightStatus s = Get();
  EXPECT_EQ(s.state(), v1::FLIGHT_STATE_PAUSED);
  EXPECT_EQ(s.pause_reason(), "the replay was started (Start)");
}

// ---- A real loopback port
// -------------------------------------------------------------------------

TEST_F(SimulatorFlightContractTest, LoopbackPortServesTheFlightRpcs) {
  auto channel = grpc::CreateChannel(server_->target(), grpc::InsecureChannelCredentials());
  auto health = transport::CheckHealth(channel, "mav.v1.Simulator", std::chrono::seconds(5));
  ASSERT_TRUE(health.ok()) << health.status().ToString();
  EXPECT_EQ(*health, transport::HealthStatus::kServing);
  auto stub = v1::Simulator::NewStub(channel);
  {
    grpc::ClientContext context;
    context.set_deadline(Deadline(10));
    v1::LoadFlightTaskRequest r;
    r.set_builtin("t3_3");
    r.set_lockstep(true);
    v1::FlightStatus s;
    const grpc::Status rpc = stub->LoadFlightTask(&context, r, &s);
    ASSERT_TRUE(rpc.ok()) << rpc.error_message();
    EXPECT_EQ(s.task().name(), "t3_3");
  }
  {
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    v1::StartFlightRequest r;
    r.set_run_until_s(0.3);
    v1::FlightStatus s;
    ASSERT_TRUE(stub->StartFlight(&context, r, &s).ok());
  }
  EXPECT_EQ(WaitStopped().steps(), 30u);
  {
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    v1::FlightStatus s;
    ASSERT_TRUE(stub->GetFlightStatus(&context, v1::GetFlightStatusRequest(), &s).ok());
    EXPECT_EQ(s.state(), v1::FLIGHT_STATE_PAUSED);
  }
  {
    // A bad request over the wire names the field too.
    grpc::ClientContext context;
    context.set_deadline(Deadline(5));
    v1::StartFlightRequest r;
    r.set_run_until_s(-3);
    v1::FlightStatus s;
    const grpc::Status rpc = stub->StartFlight(&context, r, &s);
    EXPECT_EQ(rpc.error_code(), StatusCode::INVALID_ARGUMENT);
    EXPECT_TRUE(StartsWith(rpc.error_message(), "run_until_s:"));
  }
}

// ---- DDS conversions
// ------------------------------------------------------------------------------

TEST(SimulatorFlightDdsTest, PoseSamplesCarryTheSensorFrameAndNoise) {
  sim::PoseSample pose;
  pose.sensor = 1;
  pose.t_ns = 123;
  pose.T_world_sensor =
      geometry::SE3(Eigen::Quaterniond(0.5, 0.5, 0.5, 0.5), Eigen::Vector3d(1.0, 2.0, 3.0));
  const mav_dds_PoseWithCovariance s = ToDds(4, pose, "pose_sensor1", 0.01, 0.02, 99);
  EXPECT_EQ(s.sequence_number, 4u);
  EXPECT_EQ(s.t_ns, 123);
  EXPECT_EQ(s.publish_t_ns, 99);
  EXPECT_STREQ(s.frame_id, "world");
  EXPECT_STREQ(s.child_frame_id, "pose_sensor1");
  EXPECT_DOUBLE_EQ(s.position.z, 3.0);
  EXPECT_DOUBLE_EQ(s.orientation.w, 0.5);
  EXPECT_DOUBLE_EQ(s.covariance[0], 1e-4);
  EXPECT_DOUBLE_EQ(s.covariance[14], 1e-4);
  EXPECT_DOUBLE_EQ(s.covariance[21], 4e-4);
  EXPECT_DOUBLE_EQ(s.covariance[35], 4e-4);
  EXPECT_DOUBLE_EQ(s.covariance[1], 0.0);
  EXPECT_EQ(s.tracking_state, mav_dds_TRACKING_STATE_OK);
}

TEST(SimulatorFlightDdsTest, ActuatorCommandsArriveAsSent) {
  double speeds[3] = {100, 200, 300};
  mav_dds_ActuatorCommand c{};
  c.sequence_number = 5;
  c.t_ns = 77;
  c.armed = true;
  c.rotor_speeds._buffer = speeds;
  c.rotor_speeds._length = c.rotor_speeds._maximum = 3;
  const ActuatorInput in = FromDds(c);
  EXPECT_EQ(in.sequence, 5u);
  EXPECT_EQ(in.t_ns, 77);
  EXPECT_TRUE(in.armed);
  ASSERT_EQ(in.rotor_speeds_radps.size(), 3u);  // the Flight checks the count
  EXPECT_DOUBLE_EQ(in.rotor_speeds_radps[2], 300);
}

}  // namespace
}  // namespace mav::simulator_service
