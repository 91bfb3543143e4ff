#include "services/simulator/flight.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "mav/common/check.h"
#include "mav/common/log.h"
#include "mav/common/pacing.h"
#include "mav/common/time.h"
#include "mav/sim/failsafe.h"
#include "mav/sim/scenario_source.h"
#include "services/common/proto_codec.h"

namespace mav::simulator_service {

namespace {

constexpr size_t kStatsWindow = 1000;
// Lock-step: one wait for a command is cut into slices this long so that Pause and Load
// interrupt it promptly.
constexpr int64_t kWaitSliceNs = 20'000'000;
// Real time: when stepping falls this far behind the schedule, the schedule is reset rather
// than bursting to catch up.
constexpr int64_t kMaxLatenessNs = 200'000'000;

using service_common::Number;

WorkQueueOptions QueueOptions() {
  WorkQueueOptions o = WorkQueueOptions::Named("simulator flight", 2);
  o.stats_window = kStatsWindow;
  return o;
}

eval::FlightTraceSample TraceSample(const sim::FlightStep& out) {
  // The simulator does not see the controller's estimate: the estimator columns stay the truth
  // (the score's estimator_rms_m is then 0 and is not reported).
  return {NsToSeconds(out.t_ns), out.truth.p_world, out.truth.v_world, out.truth.omega_body,
          out.truth.p_world};
}

}  // namespace

const char* FlightStateName(FlightState state) {
  switch (state) {
    case FlightState::kIdle:
      return "IDLE";
    case FlightState::kLoaded:
      return "LOADED";
    case FlightState::kRunning:
      return "RUNNING";
    case FlightState::kPaused:
      return "PAUSED";
    case FlightState::kFinished:
      return "FINISHED";
  }
  return "?";
}

bool FlightConfig::IsValid(std::string* why) const {
  if (!OptionsValid(why)) return false;
  if (std::string inner; !task.IsValid(&inner)) {
    if (why != nullptr) *why = "task: " + task.name + ": " + inner;
    return false;
  }
  return true;
}

bool FlightConfig::OptionsValid(std::string* why) const {
  auto fail = [&](const std::string& message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (!lockstep &&
      !(real_time_factor >= kMinRealTimeFactor && real_time_factor <= kMaxRealTimeFactor)) {
    return fail("real_time_factor: must be in [0.01, 100], got " + Number(real_time_factor));
  }
  if (!(lockstep_timeout_s > 0 && lockstep_timeout_s <= 600)) {
    return fail("lockstep_timeout_s: must be in (0, 600] s, got " + Number(lockstep_timeout_s));
  }
  if (!(command_stale_s > 0 && command_stale_s <= 10)) {
    return fail("command_stale_s: must be in (0, 10] s, got " + Number(command_stale_s));
  }
  std::string inner;
  if (!simulation.IsValid(&inner)) return fail("simulation." + inner);
  return true;
}

// What the worker keeps of a loaded flight.
struct Flight::Loaded {
  Loaded(sim::FlightSimulation s, FlightConfig c)
      : sim(std::move(s)),
        config(std::move(c)),
        failsafe(*sim::DescentFailsafe::Create(config.simulation.vehicle)) {}  // checked at Load
  sim::FlightSimulation sim;
  FlightConfig config;
  sim::DescentFailsafe failsafe;         // real time: flies the vehicle while commands are stale
  const sim::FlightStep* out = nullptr;  // the current step (inside `sim`)
  std::vector<std::string> frame_ids;    // per pose sensor
  std::vector<eval::FlightTraceSample> trace;  // one per step, for the score
  bool published = false;                      // the current step's readings are out
  uint64_t goal_pause_step = std::numeric_limits<uint64_t>::max();
  uint64_t step = 0;                               // index of the current step
  bool keep_trace = true;                          // false for a mission flight (no score)
  std::unique_ptr<mission::VehicleCamera> camera;  // a mission flight's, pose source vo
  int64_t imu_publish_wall_ns = 0;
  // Real time: when each step is due, and the newest valid command.
  RealTimePacer pacer{1.0, kMaxLatenessNs};
  std::optional<ActuatorInput> latest;
  sim::RotorVector latest_command;
  // The vehicle's failsafe (real time): off, flying it down, or landed with the motors off
  // until fresh commands come (a bounce on touchdown does not restart it).
  FailsafePhase failsafe_phase = FailsafePhase::kOff;
};

Flight::Flight(FlightIo* io)
    : io_(io),
      queue_(QueueOptions()),
      step_ms_(kStatsWindow),
      command_wait_ms_(kStatsWindow),
      render_ms_(kStatsWindow) {
  MAV_CHECK(io_ != nullptr);
}

Flight::~Flight() { Shutdown(); }

void Flight::Shutdown() { queue_.Stop("the simulator is shutting down"); }

Status Flight::Load(const FlightConfig& config, std::shared_ptr<const sim::CollisionWorld> world,
                    const Termination& deadline,
                    const std::shared_ptr<const MissionScene>& mission) {
  if (std::string why; !config.IsValid(&why)) return Status::InvalidArgument(why);
  const double steps = config.task.duration_s * config.task.imu.rate_hz + 2;
  if (mission == nullptr && steps > static_cast<double>(kMaxTraceSteps)) {
    return Status::ResourceExhausted(
        "duration_s: task " + config.task.name + " has " + Number(steps) +
        " steps (duration_s x imu.rate_hz), more than the flight record's cap of " +
        std::to_string(kMaxTraceSteps));
  }
  MAV_ASSIGN_OR_RETURN(
      sim::FlightSimulation simulation,
      sim::FlightSimulation::Create(config.task, config.seed, config.simulation, std::move(world)));
  MAV_RETURN_IF_ERROR(deadline.Check("LoadFlightTask"));
  auto loaded = std::make_shared<Loaded>(std::move(simulation), config);
  for (int i = 0; i < loaded->sim.pose_sensor_count(); ++i) {
    loaded->frame_ids.push_back("pose_sensor" + std::to_string(i));
  }
  loaded->out = &loaded->sim.Initial();
  loaded->keep_trace = mission == nullptr;
  if (loaded->keep_trace) {
    loaded->trace.reserve(static_cast<size_t>(steps));
    loaded->trace.push_back(TraceSample(*loaded->out));
  }
  if (mission != nullptr && mission->vehicle.pose_source == mission::PoseSource::kVo) {
    const sim::MulticopterState& x0 = loaded->out->truth;
    loaded->camera = std::make_unique<mission::VehicleCamera>(
        mission->preset, mission->vehicle, loaded->sim.step_ns(), loaded->out->t_ns,
        geometry::SE3(x0.q_world_body, x0.p_world));
  }
  loaded->latest_command = sim::RotorVector::Zero(config.simulation.vehicle.rotor_count);

  std::lock_guard<std::mutex> command(command_mutex_);
  queue_.Reset("a new flight task was loaded");  // waits for a running flight to stop
  io_->DiscardCommands();
  std::lock_guard<std::mutex> lock(mutex_);
  loaded_ = std::move(loaded);
  config_ = config;
  state_ = FlightState::kLoaded;
  steps_ = imu_published_ = poses_published_ = gt_published_ = 0;
  commands_received_ = commands_rejected_ = stale_steps_ = 0;
  failsafe_active_ = false;
  failsafe_engagements_ = 0;
  failsafe_ns_ = 0;
  t_ns_ = loaded_->sim.t_ns();
  goal_index_ = -1;
  collisions_.clear();
  collisions_total_ = 0;
  lifted_off_ = false;
  position_ = loaded_->sim.Initial().truth.p_world;
  truth_ = loaded_->sim.Initial().truth;
  gyro_offset_ = loaded_->sim.imu().gyro_offset();
  accel_offset_ = loaded_->sim.imu().accel_offset();
  frames_published_ = 0;
  render_ms_.Clear();
  is_mission_ = mission != nullptr;
  run_start_wall_ns_ = run_last_wall_ns_ = 0;
  run_start_t_ns_ = 0;
  step_ms_.Clear();
  command_wait_ms_.Clear();
  pause_reason_.clear();
  last_error_.clear();
  score_.reset();
  min_clearance_m_ = 0;
  MAV_LOG(kInfo) << (mission ? "mission flight " : "flight task ") << config.task.name
                 << " loaded ("
                 << (config.lockstep ? "lock-step"
                                     : "real time x" + Number(config.real_time_factor))
                 << ", seed " << config.seed << ", " << config.task.duration_s << " s)";
  return Status::Ok();
}

Result<FlightStatus> Flight::Start(const FlightRun& run) {
  std::lock_guard<std::mutex> command(command_mutex_);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    switch (state_) {
      case FlightState::kIdle:
        return Status::FailedPrecondition("no flight task loaded: call LoadFlightTask first");
      case FlightState::kRunning:
        return Status::FailedPrecondition("the flight is already running");
      case FlightState::kFinished:
        return Status::FailedPrecondition("the flight has finished: load the task again");
      case FlightState::kLoaded:
      case FlightState::kPaused:
        break;
    }
    if (!std::isfinite(run.until_s) || run.until_s < 0) {
      return Status::InvalidArgument("run_until_s: must be >= 0 and finite, got " +
                                     Number(run.until_s));
    }
    if (run.until_s > 0 && SecondsToNs(run.until_s) <= t_ns_) {
      return Status::InvalidArgument("run_until_s: " + Number(run.until_s) +
                                     " s is not after the flight's time " +
                                     Number(NsToSeconds(t_ns_)) + " s");
    }
    state_ = FlightState::kRunning;
    pause_reason_.clear();
    last_error_.clear();  // the previous run's (a lock-step timeout's) is in the log
    run_start_wall_ns_ = run_last_wall_ns_ = MonotonicNowNs();
    run_start_t_ns_ = t_ns_;
  }
  // The flight runs until it ends, pauses itself, or Pause/Load interrupt it.
  const Ticket<Status> ticket =
      queue_.Submit<Status>([this, run](const TaskContext& context) { return Run(context, run); });
  std::lock_guard<std::mutex> lock(mutex_);
  if (!ticket.accepted()) {
    state_ = FlightState::kPaused;
    return ticket.submit_status();
  }
  return StatusLocked();
}

Result<FlightStatus> Flight::Pause(const std::string& reason) {
  std::lock_guard<std::mutex> command(command_mutex_);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (state_ != FlightState::kRunning) {
      return Status::FailedPrecondition(std::string("not running (state ") +
                                        FlightStateName(state_) + ")");
    }
  }
  queue_.Reset("paused");  // returns after the step in flight
  std::lock_guard<std::mutex> lock(mutex_);
  // The flight may have ended or paused itself meanwhile (that state stays).
  if (state_ == FlightState::kRunning) {
    state_ = FlightState::kPaused;
    pause_reason_ = reason;
  }
  return StatusLocked();
}

bool Flight::running() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return state_ == FlightState::kRunning;
}

FlightStatus Flight::GetStatus() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return StatusLocked();
}

FlightStatus Flight::StatusLocked() const {
  FlightStatus s;
  s.state = state_;
  s.config = config_;
  s.t_ns = t_ns_;
  s.steps = steps_;
  s.imu_published = imu_published_;
  s.poses_published = poses_published_;
  s.ground_truth_published = gt_published_;
  s.commands_received = commands_received_;
  s.commands_rejected = commands_rejected_;
  s.stale_steps = stale_steps_;
  s.failsafe_active = failsafe_active_;
  s.failsafe_engagements = failsafe_engagements_;
  s.failsafe_s = NsToSeconds(failsafe_ns_);
  s.goal_index = goal_index_;
  s.collisions = collisions_;
  s.collisions_total = collisions_total_;
  s.lifted_off = lifted_off_;
  s.position = position_;
  const int64_t wall_ns = run_last_wall_ns_ - run_start_wall_ns_;
  if (wall_ns > 0) s.speed_factor = NsToSeconds(t_ns_ - run_start_t_ns_) / NsToSeconds(wall_ns);
  s.step_ms = step_ms_.Summary();
  s.command_wait_ms = command_wait_ms_.Summary();
  s.pause_reason = pause_reason_;
  s.last_error = last_error_.text();
  s.last_error_age_s = last_error_.AgeS();
  s.score = score_;
  s.min_clearance_m = min_clearance_m_;
  s.actuator_writers = io_->ActuatorWriters();
  s.dds_domain = io_->domain();
  s.truth = truth_;
  s.gyro_offset = gyro_offset_;
  s.accel_offset = accel_offset_;
  s.is_mission = is_mission_;
  s.frames_published = frames_published_;
  s.render_ms = render_ms_.Summary();
  s.stereo_readers = io_->StereoReaders();
  return s;
}

// ---- On the worker ------------------------------------------------------------------------------

Status Flight::PublishStep(const sim::FlightStep& out, Loaded* loaded) {
  uint64_t imu_seq = 0, pose_seq = 0, gt_seq = 0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    imu_seq = imu_published_;
    pose_seq = poses_published_;
    gt_seq = gt_published_;
  }
  Status first_error;
  auto note = [&](const Status& s) {
    if (!s.ok() && first_error.ok()) first_error = s;
  };
  // Poses first, then the IMU: a controller that drains its pose reader before the IMU it wakes
  // on (transport::DdsReadLoop) merges the step's poses before it answers the step.
  const std::vector<dataset::FlightPoseSensorSpec>& sensors = loaded->config.task.pose_sensors;
  for (const sim::PoseSample& p : out.poses) {
    const dataset::FlightPoseSensorSpec& spec = sensors[static_cast<size_t>(p.sensor)];
    note(io_->PublishFlightPose(pose_seq++, p, loaded->frame_ids[static_cast<size_t>(p.sensor)],
                                spec.position_sigma_m, spec.orientation_sigma_rad));
  }
  note(io_->PublishFlightImu(imu_seq++, out.imu));
  loaded->imu_publish_wall_ns = MonotonicNowNs();
  dataset::GroundTruthState gt;
  gt.t_ns = out.t_ns;
  gt.T_world_body = geometry::SE3(out.truth.q_world_body, out.truth.p_world);
  gt.v_world = out.truth.v_world;
  gt.gyro_bias = loaded->sim.imu().gyro_offset();
  gt.accel_bias = loaded->sim.imu().accel_offset();
  note(io_->PublishFlightGroundTruth(gt_seq++, gt));
  loaded->published = true;
  std::lock_guard<std::mutex> lock(mutex_);
  imu_published_ = imu_seq;
  poses_published_ = pose_seq;
  gt_published_ = gt_seq;
  if (!first_error.ok()) last_error_ = first_error.ToString();
  return first_error;
}

void Flight::PublishFrames(Loaded* loaded) {
  const sim::FlightStep& out = *loaded->out;
  loaded->camera->Observe(out.t_ns, geometry::SE3(out.truth.q_world_body, out.truth.p_world));
  for (const int64_t frame : loaded->camera->DueFrames()) {
    sim::RenderedFrame rendered;
    rendered.index = frame;
    rendered.t_ns = loaded->camera->FrameTimeNs(frame);
    const int64_t start_ns = MonotonicNowNs();
    loaded->camera->Render(frame, &rendered.left, &rendered.right);
    rendered.render_ms = MsSince(start_ns);
    const Status published = io_->PublishFlightStereo(rendered);
    std::lock_guard<std::mutex> lock(mutex_);
    render_ms_.Add(rendered.render_ms);
    if (published.ok()) {
      ++frames_published_;
    } else {
      last_error_ = published.ToString();
    }
  }
}

std::optional<sim::RotorVector> Flight::Checked(const ActuatorInput& input, int rotor_count) {
  sim::RotorVector command = sim::RotorVector::Zero(rotor_count);
  if (!input.armed) return command;  // motors off: the speeds are ignored
  std::string why;
  if (static_cast<int>(input.rotor_speeds_radps.size()) != rotor_count) {
    why = "rotor_speeds: " + std::to_string(input.rotor_speeds_radps.size()) +
          " values, the vehicle has " + std::to_string(rotor_count) + " rotors";
  } else {
    for (int i = 0; i < rotor_count && why.empty(); ++i) {
      const double w = input.rotor_speeds_radps[static_cast<size_t>(i)];
      if (!std::isfinite(w)) why = "rotor_speeds[" + std::to_string(i) + "]: not finite";
      command[i] = w;  // clamped to [0, max] by the vehicle
    }
  }
  if (why.empty()) return command;
  std::lock_guard<std::mutex> lock(mutex_);
  ++commands_rejected_;
  last_error_ = "actuator command " + std::to_string(input.sequence) + " (t_ns " +
                std::to_string(input.t_ns) + ") rejected: " + why;
  return std::nullopt;
}

Flight::FailsafePhase Flight::NextFailsafePhase(FailsafePhase before, bool stale, bool on_ground) {
  if (!stale) return FailsafePhase::kOff;
  if (before == FailsafePhase::kLanded) return FailsafePhase::kLanded;  // until fresh commands
  // On the ground a descent ends in a landing; stale before any flight: motors off, no failsafe.
  if (on_ground) {
    return before == FailsafePhase::kDescending ? FailsafePhase::kLanded : FailsafePhase::kOff;
  }
  return FailsafePhase::kDescending;
}

std::optional<sim::RotorVector> Flight::CommandForStep(const TaskContext& context, Loaded* loaded,
                                                       bool* timed_out) {
  const FlightConfig& config = loaded->config;
  const int rotor_count = config.simulation.vehicle.rotor_count;
  const int64_t t_ns = loaded->sim.t_ns();
  uint64_t received = 0;
  auto count_received = [&] {
    if (received == 0) return;
    std::lock_guard<std::mutex> lock(mutex_);
    commands_received_ += received;
    received = 0;
  };
  if (config.lockstep) {
    const int64_t give_up_ns = MonotonicNowNs() + SecondsToNs(config.lockstep_timeout_s);
    uint64_t rejected_before = 0;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      rejected_before = commands_rejected_;
    }
    while (!context.ShouldStop()) {
      const int64_t remaining = give_up_ns - MonotonicNowNs();
      if (remaining <= 0) {
        *timed_out = true;
        std::lock_guard<std::mutex> lock(mutex_);
        std::string message = "lock-step: no valid actuator command for step " +
                              std::to_string(loaded->step) + " (t_ns " + std::to_string(t_ns) +
                              ") within " + Number(config.lockstep_timeout_s) + " s (" +
                              std::to_string(io_->ActuatorWriters()) + " actuator writers matched)";
        if (commands_rejected_ > rejected_before) {
          message += "; the last one was rejected: " + last_error_.text();  // Checked()'s reason
        } else {
          message +=
              ": is the controller configured, with DDS input, and answering every IMU sample?";
        }
        last_error_ = message;
        return std::nullopt;
      }
      std::optional<ActuatorInput> input =
          io_->WaitForCommand(t_ns, t_ns, std::min(remaining, kWaitSliceNs), &received);
      count_received();
      if (!input) continue;
      std::optional<sim::RotorVector> command = Checked(*input, rotor_count);
      if (!command) continue;
      std::lock_guard<std::mutex> lock(mutex_);
      command_wait_ms_.Add(MsSince(loaded->imu_publish_wall_ns));
      return command;
    }
    return std::nullopt;
  }
  // Real time: step k+1 is due at its data time on the pacer's schedule.
  const int64_t t_next = t_ns + loaded->sim.step_ns();
  if (!context.SleepUntil(loaded->pacer.DueNs(t_next, context.NowNs()))) return std::nullopt;
  std::optional<ActuatorInput> input = io_->WaitForCommand(
      std::numeric_limits<int64_t>::min(), std::numeric_limits<int64_t>::max(), 0, &received);
  count_received();
  using Failsafe = FailsafePhase;
  if (input) {
    if (std::optional<sim::RotorVector> command = Checked(*input, rotor_count)) {
      // Once the failsafe flies, only an armed command takes the vehicle back.
      if (input->armed || loaded->failsafe_phase == Failsafe::kOff) {
        loaded->latest = std::move(input);
        loaded->latest_command = *command;
      }
    }
  }
  const bool stale =
      !loaded->latest || t_ns - loaded->latest->t_ns > SecondsToNs(config.command_stale_s);
  const sim::MulticopterState& vehicle = loaded->sim.vehicle().state();
  const Failsafe before = loaded->failsafe_phase;
  const Failsafe phase = NextFailsafePhase(before, stale, vehicle.on_ground);
  loaded->failsafe_phase = phase;
  std::lock_guard<std::mutex> lock(mutex_);
  if (phase != before) LogFailsafeLocked(t_ns, before, phase, vehicle, *loaded);
  failsafe_active_ = phase == Failsafe::kDescending;
  if (!stale) return loaded->latest_command;
  ++stale_steps_;
  if (phase != Failsafe::kDescending) return sim::RotorVector::Zero(rotor_count);
  failsafe_ns_ += loaded->sim.step_ns();
  return loaded->failsafe.Command(vehicle);
}

void Flight::LogFailsafeLocked(int64_t t_ns, FailsafePhase before, FailsafePhase phase,
                               const sim::MulticopterState& vehicle, const Loaded& loaded) {
  using Failsafe = FailsafePhase;
  if (phase == Failsafe::kDescending) {
    ++failsafe_engagements_;
    char text[160];
    std::snprintf(text, sizeof(text),
                  "t %.2f s: no valid actuator command for %.2f s at %.2f m: failsafe: level, "
                  "descending at %.2f m/s, motors off on the ground",
                  NsToSeconds(t_ns), loaded.config.command_stale_s, vehicle.p_world.z(),
                  loaded.failsafe.options().descent_mps);
    MAV_LOG(kWarning) << text;
  } else if (phase == Failsafe::kLanded) {
    MAV_LOG(kInfo) << "t " << NsToSeconds(t_ns)
                   << " s: failsafe landed the vehicle: motors off until armed commands come";
  } else if (before != Failsafe::kOff) {
    MAV_LOG(kInfo) << "t " << NsToSeconds(t_ns) << " s: failsafe off (armed commands again)";
  }
}

void Flight::FinishLocked(Loaded* loaded) {
  state_ = FlightState::kFinished;
  pause_reason_.clear();
  if (!loaded->keep_trace) {
    MAV_LOG(kInfo) << "mission flight ended at its " << NsToSeconds(t_ns_) << " s limit";
    return;
  }
  score_ = eval::ScoreFlightTask(loaded->config.task, loaded->trace,
                                 static_cast<int>(loaded->sim.collisions().size()));
  const double clearance = loaded->sim.min_clearance_m();
  min_clearance_m_ = std::isfinite(clearance) ? clearance : 0.0;
  MAV_LOG(kInfo) << "flight " << loaded->config.task.name << " finished at " << NsToSeconds(t_ns_)
                 << " s: " << score_->points << " of " << score_->max_points << " points, "
                 << collisions_total_ << " collisions";
}

Status Flight::Run(const TaskContext& context, const FlightRun& run) {
  std::shared_ptr<Loaded> loaded;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    loaded = loaded_;
  }
  MAV_CHECK(loaded != nullptr);
  if (!loaded->config.lockstep) {  // lock-step has no real-time factor
    loaded->pacer = RealTimePacer(loaded->config.real_time_factor, kMaxLatenessNs);
    loaded->pacer.Anchor(loaded->sim.t_ns(), context.NowNs());
  }
  const int64_t until_ns = run.until_s > 0 ? SecondsToNs(run.until_s) : 0;
  const int rotor_count = loaded->config.simulation.vehicle.rotor_count;
  if (loaded->config.lockstep && loaded->step == 0 && !loaded->published) {
    const int64_t give_up_ns = MonotonicNowNs() + SecondsToNs(loaded->config.lockstep_timeout_s);
    while ((io_->ActuatorWriters() == 0 || io_->ImuReaders() == 0) &&
           MonotonicNowNs() < give_up_ns) {
      if (!context.SleepUntil(MonotonicNowNs() + 10'000'000)) return Status::Ok();
    }
  }
  while (!context.ShouldStop()) {
    const sim::FlightStep& out = *loaded->out;
    if (!loaded->published) {
      std::string pause;
      if (until_ns > 0 && out.t_ns >= until_ns) {
        pause = "run_until_s " + Number(run.until_s) + " s reached";
      } else if (run.pause_on_goal && out.goal_published &&
                 loaded->goal_pause_step != loaded->step) {
        loaded->goal_pause_step = loaded->step;
        pause = "goal " + std::to_string(out.goal_index) + " published at " +
                Number(NsToSeconds(out.t_ns)) + " s";
      }
      if (!pause.empty()) {
        std::lock_guard<std::mutex> lock(mutex_);
        state_ = FlightState::kPaused;
        pause_reason_ = pause;
        return Status::Ok();
      }
      (void)PublishStep(out, loaded.get());  // errors are in last_error; the flight goes on
    }
    if (loaded->sim.done()) {
      std::lock_guard<std::mutex> lock(mutex_);
      FinishLocked(loaded.get());
      return Status::Ok();
    }
    bool timed_out = false;
    std::optional<sim::RotorVector> command = CommandForStep(context, loaded.get(), &timed_out);
    if (!command) {
      if (timed_out) {
        // Published again on resume: a controller that missed the step gets another chance (one
        // that answered already answers a repeated stamp with the same command).
        loaded->published = false;
        std::lock_guard<std::mutex> lock(mutex_);
        state_ = FlightState::kPaused;
        pause_reason_ = "lock-step timeout (see last_error)";
        MAV_LOG(kWarning) << last_error_.text();
      }
      return Status::Ok();
    }
    MAV_CHECK(command->size() == rotor_count);
    const int64_t start_ns = MonotonicNowNs();
    loaded->out = &loaded->sim.Step(*command);
    const sim::FlightStep& next = *loaded->out;
    const double step_ms = MsSince(start_ns);
    loaded->published = false;
    ++loaded->step;
    if (loaded->keep_trace) loaded->trace.push_back(TraceSample(next));
    // The frames whose shutter this step completed go out before the step's IMU sample.
    if (loaded->camera) PublishFrames(loaded.get());
    std::lock_guard<std::mutex> lock(mutex_);
    truth_ = next.truth;
    gyro_offset_ = loaded->sim.imu().gyro_offset();
    accel_offset_ = loaded->sim.imu().accel_offset();
    ++steps_;
    t_ns_ = next.t_ns;
    goal_index_ = next.goal_index;
    lifted_off_ = loaded->sim.lifted_off();
    position_ = next.truth.p_world;
    step_ms_.Add(step_ms);
    run_last_wall_ns_ = MonotonicNowNs();
    const std::vector<sim::Collision>& collisions = loaded->sim.collisions();
    for (size_t i = collisions_total_; i < collisions.size(); ++i) {
      if (collisions_.size() < kMaxCollisions) collisions_.push_back(collisions[i]);
      MAV_LOG(kWarning) << "collision at " << NsToSeconds(collisions[i].t_ns)
                        << " s: " << collisions[i].what;
    }
    collisions_total_ = collisions.size();
  }
  return Status::Ok();
}

}  // namespace mav::simulator_service
