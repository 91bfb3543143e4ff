#pragma once
// The localization service's core, free of gRPC, protobuf and DDS: a Localizer runs one
// localization::RigOdometry (libs/localization/rig_odometry.h: the stereo VO, the body-frame pose
// and the covariance heuristic, the very code mav-eval scores) on the one worker of a WorkQueue.
//
//   DDS reader --SubmitLive (drop-oldest)-->  [WorkQueue, queue_length]  --> worker: RigOdometry
//   ProcessStereoPair --Process (reject)--->                                 --> PoseSink, history
//
// Memory: at most queue_length frames wait (~720 KB each for EuRoC's 752x480 pair); the
// trajectory history keeps the newest `max_trajectory_poses` poses (~0.4 KB each; the oldest are
// dropped and counted), the runtime statistics the last 1000 frames.
//
// Thread-safety: every public method may be called from any thread.

#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "mav/common/stats.h"
#include "mav/common/status.h"
#include "mav/common/termination.h"
#include "mav/common/work_queue.h"
#include "mav/dataset/stereo_pair.h"
#include "mav/geometry/se3.h"
#include "mav/localization/rig_odometry.h"

namespace mav::localization_service {

using localization::Method;
using localization::OutputFrame;
using localization::ReportedState;
using localization::RigPose;

struct LocalizerConfig {
  localization::RigOdometryOptions odometry;
  // Input queue length in frames, [1, 100].
  int queue_length = 2;
  // The IMU's orientation in the body frame: AddGyro's samples are rotated by it.
  Eigen::Quaterniond R_body_imu = Eigen::Quaterniond::Identity();

  bool IsValid(std::string* why) const;
};

// One stereo pair to process. Images CV_8UC1 of the calibration's size.
struct StereoInput : dataset::StereoPair {
  StereoInput() = default;
  explicit StereoInput(dataset::StereoPair pair) : dataset::StereoPair(std::move(pair)) {}
  // Publish the result through the PoseSink (false: ProcessStereoPair's skip_publish).
  bool publish = true;
};

// Where results are published (DDS in production, dds_io.h; a recorder in tests). Called from
// the worker thread only.
class PoseSink {
 public:
  virtual ~PoseSink() = default;
  virtual Status PublishPose(const RigPose& pose, OutputFrame frame) = 0;
};

enum class LocalizerState { kUnconfigured, kReady, kRunning };
const char* LocalizerStateName(LocalizerState state);

struct LocalizerStatus {
  LocalizerState state = LocalizerState::kUnconfigured;
  std::optional<LocalizerConfig> config;
  uint64_t frames_processed = 0;
  uint64_t frames_dropped = 0;  // live frames dropped because the queue was full
  uint64_t frames_lost = 0;
  uint64_t frames_degraded = 0;
  uint64_t gyro_samples = 0;
  uint64_t frames_rejected = 0;  // malformed live frames (size, checksum, time not increasing)
  uint64_t poses_forgotten = 0;  // oldest poses dropped from the trajectory history (its cap)
  double fps = 0;                // processed frames per wall second over the last ~2 s
  std::optional<RigPose> last;
  RuntimeStats processing_ms;
  uint64_t keyframes = 0;
  uint32_t queue_depth = 0;
};

class Localizer {
 public:
  static constexpr size_t kDefaultMaxTrajectoryPoses = 100'000;  // 83 min at 20 Hz

  // `sink` (not owned, may be null) must outlive the localizer.
  explicit Localizer(PoseSink* sink, size_t max_trajectory_poses = kDefaultMaxTrajectoryPoses);
  ~Localizer();
  Localizer(const Localizer&) = delete;
  Localizer& operator=(const Localizer&) = delete;

  // Builds the rectifier and the odometry for `config` (InvalidArgument naming the field), then
  // replaces the running configuration: queued frames are discarded, the trajectory and counters
  // restart. Waits for the frame in flight. DEADLINE_EXCEEDED (nothing changed) when `deadline`
  // stops before the new configuration is in place.
  Status Configure(const LocalizerConfig& config, const Termination& deadline = {});

  // Forgets the trajectory and the tracking state; keeps the configuration. The next frame
  // starts at `T_world_body0` if given, else the configured initial pose. FailedPrecondition
  // when unconfigured; DEADLINE_EXCEEDED as Configure.
  Status Reset(const std::optional<geometry::SE3>& T_world_body0, const Termination& deadline = {});

  // Checks a frame against the configuration: InvalidArgument naming `field_prefix`.left/right
  // (empty, size differs from the calibration, not CV_8UC1) or `field_prefix`.t_ns (not after
  // the previous frame's); FailedPrecondition when unconfigured.
  Status CheckInput(const StereoInput& input, const std::string& field_prefix) const;

  // Live input (DDS): never blocks; when the queue is full the oldest queued live frame is
  // dropped (counted). Returns OK when queued (perhaps after dropping an older live frame),
  // RESOURCE_EXHAUSTED when dropped itself (the queue holds only unary requests),
  // INVALID_ARGUMENT when malformed (counted as rejected), FAILED_PRECONDITION unconfigured.
  Status SubmitLive(StereoInput input);

  // One gyro sample of the IMU topic (the IMU's frame, rad/s), from any thread: rotated into the
  // body frame (LocalizerConfig::R_body_imu), buffered (at most RigOdometry::kGyroHistory, the
  // oldest dropped) and handed to the odometry on the worker before the next frame (dense VO:
  // rotation prior and consistency check, dense_vo.h).
  void AddGyro(int64_t t_ns, const Eigen::Vector3d& omega_imu);
  // Counts a live frame that was malformed before it could become a StereoInput (bad checksum).
  void CountRejected();

  // Unary input: validates like CheckInput, queues the frame (RESOURCE_EXHAUSTED when the queue
  // is full) and waits for its pose until `deadline` (DEADLINE_EXCEEDED; a frame that had not
  // started is withdrawn and changes nothing).
  Result<RigPose> Process(StereoInput input, const Termination& deadline);

  bool configured() const;
  LocalizerStatus GetStatus() const;
  // Trajectory points with start_t_ns <= t_ns <= end_t_ns (0 = open end), oldest first.
  std::vector<RigPose> Trajectory(int64_t start_t_ns, int64_t end_t_ns) const;

  // Stops the worker (waiting calls fail with Unavailable). Idempotent.
  void Shutdown();

 private:
  // Queues `input` (the caller holds no lock); records its time stamp as accepted.
  Ticket<Result<RigPose>> Submit(StereoInput input, QueuePolicy policy,
                                 const Termination& deadline);
  // Runs on the worker.
  Result<RigPose> ProcessOnWorker(const StereoInput& input);
  void ClearHistoryLocked();
  Status CheckInputLocked(const StereoInput& input, const std::string& field_prefix) const;

  PoseSink* sink_;
  const size_t max_trajectory_poses_;
  WorkQueue queue_;
  // Only touched on the worker thread.
  std::unique_ptr<localization::RigOdometry> odometry_;
  ReportedState last_logged_state_ = ReportedState::kUnspecified;  // worker only
  std::deque<localization::GyroSample> pending_gyro_;              // guarded by mutex_

  mutable std::mutex mutex_;
  // Guarded by mutex_.
  std::optional<LocalizerConfig> config_;
  int64_t last_accepted_t_ns_ = 0;  // newest t_ns queued or processed since Configure/Reset
  bool have_accepted_ = false;
  std::deque<RigPose> trajectory_;
  uint64_t frames_processed_ = 0;
  uint64_t frames_dropped_ = 0;
  uint64_t frames_lost_ = 0;
  uint64_t frames_degraded_ = 0;  // guarded by mutex_
  uint64_t gyro_samples_ = 0;     // guarded by mutex_; handed to the odometry
  uint64_t frames_rejected_ = 0;
  uint64_t poses_forgotten_ = 0;
  uint64_t keyframes_ = 0;
  std::deque<int64_t> done_wall_ns_;  // completion times of the last ~2 s (fps)
  RuntimeWindow processing_ms_;
};

}  // namespace mav::localization_service
