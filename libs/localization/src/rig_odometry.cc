#include "mav/localization/rig_odometry.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include <opencv2/core/mat.hpp>

#include "mav/common/time.h"

namespace mav::localization {

namespace {

// Nominal support and residual of each method (the covariance heuristic's scale).
constexpr double kSparseNominalSupport = 100.0;
constexpr double kSparseNominalResidualPx = 0.5;
constexpr double kDenseNominalSupport = 2000.0;
constexpr double kDenseNominalResidual = 10.0;

}  // namespace

const char* OutputFrameName(OutputFrame frame) {
  return frame == OutputFrame::kCam0 ? "cam0" : "body";
}

const char* ReportedStateName(ReportedState state) {
  switch (state) {
    case ReportedState::kUnspecified:
      return "UNSPECIFIED";
    case ReportedState::kInitializing:
      return "INITIALIZING";
    case ReportedState::kOk:
      return "OK";
    case ReportedState::kLost:
      return "LOST";
  }
  return "UNSPECIFIED";
}

bool RigOdometryOptions::IsValid(std::string* why) const {
  std::string inner;
  if (!calibration.IsValid(&inner)) {
    if (why != nullptr) *why = "calibration: " + inner;
    return false;
  }
  if (calibration_rectified &&
      (calibration.cam0.HasDistortion() || calibration.cam1.HasDistortion())) {
    if (why != nullptr) *why = "calibration: a rectified rig must have no distortion";
    return false;
  }
  return odometry.IsValid(method, why);
}

Result<std::unique_ptr<RigOdometry>> RigOdometry::Create(const RigOdometryOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument(why);
  MAV_ASSIGN_OR_RETURN(
      camera::RigRectification rectification,
      camera::RigRectification::Create(options.calibration, options.calibration_rectified));
  MAV_ASSIGN_OR_RETURN(std::unique_ptr<StereoOdometry> odometry,
                       StereoOdometry::Create(options.method, rectification.rig, options.odometry));
  return std::unique_ptr<RigOdometry>(
      new RigOdometry(options, std::move(rectification), std::move(odometry)));
}

RigOdometry::RigOdometry(RigOdometryOptions options, camera::RigRectification rectification,
                         std::unique_ptr<StereoOdometry> odometry)
    : options_(std::move(options)),
      rectification_(std::move(rectification)),
      odometry_(std::move(odometry)),
      T_world_body0_(options_.T_world_body0) {}

void RigOdometry::Reset(const std::optional<geometry::SE3>& T_world_body0) {
  odometry_->Reset();
  T_world_body0_ = T_world_body0.value_or(options_.T_world_body0);
  next_index_ = 0;
  T_world_out_previous_.reset();
  variance_.setZero();
}

Status RigOdometry::Rectify(const cv::Mat& left, const cv::Mat& right, bool rectified,
                            cv::Mat* rect_left, cv::Mat* rect_right) const {
  return rectification_.Rectify(left, right, rectified, rect_left, rect_right);
}

Result<RigPose> RigOdometry::Process(int64_t t_ns, const cv::Mat& left, const cv::Mat& right,
                                     bool rectified) {
  const int64_t start_ns = MonotonicNowNs();
  RigPose out;
  out.t_ns = t_ns;
  cv::Mat rect_left = left;
  cv::Mat rect_right = right;
  if (!rectified && rectification_.rectifier.has_value()) {
    const int64_t rectify_start = MonotonicNowNs();
    MAV_RETURN_IF_ERROR(rectification_.Rectify(left, right, false, &rect_left, &rect_right));
    out.timing.rectify_ms = MsSince(rectify_start);
  }
  MAV_ASSIGN_OR_RETURN(const OdometryFrame frame, odometry_->Process(t_ns, rect_left, rect_right));
  out.frame_index = next_index_++;
  const bool lost = frame.state == TrackingState::kLost;
  out.lost_reason = frame.lost_reason;
  out.matches = static_cast<uint32_t>(std::max(0, frame.matches));
  out.inliers = static_cast<uint32_t>(std::max(0, frame.support));
  out.residual = frame.residual;
  out.keyframe = frame.keyframe;
  out.timing.features_ms = frame.features_ms;
  out.timing.matching_ms = frame.matching_ms;
  out.timing.motion_ms = frame.motion_ms;
  out.timing.odometry_ms = frame.runtime_ms;

  const geometry::SE3 T_world_body = geometry::BodyPoseFromSensorOdometry(
      T_world_body0_, rectification_.T_body_rect0, frame.T_world_cam);
  out.T_world_out = options_.output_frame == OutputFrame::kCam0
                        ? T_world_body * options_.calibration.T_body_cam0
                        : T_world_body;
  out.T_prev_cur = T_world_out_previous_.has_value()
                       ? T_world_out_previous_->Inverse() * out.T_world_out
                       : geometry::SE3::Identity();
  T_world_out_previous_ = out.T_world_out;

  if (lost) {
    out.state = ReportedState::kLost;
  } else if (out.frame_index == 0 || frame.reference_reset) {
    out.state = ReportedState::kInitializing;
  } else {
    out.state = ReportedState::kOk;
  }

  const bool dense = options_.method == Method::kDense;
  const double nominal_support = dense ? kDenseNominalSupport : kSparseNominalSupport;
  const double nominal_residual = dense ? kDenseNominalResidual : kSparseNominalResidualPx;
  double sigma_p = 0, sigma_r = 0;
  if (lost) {
    sigma_p = kLostPositionSigmaM;
    sigma_r = kLostRotationSigmaRad;
  } else if (out.frame_index > 0) {
    const double scale = std::sqrt(nominal_support / std::max<double>(frame.support, 1.0)) *
                         std::max(1.0, frame.residual / nominal_residual);
    const Eigen::Matrix<double, 6, 1> xi = out.T_prev_cur.Log();
    sigma_p = scale * (kDriftFraction * xi.head<3>().norm() + kPositionFloorM);
    sigma_r = scale * (kDriftFraction * xi.tail<3>().norm() + kRotationFloorRad);
  }
  variance_.head<3>().array() += sigma_p * sigma_p;
  variance_.tail<3>().array() += sigma_r * sigma_r;
  out.covariance.fill(0.0);
  for (int i = 0; i < 6; ++i) out.covariance[i * 6 + i] = variance_[i];
  out.timing.total_ms = MsSince(start_ns);
  return out;
}

}  // namespace mav::localization
