#pragma once
// Dense direct stereo visual odometry in the style of Kerl, Sturm, Cremers, "Robust Odometry
// Estimation for RGB-D Cameras" (ICRA 2013), with the depth camera replaced by stereo block
// matching. It is the "direct" method of Holzmann et al., "Performance Evaluation of
// Vision-Based Algorithms for MAVs" (OAGM 2015), Section 2.1.
//
// Keyframes. A keyframe is a rectified pair whose left image carries a dense depth map from
// OpenCV block matching (cv::StereoBM at pyramid level `depth_level`, half resolution by
// default), with the pixels near disparity jumps removed (block matching fattens foreground
// objects). On every pyramid level the tracker keeps the keyframe pixels with a valid depth and
// an intensity gradient of at least `min_gradient` (at most `max_pixels_per_level`, spread over
// the image by a grid), refines their disparity to sub-pixel precision against the right image
// of that level, and precomputes their 3D points and photometric Jacobians.
//
// Tracking. Each new left image is aligned to the keyframe by minimising the robust photometric
// error over the 6-DoF motion T_cur_kf (and, optionally, an affine brightness change a, b):
//   E(T, a, b) = sum_i rho( I_cur(pi(T * p_i)) - (exp(a) * I_kf(x_i) + b) )
// where p_i = depth_i * K^-1 [x_i; 1] is the keyframe point of pixel x_i and pi the pinhole
// projection. The motion is updated inverse-compositionally (Baker and Matthews, IJCV 2004): the
// Jacobians of the warp are taken on the keyframe, so they are computed once per keyframe, and
// an increment xi is applied as T <- T * Exp(xi)^-1. Each step solves the damped normal
// equations (H + lambda diag(H)) delta = -g (Levenberg-Marquardt) with iteratively re-weighted
// least squares: Student-t weights w = (nu + 1) / (nu + (r / sigma)^2) with the scale sigma
// re-estimated from the residuals, as in Kerl et al. (or Huber weights). The image pyramid is
// traversed coarse to fine, and the motion is initialised with the previous frame's velocity
// (constant-velocity motion prior).
//
// A new keyframe is taken from the current pair when the rotation or the translation since the
// keyframe, the photometric error, or the fraction of keyframe pixels still visible passes its
// threshold in DenseVoOptions.
//
// Tracking state: a frame is LOST with a reason when its left image has no contrast (black or
// saturated), when no keyframe can be built (too few pixels with depth and gradient), or when
// its alignment fails (too few pixels inside the image, too large an error, an implausible
// brightness change or motion). Its pose is held at the last good value (never NaN), and the
// tracker re-initialises: the lost pair itself becomes the keyframe when it can, otherwise the
// next usable pair does (reference_reset).
//
// Per-frame consistency check (after a tracked frame passes the LOST tests): the estimated motion
// since the previous frame is compared with what the frame before predicts, and a frame that
// fails is DEGRADED instead of publishing a jump:
//   * gyro: when the caller passes the rotation integrated from the gyro (MotionHint), the
//     estimated rotation must agree within max_gyro_rotation_error_deg;
//   * velocity: the translation must stay within max_acceleration_mps2 * dt^2 +
//     motion_check_floor_m of the constant-velocity prediction (the previous frame's motion, with
//     the gyro rotation when given);
//   * support: at least min_support_fraction of the keyframe's pixels must be used;
//   * photometric residual: at most max_rms_growth times the running mean of the OK frames'.
// A DEGRADED frame reports the prediction as its pose (the velocity is kept, the keyframe too),
// and max_degraded_frames in a row make the next one LOST (re-initialisation).
// With a gyro rotation the alignment also carries a rotation prior (rotation_prior_weight):
// the photometric error alone confuses a small sideways translation with a small yaw on scenes
// whose depth varies little, and the gyro resolves it (as in direct visual-inertial odometry,
// e.g. Usenko, Engel, Stueckler, Cremers, "Direct visual-inertial odometry with stereo cameras",
// ICRA 2016, where the IMU enters the photometric optimisation).
//
// Runs on the calling thread (cv::StereoBM may use OpenCV's own thread pool unless the
// application calls cv::setNumThreads). Not thread-safe: one DenseVo per stream.
//
// DenseFrameResult reuses TrackingState from types.h; its other fields differ from the sparse
// method's VoFrameResult (pixels instead of features/matches, a dense-specific timing).

#include <cstdint>
#include <memory>
#include <string>

#include <Eigen/Core>

#include "mav/camera/stereo.h"
#include "mav/common/status.h"
#include "mav/geometry/se3.h"
#include "mav/localization/types.h"

namespace cv {
class Mat;
}

namespace mav::localization {

enum class DenseRobustLoss { kStudentT, kHuber, kNone };

// The keyframe depth source. Block matching (cv::StereoBM) is the default: at half resolution
// it costs a few milliseconds per keyframe, and with the discontinuity filter below its depth
// was the more accurate on the simulated rooms (0.4 % vs 0.8 % relative error on 300 room-easy
// frames). Semi-global matching (cv::StereoSGBM, 3-way mode, with its left-right check) costs
// ~4x more and smooths depth; it is kept as an option for scenes where BM fails.
enum class DenseStereoMatcher { kBlockMatching, kSemiGlobal };

struct DenseVoOptions {
  // --- Image pyramid and pixel selection ---
  // Pyramid levels (level 0 = full resolution, each level halves the size with cv::pyrDown).
  int num_levels = 4;
  // The finest level the alignment runs on: 0 = full resolution; 1 skips the finest level for
  // speed.
  int finest_level = 0;
  // Minimum intensity-gradient magnitude (8-bit grey levels per pixel, central differences) of a
  // keyframe pixel used for tracking, on every level.
  double min_gradient = 6.0;
  // At most this many pixels per level; when more pass the gradient test, the image is cut into
  // square cells and the strongest pixel of each cell is kept.
  int max_pixels_per_level = 6000;

  // --- Keyframe depth from stereo matching ---
  DenseStereoMatcher matcher = DenseStereoMatcher::kBlockMatching;
  // Pyramid level the block matching runs on (1 = half resolution: ~4x faster, and the
  // disparity range halves too).
  int depth_level = 1;
  // Disparity search range in pixels at depth_level; a multiple of 16 (StereoBM).
  int num_disparities = 48;
  int block_size = 11;            // StereoBM window, odd, 5..51 (SGBM: sgbm_block_size)
  int sgbm_block_size = 5;        // StereoSGBM window, odd, 3..11
  int texture_threshold = 10;     // StereoBM: minimum texture in the block
  int uniqueness_ratio = 10;      // percent margin of the best match
  int speckle_window_size = 100;  // speckle filter (0 = off), pixels at depth_level
  int speckle_range = 2;          // disparity levels (at depth_level, in pixels)
  // Pixels within a matching window of a disparity jump (max - min over the window above
  // max(1 px, 10 %)) are dropped: block matching "fattens" foreground objects there.
  bool filter_discontinuities = true;
  // Refine each selected pixel's disparity to sub-pixel precision on its own pyramid level by a
  // 1-D Lucas-Kanade step on a 5x5 patch against the right image (block matching at half
  // resolution alone is biased by its sub-pixel interpolation); pixels whose refinement moves
  // more than 1 pixel or ends with a patch RMS error above max_refined_disparity_rms (grey
  // levels) are dropped.
  bool refine_disparity = true;
  double max_refined_disparity_rms = 8.0;
  double min_depth_m = 0.2;
  double max_depth_m = 20.0;

  // --- Alignment (Levenberg-Marquardt, IRLS) ---
  int max_iterations_per_level = 25;
  // Stop a level when the increment's norm (translation m + rotation rad) drops below this.
  double min_step = 1e-5;
  double initial_lambda = 1e-4;
  DenseRobustLoss loss = DenseRobustLoss::kStudentT;
  double student_t_nu = 5.0;  // degrees of freedom (Kerl et al. use 5)
  double huber_k = 1.345;     // Huber threshold in units of the residual scale
  // Estimate an affine brightness change between keyframe and frame (exposure changes).
  bool estimate_affine_brightness = true;
  // Initialise with the previous frame's motion (constant velocity); identity otherwise.
  bool use_motion_prior = true;

  // --- Keyframe selection ---
  double keyframe_max_rotation_deg = 8.0;
  double keyframe_max_translation_m = 0.25;
  // RMS photometric error (grey levels, robustly weighted, at finest_level) above which the
  // frame becomes a keyframe.
  double keyframe_max_rms_error = 14.0;
  // New keyframe when fewer than this fraction of the keyframe's pixels (finest tracked level)
  // project into the current image.
  double keyframe_min_visible_fraction = 0.6;

  // --- Lost tracking ---
  // A keyframe needs this many selected pixels on the finest tracked level; a frame needs this
  // many of them inside the image.
  int min_pixels = 200;
  // RMS photometric error (grey levels) above which the alignment is considered failed.
  double max_rms_error = 40.0;
  // The estimated brightness gain between keyframe and frame must stay within
  // [1 / max_brightness_gain_change, max_brightness_gain_change].
  double max_brightness_gain_change = 2.0;
  // A left image whose intensity standard deviation (grey levels, coarsest level) is below this
  // has no usable texture (black or saturated frame): LOST.
  double min_image_contrast = 2.0;
  double max_translation_per_frame_m = 1.0;  // 20 m/s at 20 Hz
  double max_rotation_per_frame_deg = 30.0;

  // --- Per-frame consistency check (DEGRADED; see the file comment) ---
  bool consistency_check = true;
  // Estimated rotation since the previous frame vs the gyro's (when given), degrees.
  double max_gyro_rotation_error_deg = 0.5;
  // Translation since the last OK frame vs the constant-velocity prediction: the bound is
  // 0.5 max_acceleration_mps2 dt^2 + motion_check_floor_m (dt from the stamps). The room presets'
  // trajectories deviate from constant velocity by up to 0.75 / 2.8 / 6.9 mm per 50 ms frame
  // (easy / medium / hard).
  double max_acceleration_mps2 = 6.0;
  double motion_check_floor_m = 0.004;
  // Pixels used / keyframe pixels.
  double min_support_fraction = 0.2;
  // RMS photometric error vs the running mean over OK frames (and at least 8 grey levels).
  double max_rms_growth = 2.5;
  // This many DEGRADED frames in a row make the next inconsistent frame LOST.
  int max_degraded_frames = 5;
  // Weight of the gyro rotation prior in the alignment, relative to the photometric information
  // on the rotation (1 = as much as all pixels together; 0 = no prior, the gyro only predicts and
  // checks).
  double rotation_prior_weight = 1.0;

  bool IsValid(std::string* why) const;
};

// Milliseconds spent in each stage of one frame.
struct DenseTiming {
  double pyramid_ms = 0;   // grey -> float conversion and pyramid of the current left image
  double keyframe_ms = 0;  // block matching, depth pyramid, pixel selection (0 if no keyframe)
  double tracking_ms = 0;  // coarse-to-fine alignment
  double total_ms = 0;
};

// The outcome of one stereo pair.
struct DenseFrameResult {
  int64_t t_ns = 0;
  int64_t frame_index = 0;  // 0 for the first pair after construction/Reset
  TrackingState state = TrackingState::kOk;
  std::string lost_reason;  // why LOST or DEGRADED; empty when state == kOk

  // Pose of the rectified left camera in the world frame (the initial pose given to Create, by
  // default the first frame's camera). Always finite: a lost frame keeps the last pose.
  geometry::SE3 T_world_cam;
  // Motion since the previous pair (identity when lost or at a reset).
  geometry::SE3 T_prev_cur;

  // This pair started a new track (first pair, or first usable pair after a LOST frame); its
  // pose is held.
  bool reference_reset = false;
  // This pair became the keyframe (after being tracked, or at a reset).
  bool new_keyframe = false;

  int num_keyframe_pixels = 0;  // selected keyframe pixels on finest_level
  int num_pixels_used = 0;      // of those, inside the current image at the solution
  int iterations = 0;           // LM iterations over all levels
  double rms_error = 0;         // robustly weighted RMS photometric error, grey levels
  double brightness_gain = 1;   // estimated exp(a)
  double brightness_bias = 0;   // estimated b, grey levels
  // Consistency check figures of the estimate (0 when not computed): distance of the estimated
  // translation from the constant-velocity prediction [m], and angle between the estimated and
  // the gyro's rotation [deg].
  double prediction_error_m = 0;
  double gyro_rotation_error_deg = 0;
  DenseTiming timing;
};

class DenseVo {
 public:
  // InvalidArgument naming the field if the rig or the options are invalid (e.g. the rig's size
  // too small for num_levels).
  static Result<DenseVo> Create(const camera::RectifiedStereo& rig,
                                const DenseVoOptions& options = {},
                                const geometry::SE3& T_world_cam0 = geometry::SE3::Identity());

  // Processes one rectified pair taken at t_ns. Both images CV_8UC1, rig.width x rig.height.
  // Bad input is an InvalidArgument naming "left"/"right" and leaves the tracker unchanged;
  // otherwise the result is OK, DEGRADED or LOST (see above). `hint` (may be null) carries the
  // gyro rotation since the previous pair.
  Result<DenseFrameResult> ProcessFrame(int64_t t_ns, const cv::Mat& left, const cv::Mat& right,
                                        const MotionHint* hint = nullptr);

  // Forgets the keyframe and the motion; the next pair starts again at the initial pose.
  void Reset();

  const geometry::SE3& T_world_cam() const;
  const DenseVoOptions& options() const;
  const camera::RectifiedStereo& rig() const;
  int64_t frames_processed() const;
  int64_t keyframes_created() const;

  DenseVo(DenseVo&&) noexcept;
  DenseVo& operator=(DenseVo&&) noexcept;
  ~DenseVo();

 private:
  struct Impl;
  explicit DenseVo(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// --- Building blocks, exposed for tests ---

// d pi(Exp(xi) * p) / d xi at xi = 0 for a pinhole camera with focal lengths fx, fy; xi ordered
// (translation, rotation) as geometry::SE3::Exp. p in the camera frame, p.z() > 0.
Eigen::Matrix<double, 2, 6> ProjectionTwistJacobian(const Eigen::Vector3d& p, double fx, double fy);

// Bilinear interpolation of a CV_32FC1 image at (u, v); the caller keeps (u, v) inside
// [0, cols - 1) x [0, rows - 1).
float SampleBilinear(const cv::Mat& image, float u, float v);

// The photometric Jacobian d I(pi(Exp(xi) * p)) / d xi at xi = 0, where p projects to the
// integer pixel (u, v) of the CV_32FC1 image and the image gradient is taken by central
// differences there: gradient(u, v) * ProjectionTwistJacobian(p).
Eigen::Matrix<double, 1, 6> PhotometricJacobian(const cv::Mat& image, int u, int v,
                                                const Eigen::Vector3d& p, double fx, double fy);

}  // namespace mav::localization
