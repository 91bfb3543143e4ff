#pragma once
// The estimator's correction weights, computed a priori as the gains of a Kalman filter for the
// configured noise (Holzmann et al. 2015, Sec. 3: "the corresponding weights are established a
// priori as the steady-state solution of an Extended Kalman Filter simulation").
//
// Model: the error dynamics of the EKF linearised at hover, per world axis (h the IMU period,
// n_a, n_g the IMU white noise per sample, w_a, w_g the offsets' random-walk densities):
//   horizontal (x with the tilt theta = theta_y, y with theta = -theta_x), x = [p, v, b_a, theta,
//   b_g]:  p+ = p + h v,  v+ = v + h (g theta - b_a) + h n_a,  b_a+ = b_a + sqrt(h) w_a,
//          theta+ = theta - h b_g + h n_g,  b_g+ = b_g + sqrt(h) w_g;   measured p and theta;
//   vertical x = [p, v, b_a] (no tilt term);   measured p;
//   heading  x = [psi, b_g];                    measured psi.
// The tilt term is what couples position and orientation at hover: an orientation error tilts
// the integrated specific force by g theta, so the position residuals also correct the tilt and
// vice versa (the decoupled filter, with that coupling dropped, estimates the horizontal velocity
// half as well). Pose sources update at their own rates; the covariance is iterated through the
// periodic schedule (IMU steps, updates at each source's sample times) - the discrete Riccati
// recursion - until the gains repeat to 1e-12 from one period of the schedule to the next. A
// source's steady-state weights are the mean of its gains over one period (all equal with a
// single source). From the initial covariance on, the gains of the first updates form the
// transient schedule, so the offsets are learnt in seconds rather than in minutes. The pose delay
// does not enter: merging each pose at its stamp and re-applying the IMU is the on-time filter.

#include <string>
#include <vector>

#include <Eigen/Core>

#include "mav/common/status.h"

namespace mav::control {

// Gains applied to one pose residual (world frame: r_p position, r_t rotation vector):
//   per horizontal axis [dp, dv, db_a, dtheta, db_g] = horizontal * [r_p, r_theta],
//   vertically [dp, dv, db_a] = vertical * r_p.z,  [dpsi, db_g] = heading * r_t.z.
struct CorrectionWeights {
  Eigen::Matrix<double, 5, 2> horizontal = Eigen::Matrix<double, 5, 2>::Zero();
  Eigen::Vector3d vertical = Eigen::Vector3d::Zero();
  Eigen::Vector2d heading = Eigen::Vector2d::Zero();

  // The paper's decoupled form: one weight per state, the same on every axis (fractions of the
  // residual for position and orientation; 1/s, 1/s^2 for the rates and offsets).
  static CorrectionWeights Decoupled(double position, double velocity, double accel_offset,
                                     double orientation, double gyro_offset);
  double position() const { return vertical[0]; }
  double orientation() const { return heading[0]; }
};

struct PoseSourceNoise {
  double rate_hz = 10;
  double position_sigma_m = 0.01;
  double orientation_sigma_rad = 0.017;
  // The tilt part (roll, pitch) of the orientation's noise; 0 = orientation_sigma_rad. A source
  // whose tilt drifts (a VO) gets a large one, so the tilt comes from gravity: the IMU's specific
  // force against the positions.
  double tilt_sigma_rad = 0;
  double TiltSigma() const { return tilt_sigma_rad > 0 ? tilt_sigma_rad : orientation_sigma_rad; }
};

struct WeightModel {
  double imu_rate_hz = 100;
  double accel_noise_sigma = 0.04;           // m/s^2 per sample
  double gyro_noise_sigma = 0.0033937;       // rad/s per sample
  double accel_offset_random_walk = 5.8e-3;  // m/s^2/sqrt(s)
  double gyro_offset_random_walk = 3.9e-5;   // rad/s/sqrt(s)
  // Initial standard deviations (the transient schedule): velocity and offsets are unknown at
  // the first pose, which initialises position and orientation.
  double initial_velocity_sigma = 0.2;      // m/s
  double initial_accel_offset_sigma = 0.5;  // m/s^2
  double initial_gyro_offset_sigma = 0.05;  // rad/s
  // false: the paper's decoupled weights (translation and orientation filtered apart).
  bool couple_tilt = true;
  // For this long after initialisation a source's tilt is weighted with its
  // orientation_sigma_rad, whatever its tilt_sigma_rad: a source that starts at a known pose (a
  // VO seeded with the true one) is right about the tilt then, and the accelerometer's offsets
  // are learnt against it. Without a turn in yaw the offsets and the tilt cannot be told apart
  // later on: gravity's tilt is only as good as the offsets learnt here.
  double trust_tilt_s = 0;
  std::vector<PoseSourceNoise> pose_sources = std::vector<PoseSourceNoise>(1);

  bool IsValid(std::string* why) const;
};

struct WeightSchedule {
  // steady[s]: the steady-state weights of source s.
  std::vector<CorrectionWeights> steady;
  // transient[s][k]: the weights of source s's (k+1)-th update after initialisation; after the
  // last entry the steady ones apply.
  std::vector<std::vector<CorrectionWeights>> transient;
  int iterations = 0;  // schedule periods iterated until convergence
};

// InvalidArgument naming the field for a bad model. Cost: a few ms (small matrices).
Result<WeightSchedule> ComputeWeightSchedule(const WeightModel& model);

}  // namespace mav::control
