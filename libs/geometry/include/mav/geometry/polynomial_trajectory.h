#pragma once
// A piecewise-polynomial trajectory in the world frame: the planner's output (a quintic spline
// through timed path points, Richter et al., "Polynomial Trajectory Planning for Aggressive
// Quadrotor Flight in Dense Indoor Environments", ISRR 2013) and the controller's reference
// (position to snap, for the feed-forward of a differentially flat multicopter).
//
// Segment i covers global time [T_i, T_i + duration_i), T_i = sum of the earlier durations; in
// local time tau = t - T_i in [0, duration_i] each axis is
//   p(tau) = sum_{k=0..5} c_k tau^k   (coefficients in ascending powers, SI units),
// the layout of mav.v1.PolynomialSegment. Continuity across joints is the producer's promise
// (the planner's splines are C4); Evaluate() does not smooth anything.
//
// Yaw: kConstant keeps start_yaw_rad; kAlongPath faces the horizontal velocity when it exceeds
// kAlongPathMinSpeed (start_yaw_rad below it); kSegment evaluates each segment's own yaw
// polynomial (every segment must then carry one).

#include <array>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mav/common/status.h"

namespace mav::geometry {

using Vector6d = Eigen::Matrix<double, 6, 1>;

struct PolynomialSegment {
  double duration_s = 0;
  // Row a = axis (x, y, z), column k = coefficient of tau^k.
  Eigen::Matrix<double, 3, 6> coefficients = Eigen::Matrix<double, 3, 6>::Zero();
  std::optional<Vector6d> yaw;  // coefficients of the yaw polynomial (rad), kSegment only
};

enum class YawPolicy { kConstant, kAlongPath, kSegment };

// The reference at one time. Derivatives of position up to snap (the 4th).
struct TrajectoryPoint {
  double t_s = 0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
  Eigen::Vector3d acceleration = Eigen::Vector3d::Zero();
  Eigen::Vector3d jerk = Eigen::Vector3d::Zero();
  Eigen::Vector3d snap = Eigen::Vector3d::Zero();
  double yaw_rad = 0;
  double yaw_rate_radps = 0;
};

class PolynomialTrajectory {
 public:
  static constexpr double kAlongPathMinSpeed = 0.2;  // m/s

  PolynomialTrajectory() = default;  // empty: duration 0, Evaluate() is a bug

  // InvalidArgument naming the field ("segments[3].duration_s: ...") for: no segments, a
  // duration that is not positive and finite, a non-finite coefficient, kSegment with a
  // segment lacking yaw coefficients, a non-finite start yaw.
  static Result<PolynomialTrajectory> Create(std::vector<PolynomialSegment> segments,
                                             YawPolicy yaw_policy = YawPolicy::kConstant,
                                             double start_yaw_rad = 0);

  bool empty() const { return segments_.empty(); }
  double duration_s() const { return duration_s_; }
  const std::vector<PolynomialSegment>& segments() const { return segments_; }
  YawPolicy yaw_policy() const { return yaw_policy_; }
  double start_yaw_rad() const { return start_yaw_rad_; }

  // The reference at t_s, clamped into [0, duration_s()]: before the start the start point,
  // after the end the end point (with the end's derivatives, zero for a rest-to-rest spline).
  TrajectoryPoint Evaluate(double t_s) const;
  // The `derivative`-th derivative (0..5) of the position at t_s (clamped as Evaluate()).
  Eigen::Vector3d EvaluateDerivative(double t_s, int derivative) const;

  // Samples every dt_s from 0 to the end (the end always included). MAV_CHECKs dt_s > 0.
  std::vector<TrajectoryPoint> Sample(double dt_s) const;

  // A copy with `offset` added to every position.
  PolynomialTrajectory Translated(const Eigen::Vector3d& offset) const;

 private:
  // Segment index and local time for a global time (clamped).
  std::pair<int, double> Locate(double t_s) const;

  std::vector<PolynomialSegment> segments_;
  std::vector<double> start_times_s_;
  double duration_s_ = 0;
  YawPolicy yaw_policy_ = YawPolicy::kConstant;
  double start_yaw_rad_ = 0;
};

// d^n/dtau^n of sum_k c_k tau^k at tau, for n = 0..5.
double EvaluatePolynomial(const Vector6d& c, double tau, int derivative);

}  // namespace mav::geometry
