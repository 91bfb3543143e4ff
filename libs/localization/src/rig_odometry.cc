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
    case ReportedState::kDegraded:
      return "DEGRADED";
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
  if (!(gyro_bias_gain >= 0 && gyro_bias_gain < 1)) {
    if (why != nullptr) *why = "gyro_bias_gain: must be in [0, 1)";
    return false;
  }
  if (!(gyro_bias_gate_deg > 0)) {
    if (why != nullptr) *why = "gyro_bias_gate_deg: must be > 0";
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

void RigOdometry::AddGyro(int64_t t_ns, const Eigen::Vector3d& omega_body) {
  if (!omega_body.allFinite()) return;
  if (!gyro_.empty() && t_ns <= gyro_.back().t_ns) {
    // A repeated or late sample is dropped; a clock that went back by more than
    // kNewGyroStreamNs (1 s) is a new stream (a replay started again).
    if (t_ns >= gyro_.back().t_ns - kNewGyroStreamNs) return;
    gyro_.clear();
  }
  gyro_.push_back({t_ns, omega_body});
  while (gyro_.size() > kGyroHistory) gyro_.pop_front();
}

std::optional<Eigen::Quaterniond> RigOdometry::IntegrateGyro(int64_t t0_ns, int64_t t1_ns) const {
  // The samples must span [t0, t1] up to one gap of kMaxGyroGapNs at each end; the rate is
  // linear between samples and constant beyond the last one.
  if (gyro_.empty() || t1_ns <= t0_ns) return std::nullopt;
  if (gyro_.front().t_ns > t0_ns + kMaxGyroGapNs || gyro_.back().t_ns < t1_ns - kMaxGyroGapNs) {
    return std::nullopt;
  }
  auto rate_at = [&](size_t i, int64_t t) -> Eigen::Vector3d {
    // Between samples i and i + 1 (or beyond the ends: the nearest sample).
    if (i + 1 >= gyro_.size() || t <= gyro_[i].t_ns) return gyro_[i].omega;
    const double f = static_cast<double>(t - gyro_[i].t_ns) /
                     static_cast<double>(gyro_[i + 1].t_ns - gyro_[i].t_ns);
    return gyro_[i].omega + std::min(1.0, f) * (gyro_[i + 1].omega - gyro_[i].omega);
  };
  Eigen::Quaterniond R = Eigen::Quaterniond::Identity();
  int64_t t = t0_ns;
  size_t i = 0;
  while (i + 1 < gyro_.size() && gyro_[i + 1].t_ns <= t) ++i;
  while (t < t1_ns) {
    const int64_t next =
        i + 1 < gyro_.size() ? std::min(t1_ns, std::max(t + 1, gyro_[i + 1].t_ns)) : t1_ns;
    if (i + 1 < gyro_.size() && gyro_[i + 1].t_ns - gyro_[i].t_ns > kMaxGyroGapNs &&
        next > gyro_[i].t_ns) {
      return std::nullopt;  // a gap in the samples inside the interval
    }
    const Eigen::Vector3d omega = 0.5 * (rate_at(i, t) + rate_at(i, next)) - gyro_bias_;
    R = R * geometry::ExpSO3(omega * 1e-9 * static_cast<double>(next - t));
    t = next;
    if (i + 1 < gyro_.size() && gyro_[i + 1].t_ns <= t) ++i;
  }
  return R.normalized();
}

void RigOdometry::UpdateGyroBias(const Eigen::Quaterniond& R_body_gyro,
                                 const Eigen::Quaterniond& R_prev_cur_cam, double dt_s) {
  if (!(dt_s > 0)) return;
  const Eigen::Quaterniond& q_br = rectification_.T_body_rect0.Rotation();
  const Eigen::Quaterniond R_body_vo = q_br * R_prev_cur_cam * q_br.conjugate();
  // The gyro over-rotates by (b_true - b_est) dt: move the estimate by a fraction of the
  // disagreement per frame (an exponential average over ~1 / gyro_bias_gain frames). The first
  // frames average with equal weights (gain 1/k for the k-th), so a constant offset is learnt
  // in as many frames as its noise needs, not in 1 / gain.
  const Eigen::Vector3d e = geometry::LogSO3(R_body_gyro.conjugate() * R_body_vo);
  if (!(e.norm() <= options_.gyro_bias_gate_deg * M_PI / 180)) return;
  ++gyro_bias_updates_;
  const double gain =
      options_.gyro_bias_gain > 0
          ? std::max(options_.gyro_bias_gain, 1.0 / static_cast<double>(gyro_bias_updates_))
          : 0.0;
  gyro_bias_ -= gain * e / dt_s;
}

void RigOdometry::Reset(const std::optional<geometry::SE3>& T_world_body0) {
  odometry_->Reset();
  t_previous_ns_.reset();
  T_world_cam_previous_.reset();
  previous_ok_ = false;
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
  std::optional<Eigen::Quaterniond> R_body_gyro;
  const bool gyro_wanted =
      options_.method == Method::kDense || options_.odometry.sparse.gyro_rotation_sigma_rad > 0;
  if (options_.use_gyro && gyro_wanted && t_previous_ns_.has_value()) {
    R_body_gyro = IntegrateGyro(*t_previous_ns_, t_ns);
  }
  std::optional<MotionHint> hint;
  if (R_body_gyro.has_value()) {
    // The rectified left camera is rigid on the body: R_cam = R_body_rect^T R_body R_body_rect.
    const Eigen::Quaterniond& q_br = rectification_.T_body_rect0.Rotation();
    hint = MotionHint{q_br.conjugate() * *R_body_gyro * q_br};
  }
  MAV_ASSIGN_OR_RETURN(
      const OdometryFrame frame,
      odometry_->Process(t_ns, rect_left, rect_right, hint.has_value() ? &*hint : nullptr));
  const double dt_s =
      t_previous_ns_.has_value() ? 1e-9 * static_cast<double>(t_ns - *t_previous_ns_) : 0.0;
  t_previous_ns_ = t_ns;
  const std::optional<geometry::SE3> T_world_cam_previous = T_world_cam_previous_;
  T_world_cam_previous_ = frame.T_world_cam;
  out.frame_index = next_index_++;
  const bool lost = frame.state == TrackingState::kLost;
  const bool degraded = frame.state == TrackingState::kDegraded;
  out.gyro_used = hint.has_value();
  out.lost_reason = frame.lost_reason;
  out.matches = static_cast<uint32_t>(std::max(0, frame.matches));
  out.inliers = static_cast<uint32_t>(std::max(0, frame.support));
  out.residual = frame.residual;
  out.prediction_error_m = frame.prediction_error_m;
  out.gyro_rotation_error_deg = frame.gyro_rotation_error_deg;
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

  // The bias learns only from two consecutive measured (OK) frames.
  const bool ok = frame.state == TrackingState::kOk;
  if (R_body_gyro.has_value() && T_world_cam_previous.has_value() && previous_ok_ && ok &&
      !frame.reference_reset) {
    UpdateGyroBias(*R_body_gyro,
                   frame.vision_R_prev_cur.value_or(
                       (T_world_cam_previous->Inverse() * frame.T_world_cam).Rotation()),
                   dt_s);
  }
  previous_ok_ = ok;

  if (lost) {
    out.state = ReportedState::kLost;
  } else if (degraded) {
    out.state = ReportedState::kDegraded;
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
  } else if (degraded) {
    sigma_p = kDegradedPositionSigmaM;
    sigma_r = kDegradedRotationSigmaRad;
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
