#pragma once
// Pinhole camera with radial-tangential ("plumb bob") distortion, the model of EuRoC's
// sensor.yaml (distortion_model: radial-tangential, coefficients k1 k2 p1 p2):
//
//   x = X/Z, y = Y/Z, r^2 = x^2 + y^2
//   x_d = x (1 + k1 r^2 + k2 r^4) + 2 p1 x y + p2 (r^2 + 2 x^2)
//   y_d = y (1 + k1 r^2 + k2 r^4) + p1 (r^2 + 2 y^2) + 2 p2 x y
//   u = fx x_d + cx,  v = fy y_d + cy
//
// Pixel coordinates put the centre of the top-left pixel at (0, 0) (OpenCV's convention).
// Frames: points are in the camera frame (z forward, x right, y down).

#include <optional>
#include <string>

#include <Eigen/Core>

namespace mav::camera {

struct PinholeRadTan {
  int width = 0;
  int height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  double k1 = 0, k2 = 0, p1 = 0, p2 = 0;

  bool IsValid(std::string* why) const;
  bool HasDistortion() const { return k1 != 0 || k2 != 0 || p1 != 0 || p2 != 0; }

  // Normalised image point (x, y) -> distorted normalised point.
  Eigen::Vector2d Distort(const Eigen::Vector2d& xy) const;
  // Inverse of Distort by Gauss-Newton on the 2x2 system; converges in a few steps within the
  // image for EuRoC-strength distortion. Returns nullopt if it does not converge.
  std::optional<Eigen::Vector2d> Undistort(const Eigen::Vector2d& xy_distorted) const;

  // Camera-frame point -> pixel. Nullopt behind the camera (Z <= 1 mm).
  // If `jacobian` is given it receives d(u,v)/d(X,Y,Z).
  std::optional<Eigen::Vector2d> Project(const Eigen::Vector3d& p_cam,
                                         Eigen::Matrix<double, 2, 3>* jacobian = nullptr) const;
  // Pixel -> unit bearing in the camera frame. Nullopt if undistortion fails.
  std::optional<Eigen::Vector3d> Unproject(const Eigen::Vector2d& uv) const;
  // True if the pixel lies inside [0, width-1] x [0, height-1] with `margin` to spare.
  bool InImage(const Eigen::Vector2d& uv, double margin = 0.0) const;
};

// EuRoC MAV data set cam0 / cam1 intrinsics (MT9V034, 752x480), from the data set's sensor.yaml.
PinholeRadTan EurocCam0();
PinholeRadTan EurocCam1();

}  // namespace mav::camera
