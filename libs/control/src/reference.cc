#include "mav/control/reference.h"

#include <algorithm>
#include <cmath>

#include <Eigen/LU>

namespace mav::control {

bool GoToLimits::IsValid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!(max_speed_mps > 0 && std::isfinite(max_speed_mps))) {
    return fail("max_speed_mps: must be positive");
  }
  if (!(max_accel_mps2 > 0 && std::isfinite(max_accel_mps2))) {
    return fail("max_accel_mps2: must be positive");
  }
  if (!(max_yaw_rate_radps > 0 && std::isfinite(max_yaw_rate_radps))) {
    return fail("max_yaw_rate_radps: must be positive");
  }
  if (!(min_duration_s > 0 && std::isfinite(min_duration_s))) {
    return fail("min_duration_s: must be positive");
  }
  return true;
}

double GoToDuration(double distance_m, double yaw_rad, const GoToLimits& limits) {
  return std::max({limits.min_duration_s, 1.875 * distance_m / limits.max_speed_mps,
                   std::sqrt(5.773502691896258 * distance_m / limits.max_accel_mps2),
                   1.875 * std::abs(yaw_rad) / limits.max_yaw_rate_radps});
}

namespace {

// Coefficients (ascending) of the quintic with value/rate/acceleration (x0, v0, a0) at 0 and
// (x1, 0, 0) at T.
Eigen::Matrix<double, 6, 1> Quintic(double x0, double v0, double a0, double x1, double T) {
  Eigen::Matrix3d m;
  m << std::pow(T, 3), std::pow(T, 4), std::pow(T, 5), 3 * T * T, 4 * std::pow(T, 3),
      5 * std::pow(T, 4), 6 * T, 12 * T * T, 20 * std::pow(T, 3);
  const Eigen::Vector3d rhs(x1 - x0 - v0 * T - 0.5 * a0 * T * T, -v0 - a0 * T, -a0);
  const Eigen::Vector3d c345 = m.partialPivLu().solve(rhs);
  Eigen::Matrix<double, 6, 1> c;
  c << x0, v0, 0.5 * a0, c345;
  return c;
}

}  // namespace

Result<geometry::PolynomialTrajectory> MakeGoToTrajectory(const geometry::TrajectoryPoint& from,
                                                          const Eigen::Vector3d& goal,
                                                          double goal_yaw_rad,
                                                          const GoToLimits& limits) {
  if (std::string why; !limits.IsValid(&why)) return Status::InvalidArgument(why);
  if (!goal.allFinite()) return Status::InvalidArgument("goal: must be finite");
  if (!std::isfinite(goal_yaw_rad)) return Status::InvalidArgument("yaw: must be finite");
  // Turn the short way round.
  const double dyaw = std::remainder(goal_yaw_rad - from.yaw_rad, 2.0 * M_PI);
  // A move that starts with speed needs time to stop: add the time to brake at the limit.
  const double braking_s = from.velocity.norm() / limits.max_accel_mps2;
  const double T = GoToDuration((goal - from.position).norm(), dyaw, limits) + braking_s;
  geometry::PolynomialSegment seg;
  seg.duration_s = T;
  for (int a = 0; a < 3; ++a) {
    seg.coefficients.row(a) =
        Quintic(from.position[a], from.velocity[a], from.acceleration[a], goal[a], T).transpose();
  }
  seg.yaw = Quintic(from.yaw_rad, from.yaw_rate_radps, 0.0, from.yaw_rad + dyaw, T);
  return geometry::PolynomialTrajectory::Create({seg}, geometry::YawPolicy::kSegment, from.yaw_rad);
}

}  // namespace mav::control
