#pragma once
// Synthetic ground truth for the control tests: a smooth 6-DoF motion with exact IMU readings
// (analytic derivatives), and helpers to feed estimators.

#include <cmath>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "mav/control/vehicle.h"
#include "mav/geometry/se3.h"

namespace mav::control::testing {

struct TruthState {
  Eigen::Vector3d p, v, a;
  Eigen::Quaterniond q;
  Eigen::Vector3d omega_body;
};

// Position: sums of sines; orientation: yaw ramp + small roll/pitch oscillations, with the body
// rate from a central difference of the orientation at 1 us (accurate to ~1e-9).
inline TruthState TruthAt(double t) {
  TruthState s;
  s.p = Eigen::Vector3d(0.8 * std::sin(0.7 * t), 0.5 * std::sin(1.1 * t + 0.3),
                        1.0 + 0.2 * std::sin(0.9 * t));
  s.v = Eigen::Vector3d(0.56 * std::cos(0.7 * t), 0.55 * std::cos(1.1 * t + 0.3),
                        0.18 * std::cos(0.9 * t));
  s.a = Eigen::Vector3d(-0.392 * std::sin(0.7 * t), -0.605 * std::sin(1.1 * t + 0.3),
                        -0.162 * std::sin(0.9 * t));
  auto rot = [](double tt) {
    return Eigen::Quaterniond(geometry::RotationFromRollPitchYaw(
        0.1 * std::sin(1.3 * tt), 0.08 * std::sin(0.9 * tt + 1), 0.3 * tt));
  };
  s.q = rot(t);
  const double h = 1e-6;
  s.omega_body = geometry::LogSO3(rot(t - h).conjugate() * rot(t + h)) / (2 * h);
  return s;
}

inline ImuMeasurement ImuAt(int64_t t_ns) {
  const TruthState s = TruthAt(t_ns * 1e-9);
  ImuMeasurement m;
  m.t_ns = t_ns;
  m.gyro = s.omega_body;
  m.accel = s.q.conjugate() * (s.a + Eigen::Vector3d(0, 0, kGravity));
  return m;
}

inline PoseMeasurement PoseAt(int64_t t_ns, const geometry::SE3& T_body_sensor, int source = 0) {
  const TruthState s = TruthAt(t_ns * 1e-9);
  return PoseMeasurement{t_ns, source, geometry::SE3(s.q, s.p) * T_body_sensor};
}

}  // namespace mav::control::testing
