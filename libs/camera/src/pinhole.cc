#include "mav/camera/pinhole.h"

#include <cmath>
#include <sstream>

#include <Eigen/LU>

namespace mav::camera {

bool PinholeRadTan::IsValid(std::string* why) const {
  std::ostringstream msg;
  if (width <= 0 || height <= 0) {
    msg << "resolution: must be positive, got " << width << "x" << height;
  } else if (!(fx > 0) || !(fy > 0) || !std::isfinite(fx) || !std::isfinite(fy)) {
    msg << "intrinsics: focal lengths must be positive and finite, got fx=" << fx << " fy=" << fy;
  } else if (!std::isfinite(cx) || !std::isfinite(cy)) {
    msg << "intrinsics: principal point must be finite";
  } else if (!std::isfinite(k1) || !std::isfinite(k2) || !std::isfinite(p1) || !std::isfinite(p2)) {
    msg << "distortion_coefficients: must be finite";
  } else {
    return true;
  }
  if (why != nullptr) *why = msg.str();
  return false;
}

Eigen::Vector2d PinholeRadTan::Distort(const Eigen::Vector2d& xy) const {
  const double x = xy.x(), y = xy.y();
  const double r2 = x * x + y * y;
  const double radial = 1.0 + k1 * r2 + k2 * r2 * r2;
  return {x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
          y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y};
}

namespace {

// d(distorted)/d(undistorted) at xy.
Eigen::Matrix2d DistortJacobian(const PinholeRadTan& c, const Eigen::Vector2d& xy) {
  const double x = xy.x(), y = xy.y();
  const double r2 = x * x + y * y;
  const double radial = 1.0 + c.k1 * r2 + c.k2 * r2 * r2;
  const double d_radial_dr2 = c.k1 + 2.0 * c.k2 * r2;
  Eigen::Matrix2d j;
  j(0, 0) = radial + x * d_radial_dr2 * 2.0 * x + 2.0 * c.p1 * y + c.p2 * 6.0 * x;
  j(0, 1) = x * d_radial_dr2 * 2.0 * y + 2.0 * c.p1 * x + c.p2 * 2.0 * y;
  j(1, 0) = y * d_radial_dr2 * 2.0 * x + c.p1 * 2.0 * x + 2.0 * c.p2 * y;
  j(1, 1) = radial + y * d_radial_dr2 * 2.0 * y + c.p1 * 6.0 * y + 2.0 * c.p2 * x;
  return j;
}

}  // namespace

std::optional<Eigen::Vector2d> PinholeRadTan::Undistort(const Eigen::Vector2d& xy_d) const {
  if (!HasDistortion()) return xy_d;
  Eigen::Vector2d xy = xy_d;
  for (int iter = 0; iter < 20; ++iter) {
    const Eigen::Vector2d residual = Distort(xy) - xy_d;
    if (residual.squaredNorm() < 1e-24) return xy;
    const Eigen::Matrix2d j = DistortJacobian(*this, xy);
    if (std::abs(j.determinant()) < 1e-12) return std::nullopt;
    xy -= j.inverse() * residual;
  }
  if ((Distort(xy) - xy_d).norm() < 1e-9) return xy;
  return std::nullopt;
}

std::optional<Eigen::Vector2d> PinholeRadTan::Project(const Eigen::Vector3d& p,
                                                      Eigen::Matrix<double, 2, 3>* jacobian) const {
  if (p.z() <= 1e-3) return std::nullopt;
  const double inv_z = 1.0 / p.z();
  const Eigen::Vector2d xy(p.x() * inv_z, p.y() * inv_z);
  const Eigen::Vector2d xy_d = Distort(xy);
  if (jacobian != nullptr) {
    Eigen::Matrix<double, 2, 3> d_xy_d_p;
    d_xy_d_p << inv_z, 0, -p.x() * inv_z * inv_z, 0, inv_z, -p.y() * inv_z * inv_z;
    const Eigen::Matrix2d d_uv_d_xyd = Eigen::Vector2d(fx, fy).asDiagonal();
    *jacobian = d_uv_d_xyd * DistortJacobian(*this, xy) * d_xy_d_p;
  }
  return Eigen::Vector2d(fx * xy_d.x() + cx, fy * xy_d.y() + cy);
}

std::optional<Eigen::Vector3d> PinholeRadTan::Unproject(const Eigen::Vector2d& uv) const {
  const Eigen::Vector2d xy_d((uv.x() - cx) / fx, (uv.y() - cy) / fy);
  const auto xy = Undistort(xy_d);
  if (!xy) return std::nullopt;
  return Eigen::Vector3d(xy->x(), xy->y(), 1.0).normalized();
}

bool PinholeRadTan::InImage(const Eigen::Vector2d& uv, double margin) const {
  return uv.x() >= margin && uv.y() >= margin && uv.x() <= width - 1 - margin &&
         uv.y() <= height - 1 - margin;
}

PinholeRadTan EurocCam0() {
  PinholeRadTan c;
  c.width = 752;
  c.height = 480;
  c.fx = 458.654;
  c.fy = 457.296;
  c.cx = 367.215;
  c.cy = 248.375;
  c.k1 = -0.28340811;
  c.k2 = 0.07395907;
  c.p1 = 0.00019359;
  c.p2 = 1.76187114e-05;
  return c;
}

PinholeRadTan EurocCam1() {
  PinholeRadTan c;
  c.width = 752;
  c.height = 480;
  c.fx = 457.587;
  c.fy = 456.134;
  c.cx = 379.999;
  c.cy = 255.238;
  c.k1 = -0.28368365;
  c.k2 = 0.07451284;
  c.p1 = -0.00010473;
  c.p2 = -3.55590700e-05;
  return c;
}

}  // namespace mav::camera
