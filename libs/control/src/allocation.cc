#include "mav/control/allocation.h"

#include <algorithm>
#include <cmath>

#include <Eigen/LU>

#include "mav/common/check.h"

namespace mav::control {

bool AllocationOptions::IsValid(std::string* why) const {
  if (!(min_rotor_speed_radps >= 0 && std::isfinite(min_rotor_speed_radps))) {
    if (why) *why = "min_rotor_speed_radps: must be >= 0";
    return false;
  }
  return true;
}

bool AllocationOptions::FitsVehicle(const VehicleParameters& vehicle, std::string* why) const {
  if (min_rotor_speed_radps >= vehicle.max_rotor_speed_radps) {
    if (why) *why = "min_rotor_speed_radps: must be below vehicle.max_rotor_speed_radps";
    return false;
  }
  return true;
}

Allocator::Allocator(const VehicleParameters& vehicle, const AllocationOptions& options)
    : vehicle_(vehicle), options_(options), mixer_(vehicle.Mixer()) {
  std::string why;
  MAV_CHECK(vehicle.IsValid(&why)) << why;
  MAV_CHECK(options.IsValid(&why)) << why;
  MAV_CHECK(options.min_rotor_speed_radps < vehicle.max_rotor_speed_radps)
      << "min_rotor_speed_radps above the maximum";
  const Eigen::Matrix4d aat = mixer_ * mixer_.transpose();
  pinv_ = mixer_.transpose() * aat.inverse();
  u_min_ = options.min_rotor_speed_radps * options.min_rotor_speed_radps;
  u_max_ = vehicle.max_rotor_speed_radps * vehicle.max_rotor_speed_radps;
  // The thrust the rotors give with no torque (thrust alone spreads evenly over the rotors for a
  // symmetric vehicle: the thrust column of A^+ is uniform).
  thrust_min_ = -1e300;
  thrust_max_ = 1e300;
  for (int i = 0; i < vehicle.rotor_count; ++i) {
    if (pinv_(i, 0) > 0) {
      thrust_min_ = std::max(thrust_min_, u_min_ / pinv_(i, 0));
      thrust_max_ = std::min(thrust_max_, u_max_ / pinv_(i, 0));
    }
  }
  thrust_mid_ = 0.5 * (thrust_min_ + thrust_max_);
}

namespace {

// Largest s >= 0 with lo <= base + s * delta <= hi for every rotor (base must fit; 1e300 for a
// zero delta).
template <typename V>
double MaxScale(const V& base, const V& delta, double lo, double hi) {
  double s = 1e300;
  for (int i = 0; i < base.size(); ++i) {
    if (delta[i] > 1e-12) {
      s = std::min(s, (hi - base[i]) / delta[i]);
    } else if (delta[i] < -1e-12) {
      s = std::min(s, (lo - base[i]) / delta[i]);
    }
  }
  return std::max(s, 0.0);
}

// The same in [0, 1].
template <typename V>
double FeasibleScale(const V& base, const V& delta, double lo, double hi) {
  return std::min(MaxScale(base, delta, lo, hi), 1.0);
}

}  // namespace

double Allocator::MaxRollPitchTorque(double thrust, const Eigen::Vector2d& direction) const {
  const double norm = direction.norm();
  if (!(norm > 0)) return 0;
  // As Allocate: thrust above thrust_mid_ gives way to roll/pitch, so the reach there is the
  // reach at thrust_mid_ (the widest).
  const double t = std::clamp(thrust, thrust_min_,
                              options_.roll_pitch_before_thrust_at_top ? thrust_mid_ : thrust_max_);
  using U = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, kMaxRotors, 1>;
  const U base = pinv_.col(0) * t;
  const U delta = (pinv_.col(1) * direction.x() + pinv_.col(2) * direction.y()) / norm;
  return MaxScale(base, delta, u_min_, u_max_);
}

RotorVector Allocator::Allocate(const Wrench& wrench, AllocationResult* result) const {
  const int n = vehicle_.rotor_count;
  using U = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, kMaxRotors, 1>;
  U u(n);
  AllocationResult info;
  if (options_.saturation == SaturationPolicy::kClip) {
    u = pinv_ * wrench;
    for (int i = 0; i < n; ++i) u[i] = std::clamp(u[i], u_min_, u_max_);
  } else {
    // Clamp the thrust so that it fits with no torque.
    const U u_thrust_unit = pinv_.col(0);
    double thrust = wrench[0];
    if (thrust < thrust_min_ || thrust > thrust_max_) {
      info.thrust_saturated = true;
      thrust = std::clamp(thrust, thrust_min_, thrust_max_);
    }
    const U rp = pinv_.col(1) * wrench[1] + pinv_.col(2) * wrench[2];
    // At the top, roll/pitch before thrust: lower the thrust until the torque fits, but not
    // below the thrust with the widest room (thrust_mid_).
    if (options_.roll_pitch_before_thrust_at_top && thrust > thrust_mid_) {
      double t_top = thrust;
      for (int i = 0; i < n; ++i) {
        if (u_thrust_unit[i] > 0) t_top = std::min(t_top, (u_max_ - rp[i]) / u_thrust_unit[i]);
      }
      if (t_top < thrust) {
        thrust = std::max(t_top, thrust_mid_);
        info.thrust_saturated = true;
      }
    }
    const U base = u_thrust_unit * thrust;
    info.roll_pitch_scale = FeasibleScale(base, rp, u_min_, u_max_);
    const U with_rp = base + info.roll_pitch_scale * rp;
    const U yaw = pinv_.col(3) * wrench[3];
    info.yaw_scale = FeasibleScale(with_rp, yaw, u_min_, u_max_);
    u = with_rp + info.yaw_scale * yaw;
    // Rounding may leave a rotor a hair outside the range.
    for (int i = 0; i < n; ++i) u[i] = std::clamp(u[i], u_min_, u_max_);
  }
  RotorVector speeds(n);
  for (int i = 0; i < n; ++i) speeds[i] = std::sqrt(u[i]);
  if (result) {
    info.achieved = mixer_ * u;
    *result = info;
  }
  return speeds;
}

Wrench Allocator::Mix(const RotorVector& speeds) const {
  MAV_CHECK(speeds.size() == vehicle_.rotor_count) << "got " << speeds.size() << " speeds";
  return mixer_ * speeds.cwiseAbs2();
}

}  // namespace mav::control
