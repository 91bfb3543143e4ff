#pragma once
// Stereo odometry of a calibrated rig, reported for the body (IMU) frame: what the localization
// service publishes and what mav-eval localization scores, on one code path.
//
//   raw or rectified pair --RigRectification--> rectified pair --StereoOdometry-->
//   T_rect0(0)_rect0(k)
//     --BodyPoseFromSensorOdometry--> T_world_body(k) (or T_world_cam0(k)) + covariance heuristic
//
// Frames. The odometry runs on rectified pairs. Raw frames (EuRoC's distorted rig) are rectified
// with camera::StereoRectifier (maps computed once, at Create). A frame flagged `rectified` is
// taken to be in the rectified geometry already and is not remapped. The VO reports the rectified
// left camera at frame k in the frame of the rectified left camera at the first frame; the body
// pose in a world fixed by the initial pose T_world_body0 (identity by default) is
//   T_world_body(k) = T_world_body0 * T_body_rect0 * T_rect0(0)_rect0(k) * T_body_rect0^-1.
// With OutputFrame::kCam0 the pose reported is T_world_cam0(k) = T_world_body(k) * T_body_cam0.
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
// come from the methods' ~1-2 % relative error on the room data sets (docs/services.md).
//
// Tracking state: kInitializing for the first frame and for a frame that re-initialises after a
// loss (the VO's reference_reset), kLost with the VO's reason, kDegraded (dense: the frame failed
// the consistency check, the pose is the prediction; covariance grows by kDegraded*Sigma*), else
// kOk.
//
// Gyro (dense, and sparse with odometry.sparse.gyro_rotation_sigma_rad > 0): samples given with
// AddGyro are integrated between consecutive frame stamps (trapezoidal, minus the estimated
// bias) and passed as the camera's rotation hint. The bias is estimated from the OK frames: an
// average of the gyro-VO rotation disagreement (plain over the first frames, then exponential).
//
// Not thread-safe: one owner (the service's worker, or mav-eval's loop).

#include <array>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <string>

#include "mav/camera/rectifier.h"
#include "mav/camera/stereo.h"
#include "mav/common/status.h"
#include "mav/geometry/se3.h"
#include "mav/localization/odometry.h"

namespace mav::localization {

enum class OutputFrame { kBody, kCam0 };
const char* OutputFrameName(OutputFrame frame);  // "body", "cam0"

// Same numbers as mav.v1.TrackingState / mav::dds::TrackingState.
enum class ReportedState { kUnspecified = 0, kInitializing = 1, kOk = 2, kLost = 3, kDegraded = 4 };
const char* ReportedStateName(ReportedState state);

struct RigOdometryOptions {
  Method method = Method::kSparseSubpixel;
  OdometryOptions odometry;
  // The raw rig; with calibration_rectified the rig is an ideal rectified pair (no distortion,
  // rows aligned) and images are used as they are.
  camera::StereoCalibration calibration;
  bool calibration_rectified = false;
  geometry::SE3 T_world_body0;
  OutputFrame output_frame = OutputFrame::kBody;
  // Dense, and sparse with a gyro_rotation_sigma_rad: integrate the gyro samples given with
  // AddGyro between frames into a rotation hint
  // (the rotation prior and the consistency check of dense_vo.h). Without samples covering a
  // frame interval the frame is processed vision-only.
  bool use_gyro = true;
  // Per-frame gain of the online gyro bias estimate (an exponential average of the gyro-VO
  // rotation disagreement over the OK frames, a plain average over the first 1 / gain of them;
  // 0 = the bias stays 0). It must be slow: whatever rotation bias the VO has, the estimate
  // learns it too.
  double gyro_bias_gain = 0.002;
  // A frame whose gyro and VO rotations disagree by more than this teaches the bias nothing
  // (a frame the matches barely constrain, not an offset: the contest IMU's 0.02 rad/s is
  // 0.06 degrees over a 20 Hz frame).
  double gyro_bias_gate_deg = 1.0;

  // Names the field: "calibration: ...", "sparse: ...", "dense: ...".
  bool IsValid(std::string* why) const;
};

// Per-stage wall time of one frame, ms.
struct RigStageTiming {
  double total_ms = 0;
  double rectify_ms = 0;
  double features_ms = 0;  // sparse: filters + NMS + descriptors; dense: keyframe depth map
  double matching_ms = 0;  // sparse: circular matching + bucketing (+ refinement)
  double motion_ms = 0;    // sparse: RANSAC + Gauss-Newton; dense: pyramid + alignment
  double odometry_ms = 0;  // the VO method's own time (Table 1's runtime)
};

// The result of one frame, in the output frame.
struct RigPose {
  int64_t t_ns = 0;
  uint64_t frame_index = 0;   // 0-based since Create/Reset
  geometry::SE3 T_world_out;  // T_world_<output_frame>
  geometry::SE3 T_prev_cur;   // relative motion of the output frame since the previous frame
  std::array<double, 36> covariance{};  // row-major, [dp (world), dtheta (child)]
  ReportedState state = ReportedState::kUnspecified;
  std::string lost_reason;
  uint32_t matches = 0;    // sparse: circular matches; dense: keyframe pixels
  uint32_t inliers = 0;    // sparse: RANSAC inliers; dense: pixels used
  double residual = 0;     // sparse: mean reprojection error px; dense: RMS photometric error
  bool keyframe = false;   // dense: this frame became a keyframe
  bool gyro_used = false;  // a gyro rotation since the previous frame was passed to the method
  double prediction_error_m = 0;  // dense: the consistency check's figures (dense_vo.h)
  double gyro_rotation_error_deg = 0;
  RigStageTiming timing;
};

// One gyro reading: stamp and angular rate in the body frame [rad/s].
struct GyroSample {
  int64_t t_ns = 0;
  Eigen::Vector3d omega = Eigen::Vector3d::Zero();
};

class RigOdometry {
 public:
  // Covariance heuristic constants (see the file comment).
  static constexpr double kDriftFraction = 0.02;
  static constexpr double kPositionFloorM = 0.001;
  static constexpr double kRotationFloorRad = 0.0005;
  static constexpr double kLostPositionSigmaM = 0.25;
  static constexpr double kLostRotationSigmaRad = 0.05;
  static constexpr double kDegradedPositionSigmaM = 0.02;
  static constexpr double kDegradedRotationSigmaRad = 0.005;
  // Gyro samples kept (10 s at 200 Hz) and the largest gap between samples an integration
  // bridges.
  static constexpr size_t kGyroHistory = 2000;
  static constexpr int64_t kMaxGyroGapNs = 20'000'000;
  static constexpr int64_t kNewGyroStreamNs = 1'000'000'000;

  // Builds the rectifier and the odometry: InvalidArgument naming the field when invalid.
  static Result<std::unique_ptr<RigOdometry>> Create(const RigOdometryOptions& options);

  const RigOdometryOptions& options() const { return options_; }
  // The rectified rig the odometry runs on.
  const camera::RectifiedStereo& rig() const { return rectification_.rig; }
  const geometry::SE3& T_body_rect0() const { return rectification_.T_body_rect0; }

  // Rectifies a raw pair of the calibration's size (CV_8UC1) into the rig's geometry; a pair
  // flagged `rectified` is used as it is. For callers that feed several odometries one pair.
  Status Rectify(const cv::Mat& left, const cv::Mat& right, bool rectified, cv::Mat* rect_left,
                 cv::Mat* rect_right) const;

  // Processes one pair (raw, or rectified when `rectified`). InvalidArgument naming
  // "left"/"right" for images of the wrong size or type (the trajectory is unchanged then).
  Result<RigPose> Process(int64_t t_ns, const cv::Mat& left, const cv::Mat& right, bool rectified);

  // One gyro sample (body frame, rad/s), in time order (older or repeated stamps and non-finite
  // rates are ignored); the last kGyroHistory are kept. Give the samples up to a frame's stamp
  // before processing the frame.
  void AddGyro(int64_t t_ns, const Eigen::Vector3d& omega_body);
  // The gyro bias the odometry estimated (rad/s, body frame), removed before integrating.
  const Eigen::Vector3d& gyro_bias() const { return gyro_bias_; }

  // Forgets the trajectory and the tracking state; the next frame starts at `T_world_body0` if
  // given, else the configured initial pose. The gyro samples and the learnt gyro bias are
  // kept: the IMU is the same (a re-seed in flight has its gyro prior from the second frame on,
  // and an in-process re-seed integrates the very samples a service's Reset does). A gyro
  // clock that goes back by more than kNewGyroStreamNs starts the samples anew (a replay
  // started again); create a new odometry for another IMU.
  void Reset(const std::optional<geometry::SE3>& T_world_body0 = std::nullopt);

 private:
  RigOdometry(RigOdometryOptions options, camera::RigRectification rectification,
              std::unique_ptr<StereoOdometry> odometry);

  // R_body(t0)_body(t1) from the gyro samples, bias removed; nullopt if they do not cover it.
  std::optional<Eigen::Quaterniond> IntegrateGyro(int64_t t0_ns, int64_t t1_ns) const;
  void UpdateGyroBias(const Eigen::Quaterniond& R_body_gyro,
                      const Eigen::Quaterniond& R_prev_cur_cam, double dt_s);

  RigOdometryOptions options_;
  camera::RigRectification rectification_;
  std::unique_ptr<StereoOdometry> odometry_;

  // Trajectory state, restarted by Reset.
  geometry::SE3 T_world_body0_;
  uint64_t next_index_ = 0;
  std::optional<geometry::SE3> T_world_out_previous_;
  Eigen::Matrix<double, 6, 1> variance_ = Eigen::Matrix<double, 6, 1>::Zero();
  std::optional<int64_t> t_previous_ns_;
  std::optional<geometry::SE3> T_world_cam_previous_;  // the method's camera pose, last frame
  bool previous_ok_ = false;                           // the last frame was OK (measured)
  std::deque<GyroSample> gyro_;
  Eigen::Vector3d gyro_bias_ = Eigen::Vector3d::Zero();
  uint64_t gyro_bias_updates_ = 0;
};

}  // namespace mav::localization
