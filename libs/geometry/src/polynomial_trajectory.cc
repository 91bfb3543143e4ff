#include "mav/geometry/polynomial_trajectory.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "mav/common/check.h"

namespace mav::geometry {

double EvaluatePolynomial(const Vector6d& c, double tau, int derivative) {
  MAV_CHECK(derivative >= 0 && derivative <= 5) << "derivative " << derivative;
  // Horner on the differentiated coefficients: d^n/dtau^n tau^k = k!/(k-n)! tau^(k-n).
  double value = 0;
  for (int k = 5; k >= derivative; --k) {
    double factor = 1;
    for (int m = 0; m < derivative; ++m) factor *= (k - m);
    value = value * tau + factor * c[k];
  }
  return value;
}

Result<PolynomialTrajectory> PolynomialTrajectory::Create(std::vector<PolynomialSegment> segments,
                                                          YawPolicy yaw_policy,
                                                          double start_yaw_rad) {
  if (segments.empty()) return Status::InvalidArgument("segments: at least one segment needed");
  if (!std::isfinite(start_yaw_rad)) {
    return Status::InvalidArgument("start_yaw_rad: must be finite");
  }
  PolynomialTrajectory t;
  t.start_times_s_.reserve(segments.size());
  for (size_t i = 0; i < segments.size(); ++i) {
    const PolynomialSegment& s = segments[i];
    const std::string field = "segments[" + std::to_string(i) + "]";
    if (!(s.duration_s > 0) || !std::isfinite(s.duration_s)) {
      return Status::InvalidArgument(field + ".duration_s: must be positive and finite, got " +
                                     std::to_string(s.duration_s));
    }
    if (!s.coefficients.allFinite()) {
      return Status::InvalidArgument(field + ".coefficients: not finite");
    }
    if (yaw_policy == YawPolicy::kSegment && !s.yaw.has_value()) {
      return Status::InvalidArgument(field + ".yaw: the segment yaw policy needs yaw coefficients");
    }
    if (s.yaw.has_value() && !s.yaw->allFinite()) {
      return Status::InvalidArgument(field + ".yaw: not finite");
    }
    t.start_times_s_.push_back(t.duration_s_);
    t.duration_s_ += s.duration_s;
  }
  t.segments_ = std::move(segments);
  t.yaw_policy_ = yaw_policy;
  t.start_yaw_rad_ = start_yaw_rad;
  return t;
}

std::pair<int, double> PolynomialTrajectory::Locate(double t_s) const {
  MAV_CHECK(!segments_.empty()) << "evaluating an empty trajectory";
  const double t = std::clamp(std::isfinite(t_s) ? t_s : 0.0, 0.0, duration_s_);
  // The last segment whose start is <= t.
  const auto it = std::upper_bound(start_times_s_.begin(), start_times_s_.end(), t);
  const int i = std::max(0, static_cast<int>(it - start_times_s_.begin()) - 1);
  const double tau = std::min(t - start_times_s_[i], segments_[i].duration_s);
  return {i, tau};
}

Eigen::Vector3d PolynomialTrajectory::EvaluateDerivative(double t_s, int derivative) const {
  const auto [i, tau] = Locate(t_s);
  const Eigen::Matrix<double, 3, 6>& c = segments_[i].coefficients;
  Eigen::Vector3d out;
  for (int a = 0; a < 3; ++a) out[a] = EvaluatePolynomial(c.row(a).transpose(), tau, derivative);
  return out;
}

TrajectoryPoint PolynomialTrajectory::Evaluate(double t_s) const {
  const auto [i, tau] = Locate(t_s);
  const PolynomialSegment& s = segments_[i];
  TrajectoryPoint p;
  p.t_s = start_times_s_[i] + tau;
  std::array<Eigen::Vector3d*, 5> outs = {&p.position, &p.velocity, &p.acceleration, &p.jerk,
                                          &p.snap};
  for (int n = 0; n < 5; ++n) {
    for (int a = 0; a < 3; ++a) {
      (*outs[n])[a] = EvaluatePolynomial(s.coefficients.row(a).transpose(), tau, n);
    }
  }
  switch (yaw_policy_) {
    case YawPolicy::kConstant:
      p.yaw_rad = start_yaw_rad_;
      break;
    case YawPolicy::kAlongPath: {
      const double speed = p.velocity.head<2>().norm();
      if (speed > kAlongPathMinSpeed) {
        p.yaw_rad = std::atan2(p.velocity.y(), p.velocity.x());
        // d/dt atan2(vy, vx) = (vx ay - vy ax) / (vx^2 + vy^2)
        p.yaw_rate_radps =
            (p.velocity.x() * p.acceleration.y() - p.velocity.y() * p.acceleration.x()) /
            (speed * speed);
      } else {
        p.yaw_rad = start_yaw_rad_;
      }
      break;
    }
    case YawPolicy::kSegment:
      p.yaw_rad = EvaluatePolynomial(*s.yaw, tau, 0);
      p.yaw_rate_radps = EvaluatePolynomial(*s.yaw, tau, 1);
      break;
  }
  return p;
}

std::vector<TrajectoryPoint> PolynomialTrajectory::Sample(double dt_s) const {
  MAV_CHECK(dt_s > 0 && std::isfinite(dt_s)) << "dt_s " << dt_s;
  std::vector<TrajectoryPoint> out;
  const int64_t n = static_cast<int64_t>(std::floor(duration_s_ / dt_s + 1e-9));
  out.reserve(static_cast<size_t>(n + 2));
  for (int64_t k = 0; k <= n; ++k) out.push_back(Evaluate(static_cast<double>(k) * dt_s));
  if (duration_s_ - static_cast<double>(n) * dt_s > 1e-9) out.push_back(Evaluate(duration_s_));
  return out;
}

PolynomialTrajectory PolynomialTrajectory::Translated(const Eigen::Vector3d& offset) const {
  PolynomialTrajectory t = *this;
  for (PolynomialSegment& s : t.segments_) s.coefficients.col(0) += offset;
  return t;
}

}  // namespace mav::geometry
