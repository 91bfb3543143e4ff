#include "mav/geometry/se3.h"

#include <Eigen/SVD>
#include <cmath>

namespace mav::geometry {

Eigen::Matrix3d Hat(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

Eigen::Vector3d Vee(const Eigen::Matrix3d& m) { return {m(2, 1), m(0, 2), m(1, 0)}; }

Eigen::Quaterniond ExpSO3(const Eigen::Vector3d& phi) {
  const double theta_sq = phi.squaredNorm();
  double real, imag_factor;
  if (theta_sq < 1e-16) {
    // Taylor series keeps the result accurate (and differentiable) at zero.
    real = 1.0 - theta_sq / 8.0;
    imag_factor = 0.5 - theta_sq / 48.0;
  } else {
    const double theta = std::sqrt(theta_sq);
    real = std::cos(0.5 * theta);
    imag_factor = std::sin(0.5 * theta) / theta;
  }
  return Eigen::Quaterniond(real, imag_factor * phi.x(), imag_factor * phi.y(),
                            imag_factor * phi.z())
      .normalized();
}

Eigen::Vector3d LogSO3(const Eigen::Quaterniond& q_in) {
  Eigen::Quaterniond q = q_in.normalized();
  if (q.w() < 0) q.coeffs() = -q.coeffs();  // pick the angle in [0, pi]
  const Eigen::Vector3d imag = q.vec();
  const double sin_half = imag.norm();
  if (sin_half < 1e-10) {
    // theta/sin(theta/2) -> 2 / w for small angles.
    return 2.0 / q.w() * imag;
  }
  const double theta = 2.0 * std::atan2(sin_half, q.w());
  return theta / sin_half * imag;
}

Eigen::Matrix3d LeftJacobianSO3(const Eigen::Vector3d& phi) {
  const double theta = phi.norm();
  const Eigen::Matrix3d hat = Hat(phi);
  if (theta < 1e-6) return Eigen::Matrix3d::Identity() + 0.5 * hat + hat * hat / 6.0;
  const double t2 = theta * theta;
  return Eigen::Matrix3d::Identity() + (1.0 - std::cos(theta)) / t2 * hat +
         (theta - std::sin(theta)) / (t2 * theta) * hat * hat;
}

double AngleBetween(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return LogSO3(a.conjugate() * b).norm();
}

SE3::SE3(const Eigen::Matrix3d& r, const Eigen::Vector3d& t)
    : q_(Eigen::Quaterniond(r).normalized()), t_(t) {}

SE3 SE3::FromMatrix(const Eigen::Matrix4d& m) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(m.topLeftCorner<3, 3>(),
                                              Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d r = svd.matrixU() * svd.matrixV().transpose();
  if (r.determinant() < 0) {
    Eigen::Matrix3d u = svd.matrixU();
    u.col(2) *= -1.0;
    r = u * svd.matrixV().transpose();
  }
  return SE3(r, m.topRightCorner<3, 1>());
}

SE3 SE3::Exp(const Vector6d& xi) {
  const Eigen::Vector3d rho = xi.head<3>();
  const Eigen::Vector3d phi = xi.tail<3>();
  return SE3(ExpSO3(phi), LeftJacobianSO3(phi) * rho);
}

Vector6d SE3::Log() const {
  const Eigen::Vector3d phi = LogSO3(q_);
  Vector6d xi;
  xi.head<3>() = LeftJacobianSO3(phi).inverse() * t_;
  xi.tail<3>() = phi;
  return xi;
}

SE3 SE3::Inverse() const {
  const Eigen::Quaterniond q_inv = q_.conjugate();
  return SE3(q_inv, -(q_inv * t_));
}

SE3 SE3::operator*(const SE3& other) const { return SE3(q_ * other.q_, q_ * other.t_ + t_); }

Eigen::Matrix4d SE3::Matrix() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = RotationMatrix();
  m.topRightCorner<3, 1>() = t_;
  return m;
}

Eigen::Matrix<double, 3, 4> SE3::Matrix3x4() const { return Matrix().topRows<3>(); }

bool SE3::IsApprox(const SE3& other, double tol) const {
  return (t_ - other.t_).norm() <= tol && AngleBetween(q_, other.q_) <= tol;
}

SE3 InterpolatePose(const SE3& a, const SE3& b, double alpha) {
  return SE3(a.Rotation().slerp(alpha, b.Rotation()),
             (1.0 - alpha) * a.Translation() + alpha * b.Translation());
}

Eigen::Matrix3d RotationFromRollPitchYaw(double roll, double pitch, double yaw) {
  return (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

SE3 BodyPoseFromSensorPose(const SE3& T_world_sensor, const SE3& T_body_sensor) {
  return T_world_sensor * T_body_sensor.Inverse();
}

SE3 BodyPoseFromSensorOdometry(const SE3& T_world_body0, const SE3& T_body_sensor,
                               const SE3& T_sensor0_sensork) {
  return T_world_body0 * T_body_sensor * T_sensor0_sensork * T_body_sensor.Inverse();
}

}  // namespace mav::geometry
