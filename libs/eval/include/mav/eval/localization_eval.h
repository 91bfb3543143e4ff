#pragma once
// The localization evaluation of mav-eval (the paper's Tables 1 and 2, Holzmann et al. 2015):
// every stereo odometry method over the same frames of an EuRoC directory with ground truth,
// through localization::RigOdometry (the localization service's code path), scored with
// mav/eval/trajectory_metrics.h.

#include <cstdint>
#include <string>
#include <vector>

#include "mav/common/stats.h"
#include "mav/common/status.h"
#include "mav/dataset/types.h"
#include "mav/eval/report.h"
#include "mav/eval/trajectory_metrics.h"
#include "mav/localization/odometry.h"
#include "mav/localization/rig_odometry.h"

namespace mav::eval {

struct LocalizationEvalOptions {
  std::string data;  // EuRoC directory with ground truth
  std::vector<localization::Method> methods = localization::AllMethods();
  int64_t max_frames = 0;  // the first N frames; 0 = all
  int step = 10;           // frames between segment starts of the relative error, >= 1
  // Dense method: imu0's gyro (rotation prior and consistency check), the gain of its online
  // bias estimate, and the per-frame consistency check.
  bool use_gyro = true;
  double gyro_bias_gain = localization::RigOdometryOptions().gyro_bias_gain;
  bool consistency_check = true;
};

// One method over the frames.
struct LocalizationMethodResult {
  localization::Method method = localization::Method::kSparsePixel;
  bool gyro = false;                               // the gyro was used (dense with use_gyro)
  std::vector<dataset::StampedPose> T_world_body;  // estimate in the ground truth's world frame
  // One line a frame: frame,t_ns,state,matches,support,residual,keyframe,gyro,step_m,
  // prediction_error_m,gyro_error_deg,reason (LocalizationFramesCsvHeader()).
  std::string frames_csv;
  int lost_frames = 0;
  int degraded_frames = 0;
  std::string first_lost_reason;
  std::string first_degraded_reason;
  TrajectoryAccuracy accuracy;
  RuntimeStats runtime;  // wall time of RigOdometry::Process, per frame
};

struct LocalizationSummary {
  std::string data;
  std::string preset;  // ReadPresetName; empty: not a mav-sim preset
  int64_t frames = 0;  // frames evaluated
  std::vector<LocalizationMethodResult> methods;
  // The ground truth at the frames of the first method (for ground_truth.tum and the plot).
  std::vector<dataset::StampedPose> ground_truth_at_frames;
};

// Runs every method over the first max_frames frames (read and rectified once for all) with the
// gyro samples up to each frame, then scores each against the ground truth. Errors name the file
// or the frame ("frame 17: ..."); a data set without ground truth is FailedPrecondition.
Result<LocalizationSummary> EvaluateLocalization(const LocalizationEvalOptions& options,
                                                 const StepProgress& progress = {});

// The header line of LocalizationMethodResult::frames_csv.
const char* LocalizationFramesCsvHeader();

// Tables 1 and 2 with the paper's figures beside ours, the lost and degraded frames, and the
// JSON {method: {metric: value}}.
Report LocalizationReport(const LocalizationSummary& summary);

}  // namespace mav::eval
