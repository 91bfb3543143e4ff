#pragma once
// The estimator's correction weights, computed a priori as the gains of a Kalman filter for the
// configured noise (Holzmann et al. 2015, Sec. 3: "the corresponding weights are established a
// priori as the steady-state solution of an Extended Kalman Filter simulation").
//
// Model (per world axis, linearised at hover, the axes and the translational / rotational parts
// decoupled: the coupling of tilt errors into horizontal acceleration is neglected):
//   translation  x = [p, v, b_a]:  p+ = p + h v,  v+ = v + h (a_meas - b_a) + h n_a,
//                b_a+ = b_a + sqrt(h) w_a;                             measured: p (sigma_p)
//   rotation     x = [theta, b_g]: theta+ = theta + h (w_meas - b_g) + h n_g,
//                b_g+ = b_g + sqrt(h) w_g;                             measured: theta (sigma_q)
// with h the IMU period, n_a, n_g the IMU white noise (sigma per sample) and w_a, w_g the
// offsets' random-walk densities. Pose sources update at their own rates; the covariance is
// iterated through the periodic schedule (IMU steps, updates at each source's sample times) —
// the discrete Riccati recursion — until the gains repeat to 1e-12 from one period of the
// schedule to the next. A source's steady-state weights are the mean of its gains over one
// period (they are all equal with a single source). Starting from the initial covariance, the
// gains of the first updates form the transient schedule, so that the offsets are learnt in
// seconds rather than in the minutes the steady state would take. The pose delay does not enter:
// the estimator merges each pose at its stamp and re-applies the IMU, which is the on-time filter.

#include <string>
#include <vector>

#include "mav/common/status.h"

namespace mav::control {

// Gains applied to one pose residual: p += position * r_p, v += velocity * r_p,
// b_a(world) += accel_offset * r_p, q = q Exp(orientation * r_q), b_g += gyro_offset * r_q.
struct CorrectionWeights {
  double position = 0;      // dimensionless
  double velocity = 0;      // 1/s
  double accel_offset = 0;  // 1/s^2 (negative: an offset makes the estimate run ahead)
  double orientation = 0;   // dimensionless: the fraction of the relative rotation applied
  double gyro_offset = 0;   // 1/s
};

struct PoseSourceNoise {
  double rate_hz = 10;
  double position_sigma_m = 0.01;
  double orientation_sigma_rad = 0.017;
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
  std::vector<PoseSourceNoise> sources{PoseSourceNoise{}};

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
