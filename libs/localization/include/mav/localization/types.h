#pragma once
// Types shared by the stereo visual odometry methods of mav::localization.

#include <cstdint>
#include <optional>
#include <string>

#include <Eigen/Geometry>

#include "mav/geometry/se3.h"

namespace mav::localization {

// OK: the frame's motion was estimated. LOST: it was not (the reason says why); the pose is held
// at the last good value and tracking restarts from the next stereo pair. DEGRADED (dense VO):
// the estimate failed the per-frame consistency check (the reason says which test), so the pose
// is the motion prediction (gyro rotation when given, constant velocity), not the measurement;
// tracking goes on against the same keyframe.
enum class TrackingState { kOk, kLost, kDegraded };

const char* TrackingStateName(TrackingState state);  // "OK", "LOST", "DEGRADED"

// What the caller knows about the motion since the previous pair from other sensors (dense VO
// uses it; the sparse methods ignore it).
struct MotionHint {
  // Rotation of the rectified left camera from the previous pair to this one (R_prev_cur),
  // integrated from the gyro with its bias removed.
  Eigen::Quaterniond R_prev_cur = Eigen::Quaterniond::Identity();
};

// Wall-clock time spent in each stage of one frame, milliseconds.
struct FrameTiming {
  double features_ms = 0;    // filter responses, non-maximum suppression, descriptors
  double matching_ms = 0;    // circular matching, bucketing, sub-pixel refinement
  double estimation_ms = 0;  // RANSAC + Gauss-Newton
  double total_ms = 0;
};

// The outcome of one stereo pair.
struct VoFrameResult {
  int64_t t_ns = 0;
  int64_t frame_index = 0;  // 0 for the first pair given to the tracker after construction/Reset
  TrackingState state = TrackingState::kOk;
  std::string lost_reason;  // empty when state == kOk

  // Pose of the rectified left camera in the world frame; the world frame is the rectified left
  // camera of the first frame. Always finite: a lost frame keeps the last pose.
  geometry::SE3 T_world_cam;
  // Motion since the previous pair: T_prev_cur = T_world_prev^-1 * T_world_cur (identity when
  // lost or on the first frame).
  geometry::SE3 T_prev_cur;
  // With a gyro prior (SparseVoOptions::gyro_rotation_sigma_rad): the rotation since the
  // previous pair that the matches alone give (StereoMotionEstimate::vision_R_cur_prev), the
  // gyro's bias is learnt against it. Unset otherwise.
  std::optional<Eigen::Quaterniond> vision_R_prev_cur;

  // True when this pair started a new track: the first pair, or the first good pair after a
  // pair without usable features. The pose is held (T_prev_cur is identity) and state is OK.
  bool reference_reset = false;

  int num_features = 0;  // features of the current left image (all four classes)
  int num_matches = 0;   // circular matches after bucketing (the RANSAC input)
  int num_inliers = 0;
  double mean_reprojection_error_px = 0;  // over inliers and both images, after refinement
  FrameTiming timing;
};

}  // namespace mav::localization
