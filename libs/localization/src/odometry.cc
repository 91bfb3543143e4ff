#include "mav/localization/odometry.h"

#include <opencv2/core/mat.hpp>

namespace mav::localization {

const char* MethodName(Method method) {
  switch (method) {
    case Method::kSparsePixel:
      return "sparse-pixel";
    case Method::kSparseSubpixel:
      return "sparse-subpixel";
    case Method::kDense:
      return "dense";
  }
  return "unknown";
}

std::optional<Method> ParseMethod(std::string_view name) {
  for (Method m : AllMethods()) {
    if (name == MethodName(m)) return m;
  }
  return std::nullopt;
}

const std::vector<Method>& AllMethods() {
  static const std::vector<Method> kMethods = {Method::kSparsePixel, Method::kSparseSubpixel,
                                               Method::kDense};
  return kMethods;
}

bool OdometryOptions::IsValid(Method method, std::string* why) const {
  std::string inner;
  if (method == Method::kDense) {
    if (!dense.IsValid(&inner)) {
      if (why != nullptr) *why = "dense: " + inner;
      return false;
    }
  } else if (!sparse.IsValid(&inner)) {
    if (why != nullptr) *why = "sparse: " + inner;
    return false;
  }
  return true;
}

namespace {

// The fields both VOs' frame results share.
template <typename FrameResult>
OdometryFrame CommonFields(const FrameResult& r) {
  OdometryFrame out;
  out.t_ns = r.t_ns;
  out.state = r.state;
  out.lost_reason = r.lost_reason;
  out.T_world_cam = r.T_world_cam;
  out.reference_reset = r.reference_reset;
  return out;
}

class SparseOdometry final : public StereoOdometry {
 public:
  SparseOdometry(Method method, SparseVo vo) : method_(method), vo_(std::move(vo)) {}

  Result<OdometryFrame> Process(int64_t t_ns, const cv::Mat& left, const cv::Mat& right,
                                const MotionHint* hint) override {
    MAV_ASSIGN_OR_RETURN(const VoFrameResult r, vo_.ProcessFrame(t_ns, left, right, hint));
    OdometryFrame out = CommonFields(r);
    out.vision_R_prev_cur = r.vision_R_prev_cur;
    out.matches = r.num_matches;
    out.support = r.num_inliers;
    out.residual = r.mean_reprojection_error_px;
    out.features_ms = r.timing.features_ms;
    out.matching_ms = r.timing.matching_ms;
    out.motion_ms = r.timing.estimation_ms;
    out.runtime_ms = r.timing.total_ms;
    return out;
  }
  void Reset() override { vo_.Reset(); }
  Method method() const override { return method_; }

 private:
  Method method_;
  SparseVo vo_;
};

class DenseOdometry final : public StereoOdometry {
 public:
  explicit DenseOdometry(DenseVo vo) : vo_(std::move(vo)) {}

  Result<OdometryFrame> Process(int64_t t_ns, const cv::Mat& left, const cv::Mat& right,
                                const MotionHint* hint) override {
    MAV_ASSIGN_OR_RETURN(const DenseFrameResult r, vo_.ProcessFrame(t_ns, left, right, hint));
    OdometryFrame out = CommonFields(r);
    out.keyframe = r.new_keyframe;
    out.matches = r.num_keyframe_pixels;
    out.support = r.num_pixels_used;
    out.residual = r.rms_error;
    out.prediction_error_m = r.prediction_error_m;
    out.gyro_rotation_error_deg = r.gyro_rotation_error_deg;
    out.features_ms = r.timing.keyframe_ms;
    out.motion_ms = r.timing.pyramid_ms + r.timing.tracking_ms;
    out.runtime_ms = r.timing.total_ms;
    return out;
  }
  void Reset() override { vo_.Reset(); }
  Method method() const override { return Method::kDense; }

 private:
  DenseVo vo_;
};

}  // namespace

Result<std::unique_ptr<StereoOdometry>> StereoOdometry::Create(Method method,
                                                               const camera::RectifiedStereo& rig,
                                                               const OdometryOptions& options) {
  std::string why;
  if (!options.IsValid(method, &why)) return Status::InvalidArgument(why);
  if (method == Method::kDense) {
    Result<DenseVo> vo = DenseVo::Create(rig, options.dense);
    if (!vo.ok()) return Status::InvalidArgument("dense: " + vo.status().message());
    return std::unique_ptr<StereoOdometry>(new DenseOdometry(std::move(*vo)));
  }
  SparseVoOptions sparse = options.sparse;
  sparse.mode = method == Method::kSparsePixel ? SparseVoMode::kPixel : SparseVoMode::kSubpixel;
  Result<SparseVo> created = SparseVo::Create(rig, sparse);
  if (!created.ok()) return Status::InvalidArgument("sparse: " + created.status().message());
  SparseVo vo = std::move(*created);
  return std::unique_ptr<StereoOdometry>(new SparseOdometry(method, std::move(vo)));
}

}  // namespace mav::localization
