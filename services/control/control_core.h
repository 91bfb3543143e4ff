#pragma once
// The control service's core, free of gRPC, protobuf and DDS: a ControlCore holds one
// control::Autopilot (libs/control/autopilot.h: estimator + paper/Lee controller + allocation +
// modes and failsafes, the very code mav-eval flies) and answers every IMU sample with exactly
// one actuator command stamped with the sample's t_ns.
//
//   DDS read loop thread:  poses (drained first) --OnPose--> Autopilot::FeedPose
//                          IMU (wakes the loop)  --OnImu---> Autopilot::FeedImu --> CommandSink
//                          every poll period     --OnPoll--> Autopilot::CheckImuTimeout
//   RPC threads:           Arm / Disarm / Hover / SetTrajectory / SetGains / Configure / Get*
//
// Why the autopilot is driven from the DDS read loop's thread under a mutex rather than owned by
// a WorkQueue worker (mav/common/work_queue.h): the IMU-rate step must be fast and in order. The
// read loop is one thread that takes the samples in arrival order (poses before the IMU sample
// that wakes it, transport::DdsReadLoop), so the steps run in order without a queue; a WorkQueue
// task per 10 ms sample would add an allocation, a future and a thread hand-off to every step,
// and in lock-step that latency is on the critical path of every simulated step (the simulator
// waits for each command). The RPCs must not race the step: they take the same mutex, and every
// command they carry is microseconds of work (a mode switch, a GoTo spline of 8 segments, a
// gains swap), so a command lands between two steps and never inside one, and a step waits at
// most that long. The one slow command, Configure (the a-priori EKF weights take a few ms), builds
// the new autopilot outside the mutex and swaps it in. Nothing here blocks on I/O while holding
// the mutex except the command write itself (a DDS write, ~10 us, kept inside so that commands
// leave in step order).
//
// Failsafes are the autopilot's: no pose for pose_timeout_s (IMU time line) -> level on the IMU
// and descend; no IMU for imu_timeout_s (wall clock, OnPoll) -> the ImuLossPolicy. In lock-step
// (ControlConfig::lockstep) the wall-clock watchdog is off: a paused simulation is not a lost
// IMU, and the simulator's own command timeout notices a controller that stopped answering; a
// vanished simulator is told from a paused one by the IMU writer's DDS liveliness (OnPoll's
// imu_publishers_alive dropping to 0): the ImuLossPolicy then applies in lock-step too.
//
// Status tells the truth about the inputs: the estimate is `stale` (and not reported converged)
// while no IMU publisher is alive, no IMU sample came for kStaleImuS of wall time (real time),
// or no pose was merged for pose_timeout_s of IMU time.
//
// Taking over in the air (SetTakeover, mav-control --takeover: a controller restarted while the
// vehicle flies on its own failsafe): once the autopilot is ReadyForTakeover the core tries
// ArmInAir once; airborne, it holds where the vehicle is; on the ground it logs why and stays
// disarmed (a vehicle carried into the air later is never armed by surprise).
//
// Lock-step pose sources (ControlConfig::lockstep_poses, a localization service tracking a
// lock-stepped simulator's camera): their poses are held and merged when the IMU's time reaches
// stamp + latency, and the DDS read loop asks AwaitingPose before each IMU sample, draining the
// pose reader until every frame due by then is answered (a pose or a LOST sample, OnPoseAnswer)
// or the wait runs out (GiveUpWaiting: the source is silent until it answers again). The
// estimate then depends on the simulated clock only, never on how fast the VO ran.
//
// Memory: fixed (the autopilot's ring buffers and 1000-sample statistics windows; at most
// kMaxHeldPoses held lock-step poses per source).
// Thread-safety: every public method may be called from any thread.

#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "mav/common/last_error.h"
#include "mav/common/stats.h"
#include "mav/common/status.h"
#include "mav/common/termination.h"
#include "mav/control/autopilot.h"
#include "mav/geometry/polynomial_trajectory.h"
#include "mav/geometry/se3.h"
#include "services/control/control_config.h"

namespace mav::control_service {

// One actuator command for the data plane.
struct ActuatorOutput {
  uint64_t sequence = 0;
  int64_t t_ns = 0;  // the IMU sample's stamp it answers
  bool armed = false;
  control::RotorVector rotor_speeds_radps;
};

// Where commands go (DDS in production, dds_io.h; a recorder in tests). Called from the thread
// that feeds the IMU, with the core's mutex held: keep it short.
class CommandSink {
 public:
  virtual ~CommandSink() = default;
  virtual Status PublishCommand(const ActuatorOutput& command) = 0;
  virtual uint32_t ActuatorSubscribers() { return 0; }
};

// Wall-clock stamps of a pose estimated from a stereo frame (PoseWithCovariance's), ns; all 0 for
// a pose not from a frame. pose_take_ns: when mav-control's DDS reader took the pose.
struct PoseStamps {
  int64_t frame_publish_ns = 0;
  int64_t frame_receive_ns = 0;
  int64_t pose_publish_ns = 0;
  int64_t pose_take_ns = 0;
};

// The end-to-end latency of vision poses, capture -> in the estimator, and its hops (wall clock,
// the last 1000 poses): the stereo frame over DDS (publish -> the localization took it), the
// localization (took it -> published the pose: queue and VO), the pose over DDS (publish ->
// mav-control took it), and mav-control (took it -> merged, or held for a lock-step release).
struct PoseLatency {
  RuntimeStats total_ms;
  RuntimeStats frame_transport_ms;
  RuntimeStats localization_ms;
  RuntimeStats pose_transport_ms;
  RuntimeStats merge_ms;
};

class PoseLatencyWindows {
 public:
  // Adds one pose (ignored when it has no frame stamps); `merged_ns`: when OnPose was done.
  void Add(const PoseStamps& s, int64_t merged_ns);
  PoseLatency Summary() const;
  void Clear();

 private:
  static constexpr size_t kWindow = 1000;
  RuntimeWindow total_{kWindow}, frame_transport_{kWindow}, localization_{kWindow},
      pose_transport_{kWindow}, merge_{kWindow};
};

struct ControlCoreStatus {
  bool configured = false;
  std::optional<ControlConfig> config;  // the effective one (gains as last set)
  control::AutopilotStatus autopilot;
  uint64_t commands_published = 0;  // since Configure
  uint64_t imu_rejected = 0;        // not finite, or older than the previous sample
  uint64_t imu_repeated = 0;        // a repeated stamp, answered again with its command
  uint64_t poses_rejected = 0;
  double imu_rate_hz = 0;  // per wall second (lock-step: the stepping speed)
  double pose_rate_hz = 0;
  uint64_t lockstep_frames_missed = 0;
  bool lockstep_source_silent = false;
  RuntimeStats loop_ms;  // OnImu: sample in -> command written
  PoseLatency pose_latency;
  std::string last_error;
  double last_error_age_s = 0;  // wall seconds since it was set (0: none)
  uint32_t actuator_subscribers = 0;
  // The inputs (see the class comment): stale = the estimate is not being fed.
  bool estimator_stale = false;
  std::optional<double> imu_age_s;   // wall seconds since the last IMU sample
  std::optional<double> pose_age_s;  // IMU seconds since the last merged pose
  uint32_t imu_publishers_alive = 0;
  bool takeover_pending = false;
};

struct ControlCoreState {
  bool configured = false;
  bool armed = false;
  control::AutopilotState autopilot;
  int64_t last_pose_t_ns = 0;
  // The IMU time of the first sample after its arrival minus its stamp.
  double last_pose_delay_ms = 0;
  bool estimator_initialized = false;
  int64_t last_pose_arrival_ns = 0;  // the IMU time it was accepted at
  uint64_t poses_gated = 0;
  std::vector<geometry::SE3> source_frames;  // control::Estimator::source_frame, per source
  bool moving = false;
};

class ControlCore {
 public:
  // `sink` (not owned) must outlive the core.
  explicit ControlCore(CommandSink* sink);
  ControlCore(const ControlCore&) = delete;
  ControlCore& operator=(const ControlCore&) = delete;

  // Builds the autopilot (InvalidArgument naming the field) and swaps it in: estimate, counters
  // and reference restart. FailedPrecondition while armed; DEADLINE_EXCEEDED (nothing changed)
  // when `deadline` stops before the swap.
  Status Configure(const ControlConfig& config, const Termination& deadline = {});
  bool configured() const;

  // ---- Data plane (the DDS read loop's thread) ----
  // Feeds one IMU sample and publishes its command. A repeated stamp is answered with the
  // command it got before (a lock-stepped simulator resuming after a timeout republishes its
  // step); an older one is rejected (counted). Ignored while unconfigured.
  void OnImu(const control::ImuMeasurement& imu);
  // A pose T_world_sensor of the source whose frame is `frame_id`; an unknown frame is rejected
  // (counted, last_error). `stamps` (a pose from a stereo frame) add to the pose latency.
  void OnPose(const std::string& frame_id, int64_t t_ns, const geometry::SE3& T_world_sensor,
              const PoseStamps& stamps = {});
  // A lock-step source's answer for the frame stamped t_ns that carries no usable pose (LOST):
  // the frame is answered (counted as rejected with `why`). Other sources: RejectPose.
  void OnPoseAnswer(const std::string& frame_id, int64_t t_ns, const std::string& why);
  // Whether a lock-step source (not silent) has not answered a frame due by the IMU time t_ns.
  bool AwaitingPose(int64_t imu_t_ns) const;
  // The wait for the frames due by imu_t_ns ran out: those sources are silent (logged, counted)
  // until they answer again.
  void GiveUpWaiting(int64_t imu_t_ns);
  // The longest lock-step wait of the configured sources (0: none lock-stepped).
  int64_t LockstepWaitNs() const;
  // A sample the transport could not use (malformed); counted with its reason.
  void RejectImu(const std::string& why);
  void RejectPose(const std::string& why);
  // The IMU watchdog on the service's clock (MonotonicNowNs), off in lock-step; and the IMU
  // writers alive now (DDS liveliness): when they drop to 0 the simulator is gone.
  void OnPoll(int64_t now_wall_ns, uint32_t imu_publishers_alive);

  // Arm in the air (ArmInAir) as soon as the autopilot is ready (see the class comment); false
  // cancels a pending takeover. Needs the configuration (FailedPrecondition).
  Status SetTakeover(bool enabled);

  // ---- Commands (RPC threads); FailedPrecondition when unconfigured ----
  // in_air: Autopilot::ArmInAir (a vehicle already flying) instead of Arm.
  Status Arm(bool in_air = false);
  void Disarm();
  // immediate: hold (position, yaw) at once; else a smooth move (limits or the configured ones).
  Status Hover(const Eigen::Vector3d& position, double yaw_rad,
               const std::optional<control::GoToLimits>& limits, bool immediate);
  Status SetTrajectory(const geometry::PolynomialTrajectory& trajectory, int64_t start_t_ns,
                       const Eigen::Vector3d& offset, bool allow_jump);
  // FailedPrecondition when the configured controller is the other one.
  Status SetPaperGains(const control::PaperControllerGains& gains);
  Status SetLeeGains(const control::LeeControllerGains& gains);

  ControlCoreStatus GetStatus() const;
  ControlCoreState GetState() const;

 private:
  // Samples per wall second over ~1 s windows.
  // A lock-step source's state (parallel to the configured sources).
  struct Held {
    int64_t t_ns = 0;
    geometry::SE3 T_world_sensor;
  };
  struct LockstepSource {
    bool enabled = false;
    int64_t latency_ns = 0, period_ns = 0, wait_ns = 0;
    int64_t first_frame_ns = -1;  // the first frame awaited (set by the first IMU sample)
    int64_t answered_ns = -1;     // the latest stamp answered
    bool silent = false;
    std::vector<Held> held;  // usable poses not merged yet, in stamp order
  };
  static constexpr size_t kMaxHeldPoses = 64;
  // The stamp of the first frame of `s` due by imu_t_ns and not answered (nullopt: none).
  static std::optional<int64_t> DueUnanswered(const LockstepSource& s, int64_t imu_t_ns);
  // The held poses due by imu_t_ns go to the estimator (before the IMU sample).
  void ReleaseHeldLocked(int64_t imu_t_ns);
  Status PublishLocked(int64_t t_ns, bool armed, const control::RotorVector& speeds);
  Status CheckConfiguredLocked() const;
  // The pending takeover, after an IMU step.
  void TryTakeoverLocked();
  bool StaleLocked(int64_t now_wall_ns) const;
  // OnPose's work; false when the pose was rejected (unconfigured, unknown frame).
  bool OnPoseLocked(const std::string& frame_id, int64_t t_ns, const geometry::SE3& T_world_sensor);

  CommandSink* sink_;
  mutable std::mutex mutex_;
  // Guarded by mutex_.
  std::optional<control::Autopilot> autopilot_;
  std::optional<ControlConfig> config_;
  uint64_t sequence_ = 0;  // DDS sequence numbers: since the start of the process
  uint64_t commands_ = 0;  // since Configure
  bool have_imu_ = false;
  int64_t last_imu_t_ns_ = 0;
  int64_t last_imu_wall_ns_ = 0;
  control::RotorVector last_command_;
  bool last_armed_ = false;
  int64_t last_pose_delay_ns_ = 0;
  int64_t pending_pose_t_ns_ = -1;  // a merged pose whose delay the next IMU sample measures
  uint64_t imu_rejected_ = 0, imu_repeated_ = 0, poses_rejected_ = 0;
  std::vector<LockstepSource> lockstep_;
  uint64_t lockstep_frames_missed_ = 0;
  RateMeter imu_rate_, pose_rate_;
  RuntimeWindow loop_ms_{1000};
  PoseLatencyWindows pose_latency_;
  LastError last_error_;
  uint32_t imu_publishers_alive_ = 0;
  bool imu_publisher_seen_ = false;  // alive > 0 once: a drop to 0 is a loss
  bool takeover_pending_ = false;
};

// Wall seconds without an IMU sample after which a real-time estimate is reported stale.
inline constexpr double kStaleImuS = 0.5;

}  // namespace mav::control_service
