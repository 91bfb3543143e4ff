#pragma once
// One interface over the stereo odometry methods of the paper (Holzmann et al. 2015, Table 1):
// sparse feature-based VO in pixel and sub-pixel mode (sparse_vo.h) and dense direct VO
// (dense_vo.h). The evaluation tool and the localization service hold a StereoOdometry (through
// RigOdometry, rig_odometry.h) and need not know which method runs.

#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mav/camera/stereo.h"
#include "mav/common/status.h"
#include "mav/localization/dense_vo.h"
#include "mav/localization/sparse_vo.h"
#include "mav/localization/types.h"

namespace cv {
class Mat;
}

namespace mav::localization {

enum class Method { kSparsePixel, kSparseSubpixel, kDense };

// "sparse-pixel", "sparse-subpixel", "dense": the names used on command lines and in JSON.
const char* MethodName(Method method);
std::optional<Method> ParseMethod(std::string_view name);
const std::vector<Method>& AllMethods();

// The options of every method; Create() uses the one of the method it builds (the sparse mode
// comes from the method, whatever sparse.mode says).
struct OdometryOptions {
  SparseVoOptions sparse;
  DenseVoOptions dense;

  // The chosen method's options; the message starts with the method ("dense: num_levels ...").
  bool IsValid(Method method, std::string* why) const;
};

// The method-independent part of a frame's result.
struct OdometryFrame {
  int64_t t_ns = 0;
  TrackingState state = TrackingState::kOk;
  std::string lost_reason;
  // Pose of the rectified left camera; the world frame is the first frame's camera.
  geometry::SE3 T_world_cam;
  // This pair started a new track (first pair, or first usable pair after a loss).
  bool reference_reset = false;
  // Sparse with a gyro prior: the rotation since the previous pair by vision alone
  // (VoFrameResult::vision_R_prev_cur); the gyro's bias is learnt against it.
  std::optional<Eigen::Quaterniond> vision_R_prev_cur;
  // Dense: this pair became the keyframe. Sparse: always false (frame to frame).
  bool keyframe = false;
  // Sparse: circular matches. Dense: keyframe pixels.
  int matches = 0;
  // Sparse: RANSAC inliers. Dense: pixels used in the alignment.
  int support = 0;
  // Sparse: mean reprojection error (px). Dense: robust RMS photometric error (grey levels).
  double residual = 0;
  // Dense: the consistency check's figures (DenseFrameResult::prediction_error_m,
  // gyro_rotation_error_deg); 0 for the sparse methods.
  double prediction_error_m = 0;
  double gyro_rotation_error_deg = 0;
  // The method's own timing of the frame, ms: features (sparse: filters, NMS, descriptors;
  // dense: the keyframe depth map), matching (sparse only), motion (sparse: RANSAC + Gauss-Newton;
  // dense: pyramid + alignment) and the whole frame.
  double features_ms = 0;
  double matching_ms = 0;
  double motion_ms = 0;
  double runtime_ms = 0;
};

class StereoOdometry {
 public:
  // InvalidArgument naming the field for an invalid rig or invalid options.
  static Result<std::unique_ptr<StereoOdometry>> Create(Method method,
                                                        const camera::RectifiedStereo& rig,
                                                        const OdometryOptions& options = {});
  virtual ~StereoOdometry() = default;

  // Rectified CV_8UC1 pair of the rig's size; bad input is InvalidArgument naming "left"/"right".
  // `hint` (may be null): the gyro rotation since the previous pair (dense; sparse with
  // SparseVoOptions::gyro_rotation_sigma_rad > 0).
  virtual Result<OdometryFrame> Process(int64_t t_ns, const cv::Mat& left, const cv::Mat& right,
                                        const MotionHint* hint = nullptr) = 0;
  virtual void Reset() = 0;
  virtual Method method() const = 0;
};

}  // namespace mav::localization
