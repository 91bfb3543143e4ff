#include "services/localization/convert.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <tuple>

#include "mav/common/text.h"

namespace mav::localization_service {

using service_common::Number;

namespace {

// An unsigned option: 0 keeps `*target`, otherwise it must lie in [lo, hi].
Status UintOption(uint32_t value, uint32_t lo, uint32_t hi, const std::string& field, int* target) {
  if (value == 0) return Status::Ok();
  if (value < lo || value > hi) {
    return Status::InvalidArgument(field + ": must be in [" + std::to_string(lo) + ", " +
                                   std::to_string(hi) + "], got " + std::to_string(value));
  }
  *target = static_cast<int>(value);
  return Status::Ok();
}

// A double option: 0 keeps `*target`, otherwise it must be finite and in (0, hi].
Status PositiveOption(double value, double hi, const std::string& field, double* target) {
  if (value == 0.0) return Status::Ok();
  if (!std::isfinite(value) || value <= 0.0 || value > hi) {
    return Status::InvalidArgument(field + ": must be > 0" +
                                   (std::isfinite(hi) ? " and <= " + Number(hi) : "") + ", got " +
                                   Number(value));
  }
  *target = value;
  return Status::Ok();
}

Status SparseFromProto(const v1::SparseVoOptions& in, Method method,
                       localization::SparseVoOptions* out) {
  out->features.half_resolution = in.half_resolution();
  MAV_RETURN_IF_ERROR(
      UintOption(in.nms_radius_px(), 1, 10, "sparse.nms_radius_px", &out->features.nms_radius));
  MAV_RETURN_IF_ERROR(UintOption(in.match_radius_px(), 10, 500, "sparse.match_radius_px",
                                 &out->matcher.search_radius_px));
  if (in.match_radius_px() != 0) {
    // Without a motion prior the window must be at least as wide as with one.
    out->matcher.search_radius_no_prior_px =
        std::max(out->matcher.search_radius_no_prior_px, out->matcher.search_radius_px);
  }
  MAV_RETURN_IF_ERROR(UintOption(in.bucket_width_px(), 10, 400, "sparse.bucket_width_px",
                                 &out->matcher.bucket_width_px));
  MAV_RETURN_IF_ERROR(UintOption(in.bucket_height_px(), 10, 400, "sparse.bucket_height_px",
                                 &out->matcher.bucket_height_px));
  MAV_RETURN_IF_ERROR(UintOption(in.max_features_per_bucket(), 1, 100,
                                 "sparse.max_features_per_bucket",
                                 &out->matcher.bucket_max_matches));
  MAV_RETURN_IF_ERROR(UintOption(in.ransac_iterations(), 10, 10000, "sparse.ransac_iterations",
                                 &out->motion.ransac_iterations));
  MAV_RETURN_IF_ERROR(
      UintOption(in.min_inliers(), 3, 1000, "sparse.min_inliers", &out->motion.min_inliers));
  double* threshold = method == Method::kSparsePixel ? &out->pixel_inlier_threshold_px
                                                     : &out->subpixel_inlier_threshold_px;
  MAV_RETURN_IF_ERROR(
      PositiveOption(in.inlier_threshold_px(), 20.0, "sparse.inlier_threshold_px", threshold));
  MAV_RETURN_IF_ERROR(PositiveOption(in.gyro_rotation_sigma_rad(), 0.1,
                                     "sparse.gyro_rotation_sigma_rad",
                                     &out->gyro_rotation_sigma_rad));
  out->mode = method == Method::kSparsePixel ? localization::SparseVoMode::kPixel
                                             : localization::SparseVoMode::kSubpixel;
  std::string why;
  if (!out->IsValid(&why)) return Status::InvalidArgument("sparse: " + why);
  return Status::Ok();
}

Status DenseFromProto(const v1::DenseVoOptions& in, localization::DenseVoOptions* out) {
  MAV_RETURN_IF_ERROR(
      UintOption(in.pyramid_levels(), 1, 6, "dense.pyramid_levels", &out->num_levels));
  MAV_RETURN_IF_ERROR(UintOption(in.max_iterations_per_level(), 1, 100,
                                 "dense.max_iterations_per_level", &out->max_iterations_per_level));
  if (in.block_size() != 0 && in.block_size() % 2 == 0) {
    return Status::InvalidArgument("dense.block_size: must be odd, got " +
                                   std::to_string(in.block_size()));
  }
  MAV_RETURN_IF_ERROR(UintOption(in.block_size(), 5, 31, "dense.block_size", &out->block_size));
  if (in.num_disparities() % 16 != 0) {
    return Status::InvalidArgument("dense.num_disparities: must be a multiple of 16, got " +
                                   std::to_string(in.num_disparities()));
  }
  MAV_RETURN_IF_ERROR(
      UintOption(in.num_disparities(), 16, 256, "dense.num_disparities", &out->num_disparities));
  constexpr double kInf = std::numeric_limits<double>::infinity();
  MAV_RETURN_IF_ERROR(PositiveOption(in.keyframe_photometric_error(), kInf,
                                     "dense.keyframe_photometric_error",
                                     &out->keyframe_max_rms_error));
  MAV_RETURN_IF_ERROR(PositiveOption(in.keyframe_rotation_deg(), 180.0,
                                     "dense.keyframe_rotation_deg",
                                     &out->keyframe_max_rotation_deg));
  MAV_RETURN_IF_ERROR(PositiveOption(in.keyframe_translation_m(), kInf,
                                     "dense.keyframe_translation_m",
                                     &out->keyframe_max_translation_m));
  if (in.huber_delta() != 0.0) {
    MAV_RETURN_IF_ERROR(PositiveOption(in.huber_delta(), kInf, "dense.huber_delta", &out->huber_k));
    out->loss = localization::DenseRobustLoss::kHuber;
  }
  // The pyramid must fit the finest tracked level and the depth level.
  out->finest_level = std::min(out->finest_level, out->num_levels - 1);
  out->depth_level = std::min(out->depth_level, out->num_levels - 1);
  std::string why;
  if (!out->IsValid(&why)) return Status::InvalidArgument("dense: " + why);
  return Status::Ok();
}

}  // namespace

Result<Method> MethodFromProto(v1::LocalizationMethod method) {
  return kMethodCodec.FromProto(method, "method");
}

v1::LocalizationMethod ToProto(Method method) { return kMethodCodec.ToProto(method); }

Result<LocalizerConfig> ConfigFromProto(const v1::LocalizationConfigureRequest& request) {
  LocalizerConfig config;
  localization::RigOdometryOptions& o = config.odometry;
  MAV_ASSIGN_OR_RETURN(o.method, MethodFromProto(request.method()));
  if (o.method == Method::kDense) {
    MAV_RETURN_IF_ERROR(DenseFromProto(request.dense(), &o.odometry.dense));
  } else {
    MAV_RETURN_IF_ERROR(SparseFromProto(request.sparse(), o.method, &o.odometry.sparse));
  }
  if (request.has_initial_pose()) {
    MAV_ASSIGN_OR_RETURN(o.T_world_body0, PoseFromProto(request.initial_pose(), "initial_pose"));
  }
  if (request.has_t_body_imu()) {
    MAV_ASSIGN_OR_RETURN(const geometry::SE3 T_body_imu,
                         PoseFromProto(request.t_body_imu(), "t_body_imu"));
    config.R_body_imu = T_body_imu.Rotation();
  }
  const std::string& frame = request.output_frame();
  if (frame.empty() || frame == "body") {
    o.output_frame = OutputFrame::kBody;
  } else if (frame == "cam0") {
    o.output_frame = OutputFrame::kCam0;
  } else {
    return Status::InvalidArgument("output_frame: " + QuoteForError(frame) +
                                   " is not body or cam0");
  }
  if (request.queue_length() > 100) {
    return Status::InvalidArgument("queue_length: must be <= 100, got " +
                                   std::to_string(request.queue_length()));
  }
  config.queue_length = request.queue_length() == 0 ? 2 : static_cast<int>(request.queue_length());
  return config;
}

void ToProto(const RigPose& pose, v1::PoseWithCovariance* out) {
  out->set_t_ns(pose.t_ns);
  ToProto(pose.T_world_out, out->mutable_pose());
  out->clear_covariance();
  for (double c : pose.covariance) out->add_covariance(c);
}

v1::TrackingState ToProto(ReportedState state) {
  return static_cast<v1::TrackingState>(static_cast<int>(state));
}

v1::LocalizationServiceState ToProto(LocalizerState state) {
  switch (state) {
    case LocalizerState::kUnconfigured:
      return v1::LOCALIZATION_SERVICE_STATE_UNCONFIGURED;
    case LocalizerState::kReady:
      return v1::LOCALIZATION_SERVICE_STATE_READY;
    case LocalizerState::kRunning:
      return v1::LOCALIZATION_SERVICE_STATE_RUNNING;
  }
  return v1::LOCALIZATION_SERVICE_STATE_UNSPECIFIED;
}

void ToProto(const RigPose& pose, v1::ProcessStereoPairResponse* out) {
  ToProto(pose, out->mutable_pose());
  out->set_tracking_state(ToProto(pose.state));
  out->set_lost_reason(pose.lost_reason);
  out->set_matches(pose.matches);
  out->set_inliers(pose.inliers);
  out->set_residual(pose.residual);
  out->set_keyframe(pose.keyframe);
  out->set_frame_index(pose.frame_index);
  v1::LocalizationTiming* timing = out->mutable_timing();
  timing->set_total_ms(pose.timing.total_ms);
  timing->set_rectify_ms(pose.timing.rectify_ms);
  timing->set_features_ms(pose.timing.features_ms);
  timing->set_matching_ms(pose.timing.matching_ms);
  timing->set_motion_ms(pose.timing.motion_ms);
  ToProto(pose.T_prev_cur, out->mutable_delta());
}

void ToProto(const RigPose& pose, v1::TrajectoryPoint* out) {
  ToProto(pose, out->mutable_pose());
  out->set_tracking_state(ToProto(pose.state));
  out->set_keyframe(pose.keyframe);
}

void ToProto(const camera::StereoCalibration& calibration, bool rectified,
             v1::StereoCalibration* out) {
  out->mutable_left()->set_camera_id("cam0");
  ToProto(calibration.cam0, out->mutable_left()->mutable_intrinsics());
  ToProto(calibration.T_body_cam0, out->mutable_left()->mutable_t_body_cam());
  out->mutable_right()->set_camera_id("cam1");
  ToProto(calibration.cam1, out->mutable_right()->mutable_intrinsics());
  ToProto(calibration.T_body_cam1, out->mutable_right()->mutable_t_body_cam());
  out->set_rectified(rectified);
  out->set_baseline_m(calibration.Baseline());
}

void ToProto(const LocalizerConfig& config, v1::LocalizationConfigureRequest* out) {
  const localization::RigOdometryOptions& c = config.odometry;
  out->set_method(ToProto(c.method));
  if (c.method == Method::kDense) {
    const localization::DenseVoOptions& d = c.odometry.dense;
    v1::DenseVoOptions* o = out->mutable_dense();
    o->set_pyramid_levels(static_cast<uint32_t>(d.num_levels));
    o->set_max_iterations_per_level(static_cast<uint32_t>(d.max_iterations_per_level));
    o->set_block_size(static_cast<uint32_t>(d.block_size));
    o->set_num_disparities(static_cast<uint32_t>(d.num_disparities));
    o->set_keyframe_photometric_error(d.keyframe_max_rms_error);
    o->set_keyframe_rotation_deg(d.keyframe_max_rotation_deg);
    o->set_keyframe_translation_m(d.keyframe_max_translation_m);
    o->set_huber_delta(d.loss == localization::DenseRobustLoss::kHuber ? d.huber_k : 0.0);
  } else {
    const localization::SparseVoOptions& s = c.odometry.sparse;
    v1::SparseVoOptions* o = out->mutable_sparse();
    o->set_half_resolution(s.features.half_resolution);
    o->set_nms_radius_px(static_cast<uint32_t>(s.features.nms_radius));
    o->set_match_radius_px(static_cast<uint32_t>(s.matcher.search_radius_px));
    o->set_bucket_width_px(static_cast<uint32_t>(s.matcher.bucket_width_px));
    o->set_bucket_height_px(static_cast<uint32_t>(s.matcher.bucket_height_px));
    o->set_max_features_per_bucket(static_cast<uint32_t>(s.matcher.bucket_max_matches));
    o->set_ransac_iterations(static_cast<uint32_t>(s.motion.ransac_iterations));
    o->set_inlier_threshold_px(c.method == Method::kSparsePixel ? s.pixel_inlier_threshold_px
                                                                : s.subpixel_inlier_threshold_px);
    o->set_min_inliers(static_cast<uint32_t>(s.motion.min_inliers));
    o->set_gyro_rotation_sigma_rad(s.gyro_rotation_sigma_rad);
  }
  ToProto(c.calibration, c.calibration_rectified,
          out->mutable_calibration()->mutable_calibration());
  ToProto(c.T_world_body0, out->mutable_initial_pose());
  out->set_output_frame(localization::OutputFrameName(c.output_frame));
  out->set_queue_length(static_cast<uint32_t>(config.queue_length));
  ToProto(geometry::SE3(config.R_body_imu, Eigen::Vector3d::Zero()), out->mutable_t_body_imu());
}

void ToProto(const LocalizerStatus& status, bool dds_input, v1::LocalizationStatus* out) {
  out->set_state(ToProto(status.state));
  if (status.config.has_value()) {
    out->set_method(ToProto(status.config->odometry.method));
    ToProto(*status.config, out->mutable_config());
    out->mutable_config()->set_disable_dds_input(!dds_input);
  }
  out->set_frames_processed(status.frames_processed);
  out->set_frames_dropped(status.frames_dropped);
  out->set_frames_lost(status.frames_lost);
  out->set_frames_degraded(status.frames_degraded);
  out->set_gyro_samples(status.gyro_samples);
  out->set_frames_rejected(status.frames_rejected);
  out->set_fps(status.fps);
  if (status.last.has_value()) {
    out->set_tracking_state(ToProto(status.last->state));
    out->set_lost_reason(status.last->lost_reason);
    ToProto(*status.last, out->mutable_last_pose());
  }
  ToProto(status.processing_ms, out->mutable_processing_ms());
  out->set_keyframes(status.keyframes);
  out->set_queue_depth(status.queue_depth);
  out->set_dds_input(dds_input);
}

}  // namespace mav::localization_service
