#pragma once
// References the autopilot flies when told to go somewhere without a planned trajectory: one
// quintic segment per axis from the current reference (position, velocity, acceleration, yaw,
// yaw rate) to rest at the goal. A rest-to-rest quintic reaches its peak speed 1.875 D/T and
// peak acceleration 5.7735 D/T^2 (D the distance, T the duration), so the duration is the least
// T that keeps both, and the yaw rate (1.875 |dpsi|/T), inside the limits.

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
