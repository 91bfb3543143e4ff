#pragma once
// The flight software's model of the multicopter and the types that cross the control library's
// API. Frames: world z up (gravity -9.81 m/s^2 along z), body = IMU frame (x forward, y left,
// z up along the rotor axes); T_a_b maps points of frame b into frame a; quaternions are
// Hamilton, w first. Time is int64 t_ns (the sensors' clock); seconds only inside the maths.
//
// Rotor i sits at angle rotor_angles_deg[i] from body x on an arm of arm_length_m and pushes
// thrust f_i = thrust_constant * w_i^2 along body z; a rotor turning counter-clockwise seen from
// above (direction +1) exerts the reactive yaw torque -moment_constant_m * f_i. So the body
// wrench [T, tau_x, tau_y, tau_z] = A u, u_i = w_i^2, with column i of A
//   kf * [1, L sin(a_i), -L cos(a_i), -d_i km].

#include <array>
#include <cstdint>
#include <string>

#include <Eigen/Core>

#include "mav/geometry/se3.h"

namespace mav::control {

inline constexpr int kMaxRotors = 8;
inline constexpr double kGravity = 9.81;  // m/s^2, along world -z

// Rotor speeds in rad/s, one per rotor (fixed capacity: no allocation in the control loop).
using RotorVector = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, kMaxRotors, 1>;
// [thrust N, torque x, y, z N m] in the body frame.
using Wrench = Eigen::Vector4d;

// One IMU reading (rad/s and m/s^2 specific force, body frame).
struct ImuMeasurement {
  int64_t t_ns = 0;
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();
};

// One pose of a pose sensor (vision, motion capture): the sensor frame in the world at the
// stamp t_ns (the time it was measured, not when it arrived). `source` indexes
// EstimatorOptions::pose_sources.
struct PoseMeasurement {
  int64_t t_ns = 0;
  int source = 0;
  geometry::SE3 T_world_sensor;
};

struct VehicleParameters {
  // The AscTec Firefly as the EuRoC 2014 contest's controllers modelled it (the simulated
  // vehicle weighs 1.5 kg; the contest told the teams 1.568 kg).
  double mass_kg = 1.568;
  Eigen::Vector3d inertia_kgm2 = Eigen::Vector3d(0.0347563, 0.0458929, 0.0977);  // diagonal
  int rotor_count = 6;
  double arm_length_m = 0.215;
  std::array<double, kMaxRotors> rotor_angles_deg = {30, 90, 150, 210, 270, 330, 0, 0};
  // +1 counter-clockwise seen from above, -1 clockwise.
  std::array<int, kMaxRotors> rotor_directions = {1, -1, 1, -1, 1, -1, 0, 0};
  double thrust_constant = 8.54858e-6;  // N/(rad/s)^2
  double moment_constant_m = 0.016;     // yaw torque per thrust
  double max_rotor_speed_radps = 838;
  // First-order motor lag (the autopilot's model of the thrust actually produced).
  double motor_time_constant_up_s = 0.0125;
  double motor_time_constant_down_s = 0.025;

  bool IsValid(std::string* why) const;
  // Thrust of all rotors at full speed, N.
  double MaxThrust() const;
  // The 4 x rotor_count mixer A above.
  Eigen::Matrix<double, 4, Eigen::Dynamic, 0, 4, kMaxRotors> Mixer() const;
};

}  // namespace mav::control
