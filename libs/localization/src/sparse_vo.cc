#include "mav/localization/sparse_vo.h"

#include <cmath>
#include <optional>
#include <sstream>
#include <utility>

#include <opencv2/core.hpp>

#include "input_checks.h"
#include "mav/common/time.h"

namespace mav::localization {
namespace {

using internal::CheckImage;

ImageView ViewOf(const cv::Mat& m) {
  return ImageView{m.data, m.cols, m.rows, static_cast<int>(m.step[0])};
}

}  // namespace

const char* TrackingStateName(TrackingState state) {
  switch (state) {
    case TrackingState::kOk:
      return "OK";
    case TrackingState::kLost:
      return "LOST";
    case TrackingState::kDegraded:
      return "DEGRADED";
  }
  return "UNKNOWN";
}

const char* SparseVoModeName(SparseVoMode mode) {
  return mode == SparseVoMode::kPixel ? "pixel" : "subpixel";
}

bool SparseVoOptions::IsValid(std::string* why) const {
  std::string inner;
  if (!features.IsValid(&inner)) {
    if (why) *why = "features." + inner;
    return false;
  }
  if (!matcher.IsValid(&inner)) {
    if (why) *why = "matcher." + inner;
    return false;
  }
  if (!motion.IsValid(&inner)) {
    if (why) *why = "motion." + inner;
    return false;
  }
  if (!(pixel_inlier_threshold_px > 0) || !(subpixel_inlier_threshold_px > 0)) {
    if (why) {
      *why = "pixel_inlier_threshold_px/subpixel_inlier_threshold_px: must be > 0, got " +
             std::to_string(pixel_inlier_threshold_px) + "/" +
             std::to_string(subpixel_inlier_threshold_px);
    }
    return false;
  }
  if (pixel_max_starts_per_bucket < 0) {
    if (why) {
      *why = "pixel_max_starts_per_bucket: must be >= 0, got " +
             std::to_string(pixel_max_starts_per_bucket);
    }
    return false;
  }
  if (min_matches < 3) {
    if (why) *why = "min_matches: must be >= 3, got " + std::to_string(min_matches);
    return false;
  }
  if (!(max_translation_per_frame_m > 0)) {
    if (why) {
      *why = "max_translation_per_frame_m: must be > 0, got " +
             std::to_string(max_translation_per_frame_m);
    }
    return false;
  }
  if (!(keyframe_max_translation_m >= 0) || !(keyframe_max_rotation_deg >= 0)) {
    if (why) {
      *why = "keyframe_max_translation_m/keyframe_max_rotation_deg: must be >= 0, got " +
             std::to_string(keyframe_max_translation_m) + "/" +
             std::to_string(keyframe_max_rotation_deg);
    }
    return false;
  }
  if (keyframe_min_inliers < 0) {
    if (why) {
      *why = "keyframe_min_inliers: must be >= 0, got " + std::to_string(keyframe_min_inliers);
    }
    return false;
  }
  if (!(keyframe_min_inlier_ratio >= 0 && keyframe_min_inlier_ratio <= 1)) {
    if (why) {
      *why = "keyframe_min_inlier_ratio: must be in [0, 1], got " +
             std::to_string(keyframe_min_inlier_ratio);
    }
    return false;
  }
  if (!(gyro_rotation_sigma_rad >= 0 && gyro_rotation_sigma_rad <= 0.1)) {
    if (why) {
      *why = "gyro_rotation_sigma_rad: must be in [0, 0.1] (0 = vision only), got " +
             std::to_string(gyro_rotation_sigma_rad);
    }
    return false;
  }
  if (!(reprojection_sigma_px > 0) || !(gyro_gate_deg >= 0)) {
    if (why) {
      *why = "reprojection_sigma_px/gyro_gate_deg: must be > 0 / >= 0, got " +
             std::to_string(reprojection_sigma_px) + "/" + std::to_string(gyro_gate_deg);
    }
    return false;
  }
  return true;
}

struct SparseVo::Impl {
  Impl(const camera::RectifiedStereo& r, const SparseVoOptions& o)
      : rig(r), options(o), extractor(o.features) {}

  camera::RectifiedStereo rig;
  SparseVoOptions options;
  FeatureExtractor extractor;
  FeatureSet prev_left, prev_right, cur_left, cur_right;
  bool has_reference = false;
  // prev_left/prev_right hold the reference pair (the previous pair, or the kept keyframe).
  geometry::SE3 T_world_cam;
  geometry::SE3 T_world_ref;       // pose of the reference pair
  geometry::SE3 T_last_ref;        // previous frame relative to the reference pair
  geometry::SE3 T_cur_prev_prior;  // last frame-to-frame motion (constant-velocity prediction)
  bool prior_valid = false;
  int64_t frames = 0;
  std::vector<QuadMatch> matches;
  std::vector<int> inliers;
  std::vector<Eigen::Vector3d> points;
  std::vector<StereoObservation> observations;
  std::vector<int> match_of_point;

  // The previous pair's points of the matches (previous-left frame) and their current
  // observations, for the motion estimate.
  void TriangulateMatches() {
    points.clear();
    observations.clear();
    match_of_point.clear();
    for (size_t i = 0; i < matches.size(); ++i) {
      const QuadMatch& q = matches[i];
      const double disparity = q.u_prev_left - q.u_prev_right;
      if (!(disparity > 0.1)) continue;
      const double z = rig.DepthFromDisparity(disparity);
      points.emplace_back((q.u_prev_left - rig.cx) / rig.fx * z,
                          (q.v_prev_left - rig.cy) / rig.fy * z, z);
      observations.emplace_back(q.u_cur_left, q.v_cur_left, q.u_cur_right, q.v_cur_right);
      match_of_point.push_back(static_cast<int>(i));
    }
  }

  // Takes the estimated motion (T_world_cur from est) as the current pose, fills the frame's
  // figures and decides whether the reference pair stays.
  void AdoptMotion(const StereoMotionEstimate& est, const geometry::SE3& T_world_cur,
                   bool gyro_aided, VoFrameResult* result) {
    const geometry::SE3 T_prev_cur = T_world_cam.Inverse() * T_world_cur;
    for (int i : est.inliers) inliers.push_back(match_of_point[i]);
    result->num_inliers = static_cast<int>(est.inliers.size());
    result->mean_reprojection_error_px = est.mean_error_px;
    result->T_prev_cur = T_prev_cur;
    if (gyro_aided) {
      // The previous pair relative to the reference as tracked, the current one by vision alone.
      result->vision_R_prev_cur =
          (T_last_ref.Rotation() * est.vision_R_cur_prev.conjugate()).normalized();
    }
    T_world_cam = T_world_cur;
    T_cur_prev_prior = T_prev_cur.Inverse();
    prior_valid = true;
    T_last_ref = est.T_cur_prev;
    const double angle_deg =
        Eigen::AngleAxisd(est.T_cur_prev.Rotation()).angle() * 180.0 / 3.14159265358979323846;
    const bool keep = options.keep_reference_while_small &&
                      est.T_cur_prev.Translation().norm() < options.keyframe_max_translation_m &&
                      angle_deg < options.keyframe_max_rotation_deg &&
                      static_cast<int>(est.inliers.size()) >= options.keyframe_min_inliers &&
                      static_cast<double>(est.inliers.size()) >=
                          options.keyframe_min_inlier_ratio * static_cast<double>(points.size());
    if (!keep) AdoptCurrentAsReference();
  }

  void AdoptCurrentAsReference() {
    std::swap(prev_left, cur_left);
    std::swap(prev_right, cur_right);
    has_reference = true;
    T_world_ref = T_world_cam;
    T_last_ref = geometry::SE3();
  }
};

SparseVo::SparseVo(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
SparseVo::SparseVo(SparseVo&&) noexcept = default;
SparseVo& SparseVo::operator=(SparseVo&&) noexcept = default;
SparseVo::~SparseVo() = default;

Result<SparseVo> SparseVo::Create(const camera::RectifiedStereo& rig,
                                  const SparseVoOptions& options) {
  std::string why;
  if (!rig.IsValid(&why)) return Status::InvalidArgument("rig: " + why);
  if (!options.IsValid(&why)) return Status::InvalidArgument("options." + why);
  return SparseVo(std::make_unique<Impl>(rig, options));
}

void SparseVo::Reset() {
  impl_->has_reference = false;
  impl_->T_world_cam = geometry::SE3();
  impl_->T_world_ref = geometry::SE3();
  impl_->T_last_ref = geometry::SE3();
  impl_->T_cur_prev_prior = geometry::SE3();
  impl_->prior_valid = false;
  impl_->frames = 0;
  impl_->matches.clear();
  impl_->inliers.clear();
}

const geometry::SE3& SparseVo::T_world_cam() const { return impl_->T_world_cam; }
const SparseVoOptions& SparseVo::options() const { return impl_->options; }
const camera::RectifiedStereo& SparseVo::rig() const { return impl_->rig; }
int64_t SparseVo::frames_processed() const { return impl_->frames; }
const std::vector<QuadMatch>& SparseVo::last_matches() const { return impl_->matches; }
const std::vector<int>& SparseVo::last_inliers() const { return impl_->inliers; }

Result<VoFrameResult> SparseVo::ProcessFrame(int64_t t_ns, const cv::Mat& left,
                                             const cv::Mat& right, const MotionHint* hint) {
  Impl& s = *impl_;
  MAV_RETURN_IF_ERROR(CheckImage("left", left, s.rig));
  MAV_RETURN_IF_ERROR(CheckImage("right", right, s.rig));
  const SparseVoOptions& opt = s.options;
  const int64_t t_start = MonotonicNowNs();

  VoFrameResult result;
  result.t_ns = t_ns;
  result.frame_index = s.frames++;
  s.matches.clear();
  s.inliers.clear();
  auto finish = [&](TrackingState state, std::string reason) {
    result.state = state;
    result.lost_reason = std::move(reason);
    if (state == TrackingState::kLost) s.prior_valid = false;
    result.T_world_cam = s.T_world_cam;
    result.timing.total_ms = MsSince(t_start);
    return result;
  };

  // 1. Features of the current pair.
  int64_t t0 = MonotonicNowNs();
  s.extractor.Extract(ViewOf(left), &s.cur_left);
  s.extractor.Extract(ViewOf(right), &s.cur_right);
  result.num_features = s.cur_left.TotalFeatures();
  const int num_right = s.cur_right.TotalFeatures();
  result.timing.features_ms = MsSince(t0);
  if (result.num_features < opt.min_matches || num_right < opt.min_matches) {
    s.has_reference = false;  // nothing to match the next pair against
    return finish(TrackingState::kLost, "too few features: " + std::to_string(result.num_features) +
                                            " left, " + std::to_string(num_right) + " right (min " +
                                            std::to_string(opt.min_matches) + ")");
  }
  if (!s.has_reference) {
    result.reference_reset = true;
    s.AdoptCurrentAsReference();
    return finish(TrackingState::kOk, "");
  }

  // 2 + 3. Matching and motion; with a motion prediction first (small windows), and if that
  // fails once more with the wide windows around the same pixel.
  StereoMotionEstimate est;
  result.num_matches = 0;
  // Predicted motion from the reference pair to the current one: constant velocity on top of the
  // last frame's pose relative to the reference.
  const geometry::SE3 T_cur_ref_prior = s.T_cur_prev_prior * s.T_last_ref;
  // The gyro's rotation prior: the previous pair relative to the reference (T_last_ref, known
  // whenever there is a reference), turned by the gyro since.
  std::optional<RotationPrior> gyro_prior;
  if (hint != nullptr && opt.gyro_rotation_sigma_rad > 0) {
    gyro_prior = RotationPrior{hint->R_prev_cur.conjugate() * s.T_last_ref.Rotation(),
                               opt.reprojection_sigma_px / opt.gyro_rotation_sigma_rad,
                               opt.gyro_gate_deg * M_PI / 180};
  }
  MatcherOptions matcher = opt.matcher;
  if (opt.mode == SparseVoMode::kPixel && opt.pixel_max_starts_per_bucket > 0) {
    matcher.max_starts_per_bucket = opt.pixel_max_starts_per_bucket;
  }
  for (int attempt = 0; attempt < 2; ++attempt) {
    const bool use_prior = attempt == 0 && s.prior_valid && opt.matcher.use_motion_prior;
    if (attempt == 1 && !(s.prior_valid && opt.matcher.use_motion_prior)) break;
    t0 = MonotonicNowNs();
    MatchCircular(s.prev_left, s.prev_right, s.cur_left, s.cur_right, s.rig,
                  use_prior ? &T_cur_ref_prior : nullptr, matcher, &s.matches);
    BucketMatches(opt.matcher, s.rig.width, s.rig.height, &s.matches);
    if (opt.mode == SparseVoMode::kSubpixel) {
      RefineMatchesSubpixel(s.prev_left, s.prev_right, s.cur_left, s.cur_right, opt.matcher,
                            &s.matches);
    } else {
      RefineMatchesPixel(s.prev_left, s.prev_right, s.cur_left, s.cur_right, opt.matcher,
                         &s.matches);
    }
    result.num_matches = static_cast<int>(s.matches.size());
    result.timing.matching_ms += MsSince(t0);
    if (result.num_matches < opt.min_matches) {
      est.ok = false;
      est.failure = "too few matches: " + std::to_string(result.num_matches) + " (min " +
                    std::to_string(opt.min_matches) + ")";
      continue;
    }
    t0 = MonotonicNowNs();
    s.TriangulateMatches();
    StereoMotionOptions motion = opt.motion;
    motion.seed = opt.motion.seed + static_cast<uint64_t>(result.frame_index);
    motion.inlier_threshold_px = opt.mode == SparseVoMode::kPixel
                                     ? opt.pixel_inlier_threshold_px
                                     : opt.subpixel_inlier_threshold_px;
    est = EstimateStereoMotion(s.rig, s.points, s.observations, motion,
                               gyro_prior.has_value() ? &*gyro_prior : nullptr);
    result.timing.estimation_ms += MsSince(t0);
    // A wrong prediction shows as few matches or a low inlier ratio: retry without it.
    if (est.ok && 2 * est.inliers.size() >= s.points.size()) break;
  }
  if (!est.ok) {
    s.AdoptCurrentAsReference();
    return finish(TrackingState::kLost, est.failure);
  }
  // est.T_cur_prev maps reference-pair points into the current camera.
  const geometry::SE3 T_ref_cur = est.T_cur_prev.Inverse();
  const geometry::SE3 T_world_cur = s.T_world_ref * T_ref_cur;
  const geometry::SE3 T_prev_cur = s.T_world_cam.Inverse() * T_world_cur;
  const double step = T_prev_cur.Translation().norm();
  if (!(step <= opt.max_translation_per_frame_m)) {
    s.AdoptCurrentAsReference();
    std::ostringstream msg;
    msg << "implausible motion: " << step << " m in one frame (max "
        << opt.max_translation_per_frame_m << ")";
    return finish(TrackingState::kLost, msg.str());
  }
  s.AdoptMotion(est, T_world_cur, gyro_prior.has_value(), &result);
  return finish(TrackingState::kOk, "");
}

}  // namespace mav::localization
