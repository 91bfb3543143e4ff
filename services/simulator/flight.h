#pragma once
// The simulator service's flight mode, free of gRPC and protobuf: a Flight steps one contest task
// (sim::FlightSimulation, the very class mav-eval flies) on the one worker of a WorkQueue, on the
// rotor speeds a controller sends, and publishes the readings through a FlightIo (DDS in
// production, dds_io.h; a fake in tests):
//
//   step k:  publish the poses delivered in step k, IMU(t_k), ground truth(t_k)
//            lock-step: wait for the command stamped t_k (bounded: lockstep_timeout_s pauses the
//            flight with a last_error naming the step, never a hang)
//            real time: sleep until t_{k+1} is due, take the newest command (none, or older than
//            command_stale_s of simulated time: the vehicle's own failsafe flies it, see
//            mav/sim/failsafe.h: level, 0.4 m/s down, motors off on the ground until fresh
//            commands come; once it flies, only an armed command takes the vehicle back: a
//            restarted controller that is not armed yet does not stop the rotors in the air)
//            FlightSimulation::Step(command) -> step k+1
//   end:     FINISHED, scored with eval::ScoreFlightTask (the contest's scripts) on the truth.
// Lock-step waits (at most lockstep_timeout_s) before the very first step until a controller is
// discovered (an actuator writer and an IMU reader matched): the first samples of a VOLATILE
// stream would otherwise go to nobody.
//
// State machine (simulator.proto): IDLE --Load--> LOADED --Start--> RUNNING --Pause / run_until_s
// / pause_on_goal / lock-step timeout--> PAUSED --Start--> RUNNING --(duration)--> FINISHED;
// any --Load--> LOADED. The run is one long task of the queue; Pause and Load interrupt it (a
// reset of the queue) between steps.
//
// Commands are checked at this edge: a command whose rotor count differs from the vehicle's or
// that holds a non-finite speed is rejected (counted, last_error) and not flown; FlightSimulation
// MAV_CHECKs the size, so nothing unchecked reaches it.
//
// Memory: the ground-truth trace for the score (~104 B per step) is capped at kMaxTraceSteps
// (a task with more steps is refused at Load); collisions are kept up to kMaxCollisions (the
// rest counted); runtime statistics keep the last 1000 steps.
//
// Thread-safety: every public method may be called from any thread.

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "mav/common/last_error.h"
#include "mav/common/stats.h"
#include "mav/common/status.h"
#include "mav/common/termination.h"
#include "mav/common/work_queue.h"
#include "mav/dataset/flight_task.h"
#include "mav/dataset/types.h"
#include "mav/eval/contest_score.h"
#include "mav/mission/vehicle.h"
#include "mav/sim/collision_world.h"
#include "mav/sim/flight_simulation.h"

namespace mav::sim {
struct RenderedFrame;
}

namespace mav::simulator_service {

// One actuator command as it arrived (validated by the Flight, not by the transport).
struct ActuatorInput {
  int64_t t_ns = 0;  // the controller's time line: the IMU stamp it answers
  uint64_t sequence = 0;
  bool armed = false;
  std::vector<double> rotor_speeds_radps;
};

// Where a flight publishes and where its commands come from. Called from the flight's worker
// only (one thread), so implementations need no locking of their own for these calls.
class FlightIo {
 public:
  virtual ~FlightIo() = default;
  virtual Status PublishFlightImu(uint64_t sequence, const dataset::ImuSample& sample) = 0;
  // A pose sensor's sample T_world_sensor, stamped pose.t_ns, child frame `frame_id`, with the
  // sensor's noise as a diagonal covariance.
  virtual Status PublishFlightPose(uint64_t sequence, const sim::PoseSample& pose,
                                   const std::string& frame_id, double position_sigma_m,
                                   double orientation_sigma_rad) = 0;
  virtual Status PublishFlightGroundTruth(uint64_t sequence,
                                          const dataset::GroundTruthState& state) = 0;
  // A mission flight's stereo pair (the EuRoC raw rig, not rectified), sequence = frame index.
  virtual Status PublishFlightStereo(const sim::RenderedFrame& frame) = 0;
  // Matched readers of the stereo stream.
  virtual uint32_t StereoReaders() = 0;
  // Forgets commands received so far (a new flight starts clean).
  virtual void DiscardCommands() = 0;
  // Waits at most timeout_ns for a command stamped in [min_t_ns, max_t_ns] and returns the newest
  // such one received (nullopt after the timeout); commands stamped outside are consumed and
  // dropped (lock-step asks for exactly its step's stamp, so a late answer to an earlier flight is
  // never flown). `*received` counts every sample taken.
  virtual std::optional<ActuatorInput> WaitForCommand(int64_t min_t_ns, int64_t max_t_ns,
                                                      int64_t timeout_ns, uint64_t* received) = 0;
  virtual uint32_t ActuatorWriters() = 0;
  // Matched readers of the IMU stream (the controller's).
  virtual uint32_t ImuReaders() = 0;
  virtual uint32_t domain() const = 0;
};

enum class FlightState { kIdle, kLoaded, kRunning, kPaused, kFinished };
const char* FlightStateName(FlightState state);

struct FlightConfig {
  static constexpr double kMinRealTimeFactor = 0.01;
  static constexpr double kMaxRealTimeFactor = 100;
  dataset::FlightTask task;
  uint64_t seed = 1;
  // Lock-step (deterministic, as fast as the controller answers) or real time.
  bool lockstep = false;
  double real_time_factor = 1.0;    // real time: simulated s per wall s, [0.01, 100]
  double lockstep_timeout_s = 2.0;  // lock-step: wait per step before pausing, (0, 600]
  // Real time: a command older than this (simulated time) is stale: the vehicle's failsafe
  // takes over (docs/contracts.md: 100 ms), (0, 10].
  double command_stale_s = 0.1;
  sim::FlightSimulationOptions simulation;

  // The field named as simulator.proto spells it ("real_time_factor: ..."); OptionsValid checks
  // everything but the task.
  bool IsValid(std::string* why) const;
  bool OptionsValid(std::string* why) const;
};

// A mission flight's world and camera (LoadFlightTask's MissionFlight): the vehicle flies in the
// preset's world and, for pose source vo, renders the forward stereo camera from its state
// (mission::VehicleCamera).
struct MissionScene {
  sim::Preset preset;  // its world's textures built for the seed
  mission::VehicleOptions vehicle;
};

struct FlightRun {
  double until_s = 0;          // 0 = to the end
  bool pause_on_goal = false;  // pause before publishing a step that publishes a goal
};

struct FlightStatus {
  FlightState state = FlightState::kIdle;
  std::optional<FlightConfig> config;
  int64_t t_ns = 0;
  uint64_t steps = 0;
  uint64_t imu_published = 0;
  uint64_t poses_published = 0;
  uint64_t ground_truth_published = 0;
  uint64_t commands_received = 0;
  uint64_t commands_rejected = 0;
  uint64_t stale_steps = 0;
  int goal_index = -1;
  std::vector<sim::Collision> collisions;
  uint64_t collisions_total = 0;  // kMaxCollisions are kept
  bool lifted_off = false;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  double speed_factor = 0;  // simulated s per wall s since the last Start
  RuntimeStats step_ms;
  RuntimeStats command_wait_ms;
  std::string pause_reason;
  std::string last_error;                // of this run (cleared by LoadFlightTask and StartFlight)
  double last_error_age_s = 0;           // wall seconds since it was set (0: none)
  std::optional<eval::TaskScore> score;  // when FINISHED
  double min_clearance_m = 0;            // 0 without a map
  uint32_t actuator_writers = 0;
  uint32_t dds_domain = 0;
  // The current step's true state.
  sim::MulticopterState truth;
  Eigen::Vector3d gyro_offset = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_offset = Eigen::Vector3d::Zero();
  bool is_mission = false;
  uint64_t frames_published = 0;
  RuntimeStats render_ms;
  uint32_t stereo_readers = 0;
  bool failsafe_active = false;
  uint64_t failsafe_engagements = 0;
  double failsafe_s = 0;
};

class Flight {
 public:
  static constexpr size_t kMaxTraceSteps = 1'000'000;  // 2.8 h at 100 Hz, ~104 MB
  static constexpr size_t kMaxCollisions = 1000;

  // `io` is not owned and must outlive the flight.
  explicit Flight(FlightIo* io);
  ~Flight();
  Flight(const Flight&) = delete;
  Flight& operator=(const Flight&) = delete;

  // Builds the simulation for `config` (InvalidArgument naming the field; NotFound / DataLoss
  // for the task's map unless `world` is given; ResourceExhausted for a task longer than
  // kMaxTraceSteps), then replaces the loaded flight: a running one is stopped first; state
  // LOADED at t = 0. DEADLINE_EXCEEDED (nothing changed) when `deadline` stops first. With
  // `mission`, a mission flight: no score trace (no step cap) and, for pose source vo, the
  // camera.
  Status Load(const FlightConfig& config, std::shared_ptr<const sim::CollisionWorld> world,
              const Termination& deadline = {},
              const std::shared_ptr<const MissionScene>& mission = nullptr);
  // FailedPrecondition unless LOADED or PAUSED; InvalidArgument for run.until_s not after the
  // flight's time (or not finite).
  Result<FlightStatus> Start(const FlightRun& run);
  // FailedPrecondition unless RUNNING. Returns after the step in flight.
  Result<FlightStatus> Pause(const std::string& reason = "PauseFlight");
  FlightStatus GetStatus() const;
  bool running() const;

  // Stops the worker (a running flight ends). Idempotent.
  void Shutdown();

 private:
  struct Loaded;  // the simulation and what the worker keeps of it
  // The vehicle's failsafe (real time): off, flying it down, or landed with the motors off
  // until fresh commands come (a bounce on touchdown does not restart it).
  enum class FailsafePhase { kOff, kDescending, kLanded };
  static FailsafePhase NextFailsafePhase(FailsafePhase before, bool stale, bool on_ground);
  void LogFailsafeLocked(int64_t t_ns, FailsafePhase before, FailsafePhase phase,
                         const sim::MulticopterState& vehicle, const Loaded& loaded);
  // On the worker: steps until the end, a pause condition, or the task goes stale.
  Status Run(const TaskContext& context, const FlightRun& run);
  Status PublishStep(const sim::FlightStep& out, Loaded* loaded);
  // A mission flight's camera after a step: renders and publishes the frames now due.
  void PublishFrames(Loaded* loaded);
  // The command for the current step: lock-step waits, real time sleeps until due. nullopt:
  // interrupted (the task went stale) or timed out (paused, last_error set).
  std::optional<sim::RotorVector> CommandForStep(const TaskContext& context, Loaded* loaded,
                                                 bool* timed_out);
  std::optional<sim::RotorVector> Checked(const ActuatorInput& input, int rotor_count);
  void FinishLocked(Loaded* loaded);
  FlightStatus StatusLocked() const;

  FlightIo* io_;
  WorkQueue queue_;
  std::mutex command_mutex_;  // one command at a time (Load, Start, Pause)

  mutable std::mutex mutex_;
  // Guarded by mutex_ (the worker updates them between steps).
  FlightState state_ = FlightState::kIdle;
  std::optional<FlightConfig> config_;
  // Owned by whoever holds it: the worker while running, a command while the queue is reset.
  std::shared_ptr<Loaded> loaded_;
  uint64_t steps_ = 0, imu_published_ = 0, poses_published_ = 0, gt_published_ = 0;
  uint64_t commands_received_ = 0, commands_rejected_ = 0, stale_steps_ = 0;
  bool failsafe_active_ = false;
  uint64_t failsafe_engagements_ = 0;
  int64_t failsafe_ns_ = 0;  // simulated time flown by the failsafe
  int64_t t_ns_ = 0;
  int goal_index_ = -1;
  std::vector<sim::Collision> collisions_;
  uint64_t collisions_total_ = 0;
  bool lifted_off_ = false;
  Eigen::Vector3d position_ = Eigen::Vector3d::Zero();
  int64_t run_start_wall_ns_ = 0, run_start_t_ns_ = 0, run_last_wall_ns_ = 0;
  RuntimeWindow step_ms_;
  RuntimeWindow command_wait_ms_;
  std::string pause_reason_;
  LastError last_error_;
  std::optional<eval::TaskScore> score_;
  double min_clearance_m_ = 0;
  sim::MulticopterState truth_;
  Eigen::Vector3d gyro_offset_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_offset_ = Eigen::Vector3d::Zero();
  uint64_t frames_published_ = 0;
  RuntimeWindow render_ms_;
  bool is_mission_ = false;
};

}  // namespace mav::simulator_service
