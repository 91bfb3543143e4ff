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
}

namespace {

// Largest s in [0, 1] with lo <= base + s * delta <= hi for every rotor (base must fit).
template <typename V>
double FeasibleScale(const V& base, const V& delta, double lo, double hi) {
  double s = 1.0;
  for (int i = 0; i < base.size(); ++i) {
    if (delta[i] > 1e-12) {
      s = std::min(s, (hi - base[i]) / delta[i]);
    } else if (delta[i] < -1e-12) {
      s = std::min(s, (lo - base[i]) / delta[i]);
    }
  }
  return std::clamp(s, 0.0, 1.0);
}

}  // namespace

RotorVector Allocator::Allocate(const Wrench& wrench, AllocationResult* result) const {
  const int n = vehicle_.rotor_count;
  using U = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, kMaxRotors, 1>;
  U u(n);
  AllocationResult info;
  if (options_.saturation == SaturationPolicy::kClip) {
    u = pinv_ * wrench;
    for (int i = 0; i < n; ++i) u[i] = std::clamp(u[i], u_min_, u_max_);
  } else {
    // Thrust alone spreads evenly over the rotors (the thrust column of A^+ is uniform for a
    // symmetric vehicle); clamp it so that it fits with no torque.
    const U u_thrust_unit = pinv_.col(0);
    double thrust = wrench[0];
    double lo_t = -1e300, hi_t = 1e300;
    for (int i = 0; i < n; ++i) {
      if (u_thrust_unit[i] > 0) {
        lo_t = std::max(lo_t, u_min_ / u_thrust_unit[i]);
        hi_t = std::min(hi_t, u_max_ / u_thrust_unit[i]);
      }
    }
    if (thrust < lo_t || thrust > hi_t) {
      info.thrust_saturated = true;
      thrust = std::clamp(thrust, lo_t, hi_t);
    }
    const U base = u_thrust_unit * thrust;
    const U rp = pinv_.col(1) * wrench[1] + pinv_.col(2) * wrench[2];
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
