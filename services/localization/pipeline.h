#pragma once
// The localization service's domain core, free of gRPC, protobuf and DDS: the Localizer, whose
// one worker thread owns the stereo odometry object (sparse StereoScan-style or dense direct VO,
// libs/localization) and processes raw or rectified stereo pairs from a bounded input queue.
//
//   DDS reader thread --SubmitLive-->  [bounded queue, drop-oldest]  --> worker: rectify, VO,
//   ProcessStereoPair --SubmitAndWait->  (rejected when full)              pose, covariance
//                                                                          --> PoseSink, trajectory
//
// Frames. The odometry runs on rectified pairs. Raw frames (EuRoC's distorted rig) are rectified
// once per rig with camera::StereoRectifier (maps computed at Configure). A frame flagged
// `rectified` is taken to be already in the rectified geometry this service uses (the output of
// the same rectifier, or the ideal pair of a rectified calibration) and is not remapped.
//
// Poses. The VO reports T_rect0(0)_rect0(k), the rectified left camera at frame k in the frame of
// the rectified left camera at the first frame. The service publishes the body (IMU) frame in a
// world frame fixed by the initial pose T_world_body0 (Configure/Reset; identity by default):
//   T_world_body(k) = T_world_body0 * T_body_rect0 * T_rect0(0)_rect0(k) * T_body_rect0^-1
// with T_body_rect0 = StereoRectifier::T_body_rect0() (T_body_cam0 for a rectified calibration).
// With output_frame "cam0" the pose is T_world_cam0(k) = T_world_body(k) * T_body_cam0.
//
// Covariance: a HEURISTIC, not a propagated estimate (the VO does not compute one). Each frame
// adds an isotropic increment to a running diagonal covariance (a random walk, like the drift of
// odometry):
//   sigma_p = s * (kDriftFraction * |dp| + kPositionFloorM)      position, world frame
//   sigma_r = s * (kDriftFraction * |dtheta| + kRotationFloorRad) rotation, body frame
//   s = sqrt(nominal_support / max(support, 1)) * max(1, residual / nominal_residual)
// (sparse: support = RANSAC inliers, nominal 100, residual = mean reprojection error, nominal
// 0.5 px; dense: support = pixels used, nominal 2000, residual = RMS photometric error, nominal
// 10 grey levels). A LOST frame adds kLostPositionSigmaM and kLostRotationSigmaRad. The numbers
// are chosen from the methods' ~1-2 % relative error on the room data sets (docs/services.md).
//
// Tracking state reported: INITIALIZING for the first frame of a trajectory and for a frame that
// re-initialises after a loss (the VO's reference_reset), LOST with the VO's reason, else OK.
//
// Thread-safety: every public method may be called from any thread.

#include <array>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "mav/camera/stereo.h"
#include "mav/common/status.h"
#include "mav/geometry/se3.h"
#include "mav/localization/dense_vo.h"
#include "mav/localization/odometry.h"
#include "mav/localization/sparse_vo.h"

namespace mav::localization_service {

using localization::Method;

enum class OutputFrame { kBody, kCam0 };
const char* OutputFrameName(OutputFrame frame);  // "body", "cam0"

// Same numbers as mav.v1.TrackingState / mav::dds::TrackingState.
enum class ReportedState { kUnspecified = 0, kInitializing = 1, kOk = 2, kLost = 3 };

struct LocalizerConfig {
  Method method = Method::kSparseSubpixel;
  // Options of the method that runs (the other one is ignored). sparse.mode is set from method.
  localization::SparseVoOptions sparse;
  localization::DenseVoOptions dense;
  // The raw rig; with calibration_rectified the rig is an ideal rectified pair (no distortion,
  // rows aligned) and images are used as they are.
  camera::StereoCalibration calibration;
  bool calibration_rectified = false;
  geometry::SE3 T_world_body0;
  OutputFrame output_frame = OutputFrame::kBody;
  // Input queue length in frames, [1, 100].
  int queue_length = 2;

  bool IsValid(std::string* why) const;
};

// One stereo pair to process. Images CV_8UC1 of the calibration's size.
struct StereoInput {
  int64_t t_ns = 0;
  cv::Mat left;
  cv::Mat right;
  bool rectified = false;
  // Publish the result through the PoseSink (false: ProcessStereoPair's skip_publish).
  bool publish = true;
};

struct StageTiming {
  double total_ms = 0;
  double rectify_ms = 0;
  double features_ms = 0;  // sparse: filters + NMS + descriptors; dense: keyframe depth map
  double matching_ms = 0;  // sparse: circular matching + bucketing (+ refinement)
  double motion_ms = 0;    // sparse: RANSAC + Gauss-Newton; dense: pyramid + alignment
};

// The result of one frame, in the output frame.
struct PoseOutput {
  int64_t t_ns = 0;
  uint64_t frame_index = 0;   // 0-based since Configure/Reset
  geometry::SE3 T_world_out;  // T_world_<output_frame>
  geometry::SE3 T_prev_cur;   // relative motion of the output frame since the previous frame
  std::array<double, 36> covariance{};  // row-major, [dp (world), dtheta (child)]
  ReportedState state = ReportedState::kUnspecified;
  std::string lost_reason;
  uint32_t matches = 0;   // sparse: circular matches; dense: keyframe pixels
  uint32_t inliers = 0;   // sparse: RANSAC inliers; dense: pixels used
  double residual = 0;    // sparse: mean reprojection error px; dense: RMS photometric error
  bool keyframe = false;  // dense: this frame became a keyframe
  StageTiming timing;
};

// Where results are published (DDS in production, dds_io.h; a recorder in tests). Called from
// the worker thread only.
class PoseSink {
 public:
  virtual ~PoseSink() = default;
  virtual Status PublishPose(const PoseOutput& pose, OutputFrame frame) = 0;
};

struct RuntimeSummary {
  uint64_t count = 0;
  double mean_ms = 0, median_ms = 0, p95_ms = 0, max_ms = 0;
};

enum class LocalizerState { kUnconfigured, kReady, kRunning };

struct LocalizerStatus {
  LocalizerState state = LocalizerState::kUnconfigured;
  std::optional<LocalizerConfig> config;
  uint64_t frames_processed = 0;
  uint64_t frames_dropped = 0;  // live frames dropped because the queue was full
  uint64_t frames_lost = 0;
  uint64_t frames_rejected = 0;  // malformed live frames (size, checksum, time not increasing)
  double fps = 0;                // processed frames per wall second over the last ~2 s
  std::optional<PoseOutput> last;
  RuntimeSummary processing_ms;
  uint64_t keyframes = 0;
  uint32_t queue_depth = 0;
};

// How a submitted frame fared.
enum class SubmitOutcome {
  kQueued,
  kQueuedDroppedOldest,  // live input: queued, the oldest queued live frame was dropped
  kDropped,              // live input: queue full of unary requests, this frame was dropped
  kQueueFull,            // unary input: rejected (RESOURCE_EXHAUSTED)
  kNotConfigured,
  kRejected,  // bad frame (message in the Status of SubmitAndWait / counted for live input)
};

class Localizer {
 public:
  // `sink` (not owned, may be null) must outlive the localizer.
  explicit Localizer(PoseSink* sink);
  ~Localizer();
  Localizer(const Localizer&) = delete;
  Localizer& operator=(const Localizer&) = delete;

  // Builds the rectifier and the odometry for `config` (InvalidArgument naming the field when
  // invalid), then replaces the running configuration: queued frames are discarded, the
  // trajectory and counters restart. Waits for the frame in flight.
  Status Configure(const LocalizerConfig& config);

  // Forgets the trajectory and the tracking state; keeps the configuration. The next frame
  // starts at `T_world_body0` if given, else the configured initial pose.
  void Reset(const std::optional<geometry::SE3>& T_world_body0);

  // Checks a frame against the configuration: InvalidArgument naming `field_prefix`.left/right
  // (empty, size differs from the calibration, not CV_8UC1) or `field_prefix`.t_ns (not after
  // the previous frame's); FailedPrecondition when unconfigured.
  Status CheckInput(const StereoInput& input, const std::string& field_prefix) const;

  // Live input (DDS): never blocks; when the queue is full the oldest queued live frame is
  // dropped (counted). Malformed frames are counted as rejected.
  SubmitOutcome SubmitLive(StereoInput input);
  // Counts a live frame that was malformed before it could become a StereoInput (bad checksum).
  void CountRejected();

  // Unary input: validates like CheckInput, queues the frame (RESOURCE_EXHAUSTED-style
  // kQueueFull when the queue is full) and waits for its result, at most `timeout_ns`
  // (Unavailable "timed out" then; the frame is still processed). `outcome` (optional) says
  // what happened at submission.
  Result<PoseOutput> SubmitAndWait(StereoInput input, int64_t timeout_ns,
                                   SubmitOutcome* outcome = nullptr);

  bool configured() const;
  LocalizerStatus GetStatus();
  // Trajectory points with start_t_ns <= t_ns <= end_t_ns (0 = open end), oldest first.
  std::vector<PoseOutput> Trajectory(int64_t start_t_ns, int64_t end_t_ns);

  // Stops the worker (pending unary requests fail with Unavailable). Idempotent.
  void Shutdown();

 private:
  struct Engine;   // rectifier + odometry; owned by the worker while a frame is in flight
  struct Pending;  // a unary request's result slot
  struct Item {
    StereoInput input;
    std::shared_ptr<Pending> pending;  // null for live frames
    uint64_t generation = 0;
  };

  void WorkerLoop();
  Result<PoseOutput> ProcessFrame(Engine* engine, const StereoInput& input, uint64_t index);
  void ClearQueueLocked(const std::string& why);
  Status CheckInputLocked(const StereoInput& input, const std::string& field_prefix) const;

  PoseSink* sink_;
  mutable std::mutex mutex_;
  std::condition_variable work_cv_;  // wakes the worker
  std::condition_variable idle_cv_;  // wakes Configure/Reset waiting for the frame in flight
  std::thread worker_;
  bool shutdown_ = false;

  // Guarded by mutex_.
  std::unique_ptr<Engine> engine_;
  bool busy_ = false;        // the worker is processing a frame (engine_ is in use, unlocked)
  uint64_t generation_ = 0;  // bumped by Configure/Reset: results of older frames are discarded
  std::deque<Item> queue_;
  int64_t last_accepted_t_ns_ = 0;  // newest t_ns queued or processed since Configure/Reset
  bool have_accepted_ = false;
  std::vector<PoseOutput> trajectory_;
  uint64_t frames_dropped_ = 0;
  uint64_t frames_lost_ = 0;
  uint64_t frames_rejected_ = 0;
  uint64_t keyframes_ = 0;
  std::deque<int64_t> done_wall_ns_;  // completion times of recent frames (fps)
  std::vector<double> processing_ms_;
};

const char* LocalizerStateName(LocalizerState state);
const char* ReportedStateName(ReportedState state);

}  // namespace mav::localization_service
