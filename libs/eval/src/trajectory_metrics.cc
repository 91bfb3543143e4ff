#include "mav/eval/trajectory_metrics.h"

#include <algorithm>
#include <cmath>
#include <cstddef>

#include <Eigen/SVD>

namespace mav::eval {

const std::vector<double>& PaperSegmentLengths() {
  static const std::vector<double> kLengths = {2, 5, 10, 15, 20, 25, 60, 75};
  return kLengths;
}

bool RelativeErrorOptions::IsValid(std::string* why) const {
  if (step < 1) {
    if (why) *why = "step: must be >= 1, got " + std::to_string(step);
    return false;
  }
  if (lengths_m.empty()) {
    if (why) *why = "lengths_m: need at least one segment length";
    return false;
  }
  for (double l : lengths_m) {
    if (!(l > 0) || !std::isfinite(l)) {
      if (why) *why = "lengths_m: lengths must be positive, got " + std::to_string(l);
      return false;
    }
  }
  return true;
}

namespace {

Status CheckSameSize(size_t a, size_t b, size_t min_size) {
  if (a != b) {
    return Status::InvalidArgument("estimate: " + std::to_string(a) +
                                   " poses but ground truth has " + std::to_string(b));
  }
  if (a < min_size) {
    return Status::InvalidArgument("estimate: need at least " + std::to_string(min_size) +
                                   " poses, got " + std::to_string(a));
  }
  return Status::Ok();
}

}  // namespace

double PathLength(const std::vector<geometry::SE3>& poses) {
  double length = 0;
  for (size_t i = 1; i < poses.size(); ++i) {
    length += (poses[i].Translation() - poses[i - 1].Translation()).norm();
  }
  return length;
}

Result<RelativeError> ComputeRelativeError(const std::vector<geometry::SE3>& estimate,
                                           const std::vector<geometry::SE3>& ground_truth,
                                           const RelativeErrorOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument(why);
  MAV_RETURN_IF_ERROR(CheckSameSize(estimate.size(), ground_truth.size(), 2));

  // Cumulative ground-truth distance: segment ends are found by binary search.
  std::vector<double> distance(ground_truth.size(), 0.0);
  for (size_t i = 1; i < ground_truth.size(); ++i) {
    distance[i] = distance[i - 1] +
                  (ground_truth[i].Translation() - ground_truth[i - 1].Translation()).norm();
  }

  RelativeError out;
  double sum_of_means = 0;
  int lengths_with_segments = 0;
  for (double length : options.lengths_m) {
    SegmentLengthError entry;
    entry.length_m = length;
    double sum = 0;
    for (size_t i = 0; i < ground_truth.size(); i += options.step) {
      const auto end = std::lower_bound(distance.begin() + static_cast<std::ptrdiff_t>(i),
                                        distance.end(), distance[i] + length);
      if (end == distance.end()) break;  // later starts cannot reach this length either
      const size_t j = static_cast<size_t>(end - distance.begin());
      const geometry::SE3 gt_motion = ground_truth[i].Inverse() * ground_truth[j];
      const geometry::SE3 est_motion = estimate[i].Inverse() * estimate[j];
      const geometry::SE3 error = gt_motion.Inverse() * est_motion;
      sum += error.Translation().norm() / length;
      ++entry.segments;
    }
    if (entry.segments > 0) {
      entry.translation_error_pct = 100.0 * sum / entry.segments;
      sum_of_means += entry.translation_error_pct;
      ++lengths_with_segments;
    }
    out.per_length.push_back(entry);
  }
  if (lengths_with_segments > 0) out.average_pct = sum_of_means / lengths_with_segments;
  return out;
}

Result<AssociatedTrajectories> AssociateByTime(
    const std::vector<dataset::StampedPose>& estimate,
    const std::vector<dataset::StampedPose>& ground_truth) {
  if (ground_truth.size() < 2) {
    return Status::InvalidArgument("ground_truth: need at least 2 poses to interpolate");
  }
  for (size_t i = 1; i < ground_truth.size(); ++i) {
    if (ground_truth[i].t_ns <= ground_truth[i - 1].t_ns) {
      return Status::InvalidArgument("ground_truth: time stamps not strictly increasing at row " +
                                     std::to_string(i));
    }
  }
  AssociatedTrajectories out;
  for (const dataset::StampedPose& e : estimate) {
    const auto it =
        std::lower_bound(ground_truth.begin(), ground_truth.end(), e.t_ns,
                         [](const dataset::StampedPose& p, int64_t t) { return p.t_ns < t; });
    if (it == ground_truth.end()) continue;
    geometry::SE3 gt;
    if (it->t_ns == e.t_ns) {
      gt = it->T_world_body;
    } else {
      if (it == ground_truth.begin()) continue;
      const auto prev = it - 1;
      const double alpha =
          static_cast<double>(e.t_ns - prev->t_ns) / static_cast<double>(it->t_ns - prev->t_ns);
      gt = geometry::InterpolatePose(prev->T_world_body, it->T_world_body, alpha);
    }
    out.t_ns.push_back(e.t_ns);
    out.estimate.push_back(e.T_world_body);
    out.ground_truth.push_back(gt);
  }
  if (out.t_ns.empty()) {
    return Status::InvalidArgument("estimate: no pose lies inside the ground truth's time span");
  }
  return out;
}

std::vector<geometry::SE3> AlignFirstPose(const std::vector<geometry::SE3>& estimate,
                                          const std::vector<geometry::SE3>& ground_truth) {
  if (estimate.empty() || ground_truth.empty()) return estimate;
  const geometry::SE3 correction = ground_truth.front() * estimate.front().Inverse();
  std::vector<geometry::SE3> out;
  out.reserve(estimate.size());
  for (const geometry::SE3& t : estimate) out.push_back(correction * t);
  return out;
}

Result<double> AbsoluteTrajectoryRmse(const std::vector<geometry::SE3>& estimate,
                                      const std::vector<geometry::SE3>& ground_truth) {
  MAV_RETURN_IF_ERROR(CheckSameSize(estimate.size(), ground_truth.size(), 3));
  const size_t n = estimate.size();
  Eigen::Vector3d mean_e = Eigen::Vector3d::Zero(), mean_g = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    mean_e += estimate[i].Translation();
    mean_g += ground_truth[i].Translation();
  }
  mean_e /= static_cast<double>(n);
  mean_g /= static_cast<double>(n);
  // Cross-covariance; the optimal rotation maps estimate onto ground truth (Umeyama 1991).
  Eigen::Matrix3d sigma = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    sigma +=
        (ground_truth[i].Translation() - mean_g) * (estimate[i].Translation() - mean_e).transpose();
  }
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(sigma, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d s = Eigen::Matrix3d::Identity();
  if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0) s(2, 2) = -1;
  const Eigen::Matrix3d r = svd.matrixU() * s * svd.matrixV().transpose();
  const Eigen::Vector3d t = mean_g - r * mean_e;
  double sum_sq = 0;
  for (size_t i = 0; i < n; ++i) {
    sum_sq += (r * estimate[i].Translation() + t - ground_truth[i].Translation()).squaredNorm();
  }
  return std::sqrt(sum_sq / static_cast<double>(n));
}

Result<double> EndPointError(const std::vector<geometry::SE3>& estimate,
                             const std::vector<geometry::SE3>& ground_truth) {
  MAV_RETURN_IF_ERROR(CheckSameSize(estimate.size(), ground_truth.size(), 1));
  const std::vector<geometry::SE3> aligned = AlignFirstPose(estimate, ground_truth);
  return (aligned.back().Translation() - ground_truth.back().Translation()).norm();
}

Result<TrajectoryAccuracy> EvaluateTrajectory(const std::vector<dataset::StampedPose>& estimate,
                                              const std::vector<dataset::StampedPose>& ground_truth,
                                              const RelativeErrorOptions& options) {
  TrajectoryAccuracy out;
  MAV_ASSIGN_OR_RETURN(out.associated, AssociateByTime(estimate, ground_truth));
  const std::vector<geometry::SE3>& est = out.associated.estimate;
  const std::vector<geometry::SE3>& gt = out.associated.ground_truth;
  Result<RelativeError> relative = ComputeRelativeError(est, gt, options);
  Result<double> ate = AbsoluteTrajectoryRmse(est, gt);
  Result<double> end = EndPointError(est, gt);
  if (!relative.ok() || !ate.ok() || !end.ok()) {
    return Status::InvalidArgument("too few frames to evaluate (" + std::to_string(est.size()) +
                                   ")");
  }
  out.relative = *std::move(relative);
  out.ate_rmse_m = *ate;
  out.end_point_error_m = *end;
  out.path_length_m = PathLength(gt);
  return out;
}

}  // namespace mav::eval
