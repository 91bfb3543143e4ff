#pragma once
// Rigid-body transforms on Eigen. Naming follows the frames: `T_world_body` maps points given in
// the body frame into the world frame (p_world = T_world_body * p_body), so transforms chain as
// T_a_c = T_a_b * T_b_c.
//
// Tangent vectors are ordered (translation part rho, rotation part phi) and use the right-handed,
// active convention: Exp(xi) = [[Exp(phi), J(phi) rho], [0, 1]] (Barfoot, "State Estimation for
// Robotics", 2017, Sec. 7.1).

#include <cmath>
#include <limits>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace mav::geometry {

using Vector6d = Eigen::Matrix<double, 6, 1>;

// Skew-symmetric matrix: Hat(a) * b == a.cross(b).
Eigen::Matrix3d Hat(const Eigen::Vector3d& v);
// Inverse of Hat for a skew-symmetric matrix.
Eigen::Vector3d Vee(const Eigen::Matrix3d& m);

// Rotation by angle |phi| about phi/|phi| (Rodrigues); exact near zero.
Eigen::Quaterniond ExpSO3(const Eigen::Vector3d& phi);
// Rotation vector with angle in [0, pi].
Eigen::Vector3d LogSO3(const Eigen::Quaterniond& q);
// Left Jacobian of SO(3): J(phi) with Exp(phi + d) ~= Exp(J(phi) d) Exp(phi).
Eigen::Matrix3d LeftJacobianSO3(const Eigen::Vector3d& phi);
// Angle in radians of the rotation a^-1 * b.
double AngleBetween(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b);

class SE3 {
 public:
  SE3() : q_(Eigen::Quaterniond::Identity()), t_(Eigen::Vector3d::Zero()) {}
  // `q` is normalised here, so callers may pass a slightly denormalised quaternion. A quaternion
  // that is already unit to rounding (|q|^2 within 4 ulp of 1) is kept bit for bit, so poses read
  // from files round-trip exactly.
  SE3(const Eigen::Quaterniond& q, const Eigen::Vector3d& t) : q_(NormalizedIfNeeded(q)), t_(t) {}
  SE3(const Eigen::Matrix3d& r, const Eigen::Vector3d& t);

  static SE3 Identity() { return SE3(); }
  // From a homogeneous 4x4 matrix; the rotation block is projected onto SO(3).
  static SE3 FromMatrix(const Eigen::Matrix4d& m);
  static SE3 Exp(const Vector6d& xi);
  Vector6d Log() const;

  SE3 Inverse() const;
  SE3 operator*(const SE3& other) const;
  Eigen::Vector3d operator*(const Eigen::Vector3d& p) const { return q_ * p + t_; }

  const Eigen::Quaterniond& Rotation() const { return q_; }
  Eigen::Matrix3d RotationMatrix() const { return q_.toRotationMatrix(); }
  const Eigen::Vector3d& Translation() const { return t_; }
  Eigen::Matrix4d Matrix() const;
  // The 3x4 block [R | t].
  Eigen::Matrix<double, 3, 4> Matrix3x4() const;

  bool IsApprox(const SE3& other, double tol = 1e-9) const;

 private:
  static Eigen::Quaterniond NormalizedIfNeeded(const Eigen::Quaterniond& q) {
    const double n2 = q.squaredNorm();
    return std::abs(n2 - 1.0) <= 4.0 * std::numeric_limits<double>::epsilon() ? q : q.normalized();
  }

  Eigen::Quaterniond q_;
  Eigen::Vector3d t_;
};

// Pose at fraction alpha in [0, 1] between a and b: rotation by slerp, translation linear.
// This is the interpolation ground-truth files assume between samples.
SE3 InterpolatePose(const SE3& a, const SE3& b, double alpha);

// Frames of a sensor rigidly mounted on a body at T_body_sensor.
//
// A pose measured for the sensor, as the pose of the body: T_world_body = T_world_sensor *
// T_body_sensor^-1 (a localization pose of cam0, a motion-capture marker, a pose sensor).
SE3 BodyPoseFromSensorPose(const SE3& T_world_sensor, const SE3& T_body_sensor);
// The sensor's odometry T_sensor0_sensork (its first pose is its origin) as the body's pose in a
// world where the body started at T_world_body0: the motion conjugated into the body frame,
//   T_world_body(k) = T_world_body0 * T_body_sensor * T_sensor0_sensork * T_body_sensor^-1.
SE3 BodyPoseFromSensorOdometry(const SE3& T_world_body0, const SE3& T_body_sensor,
                               const SE3& T_sensor0_sensork);

// Rotation from roll (about x), pitch (about y), yaw (about z) applied as R = Rz * Ry * Rx.
Eigen::Matrix3d RotationFromRollPitchYaw(double roll, double pitch, double yaw);

}  // namespace mav::geometry
