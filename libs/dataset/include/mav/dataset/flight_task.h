#pragma once
// The data model of a flight task: the EuRoC 2014 Challenge 3 simulation tasks (t3_1 ... t4_3,
// built in mav/sim/flight_task.h) and any variant of them read from a task file
// (mav/dataset/flight_task_io.h). Plain figures only; the simulator (mav/sim/flight_simulation.h)
// flies them and mav/eval/contest_score.h scores them. Units SI; world frame z up; times in
// seconds from the start of the task (they are task parameters, not data-path stamps).

#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mav/geometry/se3.h"

namespace mav::dataset {

inline constexpr double kForever = std::numeric_limits<double>::infinity();

// A force on the vehicle's centre of mass in the world frame (wind, a gust) over [start, end).
struct ForceWindow {
  Eigen::Vector3d force_world_n = Eigen::Vector3d::Zero();
  double start_s = 0;
  double end_s = kForever;
};

// The contest's IMU: 100 Hz, constant offsets, white noise and a slow drift of the offsets.
struct FlightImuSpec {
  double rate_hz = 100;
  Eigen::Vector3d accel_offset = Eigen::Vector3d(0.2, 0.1, -0.3);      // m/s^2
  Eigen::Vector3d gyro_offset = Eigen::Vector3d(-0.02, 0.008, -0.01);  // rad/s
  double accel_noise_sigma = 0.04;                                     // m/s^2 per sample
  double gyro_noise_sigma = 0.0033937;                                 // rad/s per sample
  // Drift: each offset component is a random walk whose change over drift_horizon_s has this
  // standard deviation (the contest's model: about 0.09 m/s^2 and 6e-4 rad/s over 240 s).
  double accel_drift_sigma = 0.09;
  double gyro_drift_sigma = 6e-4;
  double drift_horizon_s = 240;
};

// A pose sensor (the contest's "virtual vision system"): samples T_world_sensor at rate_hz,
// delivers each sample delay_s late, stamped with its sampling time + stamp_offset_s (a clock
// error the estimator is not told), with white position and orientation noise.
struct FlightPoseSensorSpec {
  double rate_hz = 10;
  double delay_s = 0.1;
  double stamp_offset_s = 0;
  double position_sigma_m = 0.01;        // per axis
  double orientation_sigma_rad = 0.017;  // per axis (rotation vector, sensor frame)
  // Mounting T_body_sensor: translation and roll/pitch/yaw (R = Rz Ry Rx).
  Eigen::Vector3d mount_xyz_m = Eigen::Vector3d(0.03, -0.07, 0.1);
  Eigen::Vector3d mount_rpy_rad = Eigen::Vector3d(0.2, -0.1, 0.3);
  // The sensor delivers samples taken in [active_from_s, active_until_s) only (sensor switching).
  double active_from_s = 0;
  double active_until_s = kForever;

  geometry::SE3 T_body_sensor() const;
};

enum class FlightTaskKind {
  kHover,        // t3_1: hold the set point; RMS window from hover_delay_s after it is published
  kDisturbance,  // t3_2, t3_3: hold it under forces; settle from the first force's onset
  kWaypoints,    // t4_1, t4_2: goals in turn; every goal after the first is settled and scored
  kPlannedLegs,  // t4_3: as kWaypoints, each leg flown on a planned path through the map
};

const char* FlightTaskKindName(FlightTaskKind kind);

// A goal published to the vehicle at publish_s.
struct FlightGoal {
  double publish_s = 0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  double yaw_rad = 0;
};

// How the contest's scripts score a task (docs/control.md, "Scoring").
struct FlightScoring {
  double window_s = 10;           // RMS window length
  double hover_delay_s = 5;       // kHover: the window starts this long after the set point
  double settle_radius_m = 0.1;   // settled: inside this ball ...
  double settle_hold_s = 3;       // ... for this long
  double settle_limit_s = 10;     // must settle within this or scores nothing
  double position_limit_m = 0.2;  // the bands' 100 % of position RMS
  double angular_rate_limit_radps = 0.2;
};

struct FlightTask {
  std::string name;
  FlightTaskKind kind = FlightTaskKind::kHover;
  double duration_s = 30;
  // The vehicle spawns resting on the ground plane at ground_z_m with its body origin at
  // spawn_position (z = ground + the legs' height).
  Eigen::Vector3d spawn_position = Eigen::Vector3d(0, 0, 0.08);
  double spawn_yaw_rad = 0;
  double ground_z_m = 0;
  // Where the vehicle hovers after take-off, before the first goal (kHover/kDisturbance: the
  // set point itself).
  Eigen::Vector3d takeoff_position = Eigen::Vector3d(0, 0, 1);
  std::vector<FlightGoal> goals;
  std::vector<ForceWindow> forces;
  FlightImuSpec imu;
  std::vector<FlightPoseSensorSpec> pose_sensors = std::vector<FlightPoseSensorSpec>(1);
  // OctoMap (.bt) the vehicle may collide with; empty: the ground plane only.
  std::string map_path;
  // Collision sphere around the body origin (arms 0.215 m + rotor radius 0.1 m + margin).
  double vehicle_radius_m = 0.35;
  FlightScoring scoring;

  // InvalidArgument-style message naming the field ("goals[2].publish_s: ...").
  bool IsValid(std::string* why) const;
};

}  // namespace mav::dataset
