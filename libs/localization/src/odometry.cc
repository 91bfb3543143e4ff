#include "mav/localization/odometry.h"

#include <opencv2/core/mat.hpp>

#include "mav/localization/dense_vo.h"
#include "mav/localization/sparse_vo.h"

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

namespace {

class SparseOdometry final : public StereoOdometry {
 public:
  SparseOdometry(Method method, SparseVo vo) : method_(method), vo_(std::move(vo)) {}

  Result<OdometryFrame> Process(int64_t t_ns, const cv::Mat& left, const cv::Mat& right) override {
    MAV_ASSIGN_OR_RETURN(const VoFrameResult r, vo_.ProcessFrame(t_ns, left, right));
    OdometryFrame out;
    out.t_ns = r.t_ns;
    out.state = r.state;
    out.lost_reason = r.lost_reason;
    out.T_world_cam = r.T_world_cam;
    out.support = r.num_inliers;
    out.residual = r.mean_reprojection_error_px;
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

  Result<OdometryFrame> Process(int64_t t_ns, const cv::Mat& left, const cv::Mat& right) override {
    MAV_ASSIGN_OR_RETURN(const DenseFrameResult r, vo_.ProcessFrame(t_ns, left, right));
    OdometryFrame out;
    out.t_ns = r.t_ns;
    out.state = r.state;
    out.lost_reason = r.lost_reason;
    out.T_world_cam = r.T_world_cam;
    out.support = r.num_pixels_used;
    out.residual = r.rms_error;
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
                                                               const camera::RectifiedStereo& rig) {
  if (method == Method::kDense) {
    MAV_ASSIGN_OR_RETURN(DenseVo vo, DenseVo::Create(rig));
    return std::unique_ptr<StereoOdometry>(new DenseOdometry(std::move(vo)));
  }
  SparseVoOptions options;
  options.mode = method == Method::kSparsePixel ? SparseVoMode::kPixel : SparseVoMode::kSubpixel;
  MAV_ASSIGN_OR_RETURN(SparseVo vo, SparseVo::Create(rig, options));
  return std::unique_ptr<StereoOdometry>(new SparseOdometry(method, std::move(vo)));
}

}  // namespace mav::localization
