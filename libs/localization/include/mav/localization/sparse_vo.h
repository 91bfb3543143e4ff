#pragma once
// Sparse stereo visual odometry in the style of libviso2, written from Geiger, Ziegler, Stiller,
// "StereoScan: Dense 3d reconstruction in real-time", IEEE Intelligent Vehicles Symposium 2011.
//
// Per stereo pair (already rectified, see camera::StereoRectifier):
//   1. features: blob/corner 5x5 filter responses, non-maximum suppression, Sobel descriptors
//      (features.h) in both images;
//   2. circular matching previous left -> previous right -> current right -> current left ->
//      previous left, bucketing, then refinement against the previous-left feature: to the best
//      integer position (`pixel`) or sub-pixel (`subpixel`) (matcher.h);
//   3. motion: points triangulated from the previous pair, RANSAC over 3-point sets with
//      Gauss-Newton on the reprojection error in both current images, final refinement on all
//      inliers, then jointly with the inliers' points (stereo_motion.h).
// The pose is chained: T_world_cur = T_world_ref * T_ref_cur, where the reference ("keyframe")
// is the previous pair, or, with options.keep_reference_while_small (default), the last pair
// that became the reference: the reference pair is kept while the motion since it is small
// (translation, rotation below thresholds and enough inliers), so slow motion does not
// accumulate the per-frame quantisation and matching error at every frame. Keeping the last
// keyframe as the matching reference is a common VO practice (e.g. libviso2's
// `process(..., replace = false)`, the keyframe selection of Nister, Naroditsky, Bergen, "Visual
// odometry", CVPR 2004, and of the direct methods, Kerl et al. 2013).
//
// Tracking: when a frame cannot be estimated (too few features, matches or inliers; implausible
// motion) the result is LOST with a reason, the pose is held (never NaN) and the current pair
// becomes the reference for the next one, so tracking resumes on the next good pair.
//
// Runs on one thread. Not thread-safe: one SparseVo per stream.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "mav/camera/stereo.h"
#include "mav/common/status.h"
#include "mav/geometry/se3.h"
#include "mav/localization/features.h"
#include "mav/localization/matcher.h"
#include "mav/localization/stereo_motion.h"
#include "mav/localization/types.h"

namespace cv {
class Mat;
}

namespace mav::localization {

// The two modes of the paper (Holzmann et al. 2015, Table 1), libviso2's "pixel" and "subpixel"
// refinement: matches at integer positions (each moved to the integer position that best aligns
// it with the previous-left feature, RefineMatchesPixel), or refined to sub-pixel accuracy
// (RefineMatchesSubpixel).
enum class SparseVoMode { kPixel, kSubpixel };
const char* SparseVoModeName(SparseVoMode mode);  // "pixel", "subpixel"

struct SparseVoOptions {
  SparseVoMode mode = SparseVoMode::kSubpixel;
  FeatureOptions features;
  MatcherOptions matcher;
  // motion.inlier_threshold_px is replaced by the threshold of the mode: integer positions
  // carry up to +-0.5 px quantisation per coordinate (a 4-vector residual of up to ~1.4 px), so
  // pixel mode needs a wider gate, while sub-pixel mode gains accuracy from a tight one. A gate
  // much above the quantisation (2 px) admits near-miss matches that bias the motion short.
  StereoMotionOptions motion;
  double pixel_inlier_threshold_px = 1.5;
  double subpixel_inlier_threshold_px = 1.0;
  // If > 0, replaces matcher.max_starts_per_bucket in pixel mode. Off by default: 16 starts make
  // pixel matching ~1.3 ms cheaper (BM_SparseVo/pixel 11.6 -> 10.2 ms CPU) but raised the
  // full room-hard error from 1.45 % to 2.10 % (room-easy 0.53 -> 0.59 %, room-medium 0.28 ->
  // 0.39 %), measured with the keyframe reference, see docs/localization.md.
  int pixel_max_starts_per_bucket = 0;
  // A frame with fewer circular matches (after bucketing) than this is LOST.
  int min_matches = 12;
  // A per-frame translation above this (metres) is rejected as LOST (20 m/s at 20 Hz).
  double max_translation_per_frame_m = 1.0;

  // Gyro-aided motion (off by default: the paper's VO is vision-only). With a MotionHint and a
  // sigma > 0, the rotation since the previous pair is a prior of the motion estimate
  // (RotationPrior): the previous pair's pose relative to the reference, turned by the gyro.
  // gyro_rotation_sigma_rad is the noise of the gyro's rotation over one frame interval
  // (bias-corrected: ~5e-5 rad at 20 Hz for the contest IMU), reprojection_sigma_px that of a
  // match; RANSAC drops hypotheses more than gyro_gate_deg from the prior.
  double gyro_rotation_sigma_rad = 0;
  double reprojection_sigma_px = 0.5;
  double gyro_gate_deg = 1.0;

  // Reference ("keyframe") pair: when true, the reference pair stays while the motion since it is
  // below both thresholds and the frame kept at least keyframe_min_inliers inliers (and at least
  // keyframe_min_inlier_ratio of the matches); otherwise the current pair becomes the reference.
  // When false, every pair becomes the reference (frame-to-frame odometry).
  bool keep_reference_while_small = true;
  double keyframe_max_translation_m = 0.10;
  double keyframe_max_rotation_deg = 3.0;
  int keyframe_min_inliers = 60;
  double keyframe_min_inlier_ratio = 0.5;

  bool IsValid(std::string* why) const;
};

class SparseVo {
 public:
  // InvalidArgument naming the field if the rig or the options are invalid.
  static Result<SparseVo> Create(const camera::RectifiedStereo& rig,
                                 const SparseVoOptions& options = {});

  // Processes one rectified pair taken at t_ns. Both images: CV_8UC1, rig.width x rig.height.
  // Bad input is an InvalidArgument naming "left"/"right" and leaves the tracker unchanged;
  // otherwise the result is OK or LOST (see above). `hint` (may be null): the gyro's rotation
  // since the previous pair, used with options().gyro_rotation_sigma_rad > 0.
  Result<VoFrameResult> ProcessFrame(int64_t t_ns, const cv::Mat& left, const cv::Mat& right,
                                     const MotionHint* hint = nullptr);

  // Forgets the reference pair and the pose (next frame starts again at identity).
  void Reset();

  const geometry::SE3& T_world_cam() const;
  const SparseVoOptions& options() const;
  const camera::RectifiedStereo& rig() const;
  int64_t frames_processed() const;
  // The last frame's matches after bucketing (and refinement) and which of them were inliers.
  const std::vector<QuadMatch>& last_matches() const;
  const std::vector<int>& last_inliers() const;

  SparseVo(SparseVo&&) noexcept;
  SparseVo& operator=(SparseVo&&) noexcept;
  ~SparseVo();

 private:
  struct Impl;
  explicit SparseVo(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace mav::localization
