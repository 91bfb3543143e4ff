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
  // The septic rest-to-rest profile's peaks: speed 35/16 D/T, acceleration 84 sqrt(5)/25 D/T^2.
  return std::max({limits.min_duration_s, 2.1875 * distance_m / limits.max_speed_mps,
                   std::sqrt(7.513188404399293 * distance_m / limits.max_accel_mps2),
                   2.1875 * std::abs(yaw_rad) / limits.max_yaw_rate_radps});
}

namespace {

// Coefficients (ascending) of the quintic with value/rate/acceleration (x0, v0, a0) at 0 and
// (x1, v1, a1) at T.
Eigen::Matrix<double, 6, 1> Quintic(double x0, double v0, double a0, double x1, double v1,
                                    double a1, double T) {
  Eigen::Matrix3d m;
  m << std::pow(T, 3), std::pow(T, 4), std::pow(T, 5), 3 * T * T, 4 * std::pow(T, 3),
      5 * std::pow(T, 4), 6 * T, 12 * T * T, 20 * std::pow(T, 3);
  const Eigen::Vector3d rhs(x1 - x0 - v0 * T - 0.5 * a0 * T * T, v1 - v0 - a0 * T, a1 - a0);
  const Eigen::Vector3d c345 = m.partialPivLu().solve(rhs);
  Eigen::Matrix<double, 6, 1> c;
  c << x0, v0, 0.5 * a0, c345;
  return c;
}

// The septic s(u) = 35u^4 - 84u^5 + 70u^6 - 20u^7 and its first two derivatives: 0 -> 1 with
// zero rate, acceleration and jerk at both ends.
Eigen::Vector3d Septic(double u) {
  const double u2 = u * u, u3 = u2 * u, u4 = u3 * u;
  return {u4 * (35 - 84 * u + 70 * u2 - 20 * u3), u3 * (140 - 420 * u + 420 * u2 - 140 * u3),
          u2 * (420 - 1680 * u + 2100 * u2 - 840 * u3)};
}

constexpr int kSepticSegments = 8;

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
  const Eigen::Vector3d d = goal - from.position;
  const bool at_rest = from.velocity.norm() < 1e-3 && from.acceleration.norm() < 1e-3 &&
                       std::abs(from.yaw_rate_radps) < 1e-3;
  std::vector<geometry::PolynomialSegment> segments;
  if (at_rest) {
    // The septic profile, as quintic segments matching its position, rate and acceleration at
    // kSepticSegments + 1 knots: C2, and the jerk (the body rate) starts and ends near zero
    // instead of jumping as a single rest-to-rest quintic's does.
    const double T = GoToDuration(d.norm(), dyaw, limits);
    const double dt = T / kSepticSegments;
    for (int k = 0; k < kSepticSegments; ++k) {
      const Eigen::Vector3d s0 = Septic(static_cast<double>(k) / kSepticSegments);
      const Eigen::Vector3d s1 = Septic(static_cast<double>(k + 1) / kSepticSegments);
      geometry::PolynomialSegment seg;
      seg.duration_s = dt;
      for (int a = 0; a < 3; ++a) {
        seg.coefficients.row(a) =
            Quintic(from.position[a] + d[a] * s0[0], d[a] * s0[1] / T, d[a] * s0[2] / (T * T),
                    from.position[a] + d[a] * s1[0], d[a] * s1[1] / T, d[a] * s1[2] / (T * T), dt)
                .transpose();
      }
      seg.yaw = Quintic(from.yaw_rad + dyaw * s0[0], dyaw * s0[1] / T, dyaw * s0[2] / (T * T),
                        from.yaw_rad + dyaw * s1[0], dyaw * s1[1] / T, dyaw * s1[2] / (T * T), dt);
      segments.push_back(seg);
    }
  } else {
    // Moving already: one quintic from the current state to rest, with time to brake.
    const double braking_s = from.velocity.norm() / limits.max_accel_mps2;
    const double T = GoToDuration(d.norm(), dyaw, limits) + braking_s;
    geometry::PolynomialSegment seg;
    seg.duration_s = T;
    for (int a = 0; a < 3; ++a) {
      seg.coefficients.row(a) =
          Quintic(from.position[a], from.velocity[a], from.acceleration[a], goal[a], 0, 0, T)
              .transpose();
    }
    seg.yaw = Quintic(from.yaw_rad, from.yaw_rate_radps, 0.0, from.yaw_rad + dyaw, 0, 0, T);
    segments.push_back(seg);
  }
  return geometry::PolynomialTrajectory::Create(std::move(segments), geometry::YawPolicy::kSegment,
                                                from.yaw_rad);
}

}  // namespace mav::control
