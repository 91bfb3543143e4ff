#include "mav/control/vehicle.h"

#include <cmath>

#include <Eigen/LU>

namespace mav::control {

bool VehicleParameters::IsValid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!(mass_kg > 0 && std::isfinite(mass_kg))) return fail("mass_kg: must be positive");
  if (!(inertia_kgm2.array() > 0).all() || !inertia_kgm2.allFinite()) {
    return fail("inertia_kgm2: every diagonal entry must be positive");
  }
  if (rotor_count < 4 || rotor_count > kMaxRotors) return fail("rotor_count: must be in [4, 8]");
  if (!(arm_length_m > 0 && std::isfinite(arm_length_m))) {
    return fail("arm_length_m: must be positive");
  }
  for (int i = 0; i < rotor_count; ++i) {
    if (rotor_directions[i] != 1 && rotor_directions[i] != -1) {
      return fail("rotor_directions[" + std::to_string(i) + "]: must be +1 or -1");
    }
    if (!std::isfinite(rotor_angles_deg[i])) {
      return fail("rotor_angles_deg[" + std::to_string(i) + "]: must be finite");
    }
  }
  if (!(thrust_constant > 0 && std::isfinite(thrust_constant))) {
    return fail("thrust_constant: must be positive");
  }
  if (!(moment_constant_m > 0 && std::isfinite(moment_constant_m))) {
    return fail("moment_constant_m: must be positive");
  }
  if (!(max_rotor_speed_radps > 0 && std::isfinite(max_rotor_speed_radps))) {
    return fail("max_rotor_speed_radps: must be positive");
  }
  if (!(motor_time_constant_up_s >= 0 && motor_time_constant_down_s >= 0)) {
    return fail("motor_time_constant_up_s/down_s: must be >= 0");
  }
  const Eigen::MatrixXd a = Mixer();
  if (Eigen::FullPivLU<Eigen::MatrixXd>(a).rank() < 4) {
    return fail("rotor_angles_deg/rotor_directions: the rotors cannot produce every wrench");
  }
  if (MaxThrust() <= mass_kg * kGravity) return fail("max_rotor_speed_radps: cannot lift mass_kg");
  return true;
}

double VehicleParameters::MaxThrust() const {
  return rotor_count * thrust_constant * max_rotor_speed_radps * max_rotor_speed_radps;
}

Eigen::Matrix<double, 4, Eigen::Dynamic, 0, 4, kMaxRotors> VehicleParameters::Mixer() const {
  Eigen::Matrix<double, 4, Eigen::Dynamic, 0, 4, kMaxRotors> a(4, rotor_count);
  for (int i = 0; i < rotor_count; ++i) {
    const double angle = rotor_angles_deg[i] * M_PI / 180.0;
    a(0, i) = thrust_constant;
    a(1, i) = thrust_constant * arm_length_m * std::sin(angle);
    a(2, i) = -thrust_constant * arm_length_m * std::cos(angle);
    a(3, i) = -rotor_directions[i] * thrust_constant * moment_constant_m;
  }
  return a;
}

}  // namespace mav::control
