#pragma once
// The sensor data model shared by the simulator, the data-set readers/writers and the services.
// Units: SI (m, s, rad). Frames: "world" is gravity-aligned with z up (EuRoC's Vicon/Leica frame),
// "body" is the IMU frame (EuRoC's B = imu0 frame, identity T_BS for imu0).

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mav/geometry/se3.h"

namespace mav::dataset {

// One IMU reading, as in mav0/imu0/data.csv (gyro first, then accelerometer).
struct ImuSample {
  int64_t t_ns = 0;
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();   // rad/s, body frame
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();  // m/s^2, specific force in the body frame
};

// One row of mav0/state_groundtruth_estimate0/data.csv (17 columns).
struct GroundTruthState {
  int64_t t_ns = 0;
  geometry::SE3 T_world_body;
  Eigen::Vector3d v_world = Eigen::Vector3d::Zero();     // m/s
  Eigen::Vector3d gyro_bias = Eigen::Vector3d::Zero();   // rad/s
  Eigen::Vector3d accel_bias = Eigen::Vector3d::Zero();  // m/s^2
};

// A pose with a time stamp (TUM trajectory rows).
struct StampedPose {
  int64_t t_ns = 0;
  geometry::SE3 T_world_body;
};

// Continuous-time noise figures of an IMU, as in EuRoC's imu0/sensor.yaml.
struct ImuNoise {
  double gyroscope_noise_density = 1.6968e-04;     // rad/s/sqrt(Hz)
  double gyroscope_random_walk = 1.9393e-05;       // rad/s^2/sqrt(Hz)
  double accelerometer_noise_density = 2.0000e-3;  // m/s^2/sqrt(Hz)
  double accelerometer_random_walk = 3.0000e-3;    // m/s^3/sqrt(Hz)
};

}  // namespace mav::dataset
