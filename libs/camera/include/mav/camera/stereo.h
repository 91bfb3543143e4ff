#pragma once
// Stereo rigs: the raw calibration (two distorted cameras and their extrinsics, as in EuRoC's
// sensor.yaml), and the ideal rectified pair that stereo algorithms work on.

#include <optional>
#include <string>

#include <Eigen/Core>

#include "mav/camera/pinhole.h"
#include "mav/geometry/se3.h"

namespace mav::camera {

// A raw stereo rig. T_body_cam maps camera-frame points into the body (IMU) frame; EuRoC calls
// it T_BS. The relative pose T_cam0_cam1 follows.
struct StereoCalibration {
  PinholeRadTan cam0;
  PinholeRadTan cam1;
  geometry::SE3 T_body_cam0;
  geometry::SE3 T_body_cam1;

  geometry::SE3 T_cam0_cam1() const { return T_body_cam0.Inverse() * T_body_cam1; }
  double Baseline() const { return T_cam0_cam1().Translation().norm(); }
  bool IsValid(std::string* why) const;
};

// EuRoC's Vicon-room calibration (both cameras, distortion, extrinsics, ~0.110 m baseline).
StereoCalibration EurocStereoCalibration();

// An ideal rectified pair: identical pinhole intrinsics without distortion, the right camera
// displaced by +baseline along the left camera's x axis, image rows aligned.
// For a point at depth Z: disparity d = u_left - u_right = fx * baseline / Z.
struct RectifiedStereo {
  int width = 0;
  int height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  double baseline = 0;  // metres, > 0

  bool IsValid(std::string* why) const;
  // Point in the rectified left frame -> left pixel. Nullopt if Z <= 1 mm.
  std::optional<Eigen::Vector2d> ProjectLeft(const Eigen::Vector3d& p_left) const;
  std::optional<Eigen::Vector2d> ProjectRight(const Eigen::Vector3d& p_left) const;
  // Left pixel + depth -> point in the left frame.
  Eigen::Vector3d Unproject(const Eigen::Vector2d& uv_left, double depth) const;
  // Left pixel + disparity (> 0) -> point in the left frame. Nullopt for disparity <= 0.
  std::optional<Eigen::Vector3d> Triangulate(const Eigen::Vector2d& uv_left,
                                             double disparity) const;
  double DisparityFromDepth(double depth) const { return fx * baseline / depth; }
  double DepthFromDisparity(double disparity) const { return fx * baseline / disparity; }
  // The intrinsic matrix K.
  Eigen::Matrix3d K() const;
  // The undistorted pinhole model of the left camera (all distortion terms zero).
  PinholeRadTan LeftPinhole() const;
};

}  // namespace mav::camera
