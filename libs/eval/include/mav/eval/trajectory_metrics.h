#pragma once
// Accuracy metrics for visual odometry, as used by the reference paper (Holzmann et al. 2015,
// Tables 1-2) and the KITTI odometry benchmark (Geiger et al., CVPR 2012).
//
// Relative translational error: for every start frame i (every `step` frames) and every segment
// length L, the segment ends at the first frame j whose ground-truth path length from i reaches
// L. Both trajectories are aligned at the segment's first frame, and the error is
//   e = || trans( (T_gt_i^-1 T_gt_j)^-1 (T_est_i^-1 T_est_j) ) || / L,
// reported in percent. Only translation is used (the paper had no rotation ground truth).
// The per-length figure is the mean over that length's segments; the overall average is the
// mean of the per-length figures over the lengths that had at least one segment (every length
// weighs the same, as in the paper's "average over 2..75 m").

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "mav/common/status.h"
#include "mav/dataset/types.h"
#include "mav/geometry/se3.h"

namespace mav::eval {

// The paper's segment lengths in metres.
const std::vector<double>& PaperSegmentLengths();

struct RelativeErrorOptions {
  std::vector<double> lengths_m = PaperSegmentLengths();
  // Start a segment every `step` frames (KITTI uses 10 at 10 Hz; we use 10 at 20 Hz = 0.5 s).
  int step = 10;
  bool IsValid(std::string* why) const;
};

struct SegmentLengthError {
  double length_m = 0;
  int segments = 0;                  // 0: the trajectory is shorter than this length
  double translation_error_pct = 0;  // mean over segments
};

struct RelativeError {
  std::vector<SegmentLengthError> per_length;
  // Mean over the lengths with segments; nullopt if no length had any segment.
  std::optional<double> average_pct;
};

// `estimate` and `ground_truth` are the same frames in the same order (use AssociateByTime
// first). InvalidArgument if their sizes differ or are < 2.
Result<RelativeError> ComputeRelativeError(const std::vector<geometry::SE3>& estimate,
                                           const std::vector<geometry::SE3>& ground_truth,
                                           const RelativeErrorOptions& options);

// Ground-truth poses interpolated at the estimate's time stamps (slerp + linear). Estimates
// outside the ground truth's time span are dropped. Returns matched pairs in time order.
struct AssociatedTrajectories {
  std::vector<int64_t> t_ns;
  std::vector<geometry::SE3> estimate;
  std::vector<geometry::SE3> ground_truth;
};
Result<AssociatedTrajectories> AssociateByTime(
    const std::vector<dataset::StampedPose>& estimate,
    const std::vector<dataset::StampedPose>& ground_truth);

// Expresses `estimate` in the ground truth's frame by aligning the first poses:
// T'_k = T_gt_0 * T_est_0^-1 * T_est_k. This is how a VO run started at the true pose looks.
std::vector<geometry::SE3> AlignFirstPose(const std::vector<geometry::SE3>& estimate,
                                          const std::vector<geometry::SE3>& ground_truth);

// Absolute trajectory error: RMSE of position differences after the least-squares rigid
// alignment (rotation + translation, no scale) of the estimate's positions onto the ground
// truth's (Horn 1987 / Umeyama 1991). InvalidArgument on size mismatch or < 3 poses.
Result<double> AbsoluteTrajectoryRmse(const std::vector<geometry::SE3>& estimate,
                                      const std::vector<geometry::SE3>& ground_truth);

// Distance between the last positions after AlignFirstPose.
Result<double> EndPointError(const std::vector<geometry::SE3>& estimate,
                             const std::vector<geometry::SE3>& ground_truth);

// Total path length of the positions (metres).
double PathLength(const std::vector<geometry::SE3>& poses);

// Every figure of one estimated trajectory against the ground truth (the paper's Tables 1-2).
struct TrajectoryAccuracy {
  AssociatedTrajectories associated;  // the estimate's frames with the ground truth at them
  RelativeError relative;
  double ate_rmse_m = 0;
  double end_point_error_m = 0;
  double path_length_m = 0;  // of the ground truth at the estimate's frames
};

// AssociateByTime, then ComputeRelativeError, AbsoluteTrajectoryRmse, EndPointError and
// PathLength. The association's error as it is; InvalidArgument "too few frames to evaluate
// (N)" when the associated frames are too few for any of the figures.
Result<TrajectoryAccuracy> EvaluateTrajectory(const std::vector<dataset::StampedPose>& estimate,
                                              const std::vector<dataset::StampedPose>& ground_truth,
                                              const RelativeErrorOptions& options);

}  // namespace mav::eval
