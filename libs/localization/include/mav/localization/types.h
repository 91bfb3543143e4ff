#pragma once
// Types shared by the stereo visual odometry methods of mav::localization.

#include <cstdint>
#include <string>

#include "mav/geometry/se3.h"

namespace mav::localization {

// OK: the frame's motion was estimated. LOST: it was not (the reason says why); the pose is held
// at the last good value and tracking restarts from the next stereo pair.
enum class TrackingState { kOk, kLost };

const char* TrackingStateName(TrackingState state);  // "OK", "LOST"

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
