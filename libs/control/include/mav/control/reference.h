#pragma once
// References the autopilot flies when told to go somewhere without a planned trajectory. From
// rest: the septic rest-to-rest profile s(u) = 35u^4 - 84u^5 + 70u^6 - 20u^7 along the straight
// line (zero speed, acceleration and jerk at both ends, so the body rates start and end near
// zero), as 8 quintic segments matching it to the acceleration at their knots (the
// PolynomialTrajectory layout). Its peak speed is 2.1875 D/T and peak acceleration 7.5132 D/T^2
// (D the distance, T the duration): the duration is the least T that keeps both, and the yaw
// rate (2.1875 |dpsi|/T), inside the limits. From a moving reference: one quintic to rest.

#include <Eigen/Core>

#include "mav/common/status.h"
#include "mav/geometry/polynomial_trajectory.h"

namespace mav::control {

struct GoToLimits {
  double max_speed_mps = 2.0;
  double max_accel_mps2 = 2.0;
  double max_yaw_rate_radps = 1.0;
  double min_duration_s = 0.5;
  bool IsValid(std::string* why) const;
};

// InvalidArgument naming the field for bad limits or a non-finite goal.
Result<geometry::PolynomialTrajectory> MakeGoToTrajectory(const geometry::TrajectoryPoint& from,
                                                          const Eigen::Vector3d& goal,
                                                          double goal_yaw_rad,
                                                          const GoToLimits& limits);

// The duration MakeGoToTrajectory picks for a rest-to-rest move of `distance_m` and `yaw_rad`.
double GoToDuration(double distance_m, double yaw_rad, const GoToLimits& limits);

}  // namespace mav::control
