#include "mav/camera/stereo.h"

#include <cmath>
#include <sstream>

namespace mav::camera {

bool StereoCalibration::IsValid(std::string* why) const {
  std::string inner;
  if (!cam0.IsValid(&inner)) {
    if (why) *why = "cam0: " + inner;
    return false;
  }
  if (!cam1.IsValid(&inner)) {
    if (why) *why = "cam1: " + inner;
    return false;
  }
  if (cam0.width != cam1.width || cam0.height != cam1.height) {
    if (why) *why = "cam1: resolution differs from cam0";
    return false;
  }
  const double b = Baseline();
  if (!std::isfinite(b) || b < 1e-3) {
    if (why) *why = "T_BS: cameras must be at least 1 mm apart, baseline is " + std::to_string(b);
    return false;
  }
  return true;
}

StereoCalibration EurocStereoCalibration() {
  StereoCalibration calib;
  calib.cam0 = EurocCam0();
  calib.cam1 = EurocCam1();
  Eigen::Matrix4d t0, t1;
  t0 << 0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975,  //
      0.999557249008, 0.0149672133247, 0.025715529948, -0.064676986768,        //
      -0.0257744366974, 0.00375618835797, 0.999660727178, 0.00981073058949,    //
      0, 0, 0, 1;
  t1 << 0.0125552670891, -0.999755099723, 0.0182237714554, -0.0198435579556,  //
      0.999598781151, 0.0130119051815, 0.0251588363115, 0.0453689425024,      //
      -0.0253898008918, 0.0179005838253, 0.999517347078, 0.00786212447038,    //
      0, 0, 0, 1;
  calib.T_body_cam0 = geometry::SE3::FromMatrix(t0);
  calib.T_body_cam1 = geometry::SE3::FromMatrix(t1);
  return calib;
}

bool RectifiedStereo::IsValid(std::string* why) const {
  std::ostringstream msg;
  if (width <= 0 || height <= 0) {
    msg << "resolution: must be positive, got " << width << "x" << height;
  } else if (!(fx > 0) || !(fy > 0)) {
    msg << "intrinsics: focal lengths must be positive";
  } else if (!(baseline > 0) || !std::isfinite(baseline)) {
    msg << "baseline: must be positive, got " << baseline;
  } else {
    return true;
  }
  if (why) *why = msg.str();
  return false;
}

std::optional<Eigen::Vector2d> RectifiedStereo::ProjectLeft(const Eigen::Vector3d& p) const {
  if (p.z() <= 1e-3) return std::nullopt;
  return Eigen::Vector2d(fx * p.x() / p.z() + cx, fy * p.y() / p.z() + cy);
}

std::optional<Eigen::Vector2d> RectifiedStereo::ProjectRight(const Eigen::Vector3d& p) const {
  return ProjectLeft(p - Eigen::Vector3d(baseline, 0, 0));
}

Eigen::Vector3d RectifiedStereo::Unproject(const Eigen::Vector2d& uv, double depth) const {
  return {(uv.x() - cx) / fx * depth, (uv.y() - cy) / fy * depth, depth};
}

std::optional<Eigen::Vector3d> RectifiedStereo::Triangulate(const Eigen::Vector2d& uv,
                                                            double disparity) const {
  if (!(disparity > 0)) return std::nullopt;
  return Unproject(uv, DepthFromDisparity(disparity));
}

Eigen::Matrix3d RectifiedStereo::K() const {
  Eigen::Matrix3d k;
  k << fx, 0, cx, 0, fy, cy, 0, 0, 1;
  return k;
}

PinholeRadTan RectifiedStereo::LeftPinhole() const {
  PinholeRadTan c;
  c.width = width;
  c.height = height;
  c.fx = fx;
  c.fy = fy;
  c.cx = cx;
  c.cy = cy;
  return c;
}

}  // namespace mav::camera
