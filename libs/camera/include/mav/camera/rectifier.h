#pragma once
// Rectification of a raw stereo pair with OpenCV (cv::stereoRectify + initUndistortRectifyMap).
// Kept out of stereo.h so that only code that rectifies images pulls in OpenCV headers.

#include <memory>
#include <optional>

#include <opencv2/core/mat.hpp>

#include "mav/camera/stereo.h"
#include "mav/common/status.h"

namespace mav::camera {

class StereoRectifier {
 public:
  struct Options {
    // 0 keeps only valid pixels (zoomed in), 1 keeps all source pixels (black borders).
    // 0 suits stereo matching: no invalid border pixels.
    double alpha = 0.0;
    bool IsValid(std::string* why) const;
  };

  // Computes the maps once per rig. Fails (InvalidArgument naming the field) on a bad calibration.
  static Result<StereoRectifier> Create(const StereoCalibration& calibration,
                                        const Options& options);
  static Result<StereoRectifier> Create(const StereoCalibration& calibration) {
    return Create(calibration, Options());
  }

  const RectifiedStereo& rectified() const { return rectified_; }
  // Rotation from the raw camera-0 frame to the rectified left frame, and likewise for camera 1:
  // p_rect0 = R_rect0_cam0 * p_cam0. The rectified left frame shares cam0's optical centre.
  const Eigen::Matrix3d& R_rect0_cam0() const { return R_rect0_cam0_; }
  const Eigen::Matrix3d& R_rect1_cam1() const { return R_rect1_cam1_; }
  // Pose of the rectified left camera in the body frame.
  geometry::SE3 T_body_rect0() const;

  // Remaps a raw 8-bit grey pair (sizes must match the calibration) with bilinear interpolation.
  Status Rectify(const cv::Mat& raw_left, const cv::Mat& raw_right, cv::Mat* rect_left,
                 cv::Mat* rect_right) const;

 private:
  StereoRectifier() = default;

  StereoCalibration calibration_;
  RectifiedStereo rectified_;
  Eigen::Matrix3d R_rect0_cam0_ = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d R_rect1_cam1_ = Eigen::Matrix3d::Identity();
  // CV_32FC1 maps (shared so the rectifier copies cheaply).
  std::shared_ptr<const cv::Mat> map0x_, map0y_, map1x_, map1y_;
};

// A calibrated rig prepared for the rectified-stereo algorithms (VO, mapping): either a raw rig
// with its StereoRectifier, or a rig whose calibration already is an ideal rectified pair
// (`calibration_rectified`: no distortion, rows aligned), used as it is.
//   rig           the rectified left/right pair the algorithms work in;
//   T_body_rect0  pose of the rectified left camera in the body frame (T_body_cam0 for a
//                 rectified calibration).
struct RigRectification {
  RectifiedStereo rig;
  geometry::SE3 T_body_rect0;
  std::optional<StereoRectifier> rectifier;  // empty for a rectified calibration

  // InvalidArgument "calibration: ..." for a bad calibration, or a rig flagged rectified that
  // has distortion.
  static Result<RigRectification> Create(const StereoCalibration& calibration,
                                         bool calibration_rectified);

  // The pair in the rectified geometry: remapped when raw, as it is when `already_rectified` or
  // when the calibration is rectified (no copy: the outputs share the inputs' pixels then).
  Status Rectify(const cv::Mat& left, const cv::Mat& right, bool already_rectified,
                 cv::Mat* rect_left, cv::Mat* rect_right) const;
};

}  // namespace mav::camera
