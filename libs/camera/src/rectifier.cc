#include "mav/camera/rectifier.h"

#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>

namespace mav::camera {
namespace {

cv::Mat CameraMatrix(const PinholeRadTan& c) {
  return (cv::Mat_<double>(3, 3) << c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1);
}

cv::Mat DistortionVector(const PinholeRadTan& c) {
  return (cv::Mat_<double>(1, 4) << c.k1, c.k2, c.p1, c.p2);
}

}  // namespace

bool StereoRectifier::Options::IsValid(std::string* why) const {
  if (alpha < 0.0 || alpha > 1.0) {
    if (why) *why = "alpha: must be in [0, 1], got " + std::to_string(alpha);
    return false;
  }
  return true;
}

Result<StereoRectifier> StereoRectifier::Create(const StereoCalibration& calibration,
                                                const Options& options) {
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument("rectifier options: " + why);
  if (!calibration.IsValid(&why)) return Status::InvalidArgument("stereo calibration: " + why);

  // OpenCV wants the transform taking cam0 points into cam1: p_cam1 = R p_cam0 + T.
  const geometry::SE3 T_cam1_cam0 = calibration.T_cam0_cam1().Inverse();
  cv::Mat r, t;
  cv::eigen2cv(Eigen::Matrix3d(T_cam1_cam0.RotationMatrix()), r);
  cv::eigen2cv(Eigen::Vector3d(T_cam1_cam0.Translation()), t);
  const cv::Size size(calibration.cam0.width, calibration.cam0.height);
  cv::Mat r0, r1, p0, p1, q;
  cv::stereoRectify(CameraMatrix(calibration.cam0), DistortionVector(calibration.cam0),
                    CameraMatrix(calibration.cam1), DistortionVector(calibration.cam1), size, r, t,
                    r0, r1, p0, p1, q, cv::CALIB_ZERO_DISPARITY, options.alpha, size);

  StereoRectifier out;
  out.calibration_ = calibration;
  cv::cv2eigen(r0, out.R_rect0_cam0_);
  cv::cv2eigen(r1, out.R_rect1_cam1_);
  RectifiedStereo& rect = out.rectified_;
  rect.width = size.width;
  rect.height = size.height;
  rect.fx = p0.at<double>(0, 0);
  rect.fy = p0.at<double>(1, 1);
  rect.cx = p0.at<double>(0, 2);
  rect.cy = p0.at<double>(1, 2);
  // P1(0,3) = -fx * baseline for a horizontal rig with the right camera on the +x side.
  rect.baseline = -p1.at<double>(0, 3) / p1.at<double>(0, 0);
  if (!rect.IsValid(&why)) {
    return Status::InvalidArgument("stereo calibration: rectification failed (" + why +
                                   "); is cam1 to the right of cam0?");
  }

  cv::Mat m0x, m0y, m1x, m1y;
  cv::initUndistortRectifyMap(CameraMatrix(calibration.cam0), DistortionVector(calibration.cam0),
                              r0, p0, size, CV_32FC1, m0x, m0y);
  cv::initUndistortRectifyMap(CameraMatrix(calibration.cam1), DistortionVector(calibration.cam1),
                              r1, p1, size, CV_32FC1, m1x, m1y);
  out.map0x_ = std::make_shared<const cv::Mat>(m0x);
  out.map0y_ = std::make_shared<const cv::Mat>(m0y);
  out.map1x_ = std::make_shared<const cv::Mat>(m1x);
  out.map1y_ = std::make_shared<const cv::Mat>(m1y);
  return out;
}

geometry::SE3 StereoRectifier::T_body_rect0() const {
  return calibration_.T_body_cam0 *
         geometry::SE3(Eigen::Matrix3d(R_rect0_cam0_.transpose()), Eigen::Vector3d::Zero());
}

Status StereoRectifier::Rectify(const cv::Mat& raw_left, const cv::Mat& raw_right,
                                cv::Mat* rect_left, cv::Mat* rect_right) const {
  const cv::Size expected(calibration_.cam0.width, calibration_.cam0.height);
  if (raw_left.empty() || raw_right.empty()) {
    return Status::InvalidArgument("image: empty image passed to Rectify");
  }
  if (raw_left.size() != expected || raw_right.size() != expected) {
    return Status::InvalidArgument("image: size " + std::to_string(raw_left.cols) + "x" +
                                   std::to_string(raw_left.rows) + " does not match the " +
                                   std::to_string(expected.width) + "x" +
                                   std::to_string(expected.height) + " calibration");
  }
  cv::remap(raw_left, *rect_left, *map0x_, *map0y_, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
  cv::remap(raw_right, *rect_right, *map1x_, *map1y_, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
  return Status::Ok();
}

Result<RigRectification> RigRectification::Create(const StereoCalibration& calibration,
                                                  bool calibration_rectified) {
  std::string why;
  if (!calibration.IsValid(&why)) return Status::InvalidArgument("calibration: " + why);
  RigRectification out;
  if (calibration_rectified) {
    if (calibration.cam0.HasDistortion() || calibration.cam1.HasDistortion()) {
      return Status::InvalidArgument("calibration: a rectified rig must have no distortion");
    }
    const PinholeRadTan& cam0 = calibration.cam0;
    out.rig.width = cam0.width;
    out.rig.height = cam0.height;
    out.rig.fx = cam0.fx;
    out.rig.fy = cam0.fy;
    out.rig.cx = cam0.cx;
    out.rig.cy = cam0.cy;
    out.rig.baseline = calibration.Baseline();
    out.T_body_rect0 = calibration.T_body_cam0;
    return out;
  }
  Result<StereoRectifier> rectifier = StereoRectifier::Create(calibration);
  if (!rectifier.ok())
    return Status::InvalidArgument("calibration: " + rectifier.status().message());
  out.rig = rectifier->rectified();
  out.T_body_rect0 = rectifier->T_body_rect0();
  out.rectifier.emplace(std::move(*rectifier));
  return out;
}

Status RigRectification::Rectify(const cv::Mat& left, const cv::Mat& right, bool already_rectified,
                                 cv::Mat* rect_left, cv::Mat* rect_right) const {
  if (already_rectified || !rectifier.has_value()) {
    *rect_left = left;
    *rect_right = right;
    return Status::Ok();
  }
  return rectifier->Rectify(left, right, rect_left, rect_right);
}

}  // namespace mav::camera
