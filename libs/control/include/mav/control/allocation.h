#pragma once
// Control allocation: the body wrench [T, tau] a controller asks for -> rotor speeds.
//
// Unconstrained, u = A^+ w (u_i = w_i^2, A the mixer of vehicle.h, A^+ its Moore-Penrose
// pseudo-inverse: the least-squares rotor effort). The rotors can only deliver u_i in
// [u_min, u_max], so when the request is out of reach the allocator gives up in a fixed order
// of priorities:
//   1. thrust (clamped to what the rotors can give with no torque at all), except that above the
//      thrust with the widest torque room (half the rotors' range) the thrust gives way to
//      roll/pitch: it is lowered until the roll/pitch torque fits, at most down to that thrust
//      (AllocationOptions::roll_pitch_before_thrust_at_top; as PX4's mixer does),
//   2. roll/pitch torque (scaled down, keeping its direction, until it fits beside the thrust),
//   3. yaw torque last (scaled into what is left),
// since the vehicle stays upright without yaw authority but not without roll/pitch: at full
// thrust (all rotors at their maximum) strict thrust priority leaves no roll/pitch torque at all,
// which is how a vehicle tilted beyond ~65 deg (the thrust command m (a_z + g) / cos(tilt) then
// saturates) flips instead of righting itself.
// kClip reproduces the plain behaviour of RotorS' controllers (u = A^+ w, then each rotor is
// clamped on its own), used for the Lee peer so that it flies as it does there.

#include <string>

#include "mav/control/vehicle.h"

namespace mav::control {

enum class SaturationPolicy {
  kPrioritized,  // thrust, then roll/pitch, then yaw (above)
  kClip,         // clamp each rotor independently (RotorS)
};

struct AllocationOptions {
  SaturationPolicy saturation = SaturationPolicy::kPrioritized;
  // Lowest commanded rotor speed while armed (rad/s): keeps the motors spinning (and so able to
  // respond) when the controller asks for very little thrust. 0 = none.
  double min_rotor_speed_radps = 0;
  // kPrioritized: above the thrust with the widest torque room, lower the thrust (down to it)
  // before scaling roll/pitch. false = strict thrust priority.
  bool roll_pitch_before_thrust_at_top = true;

  bool IsValid(std::string* why) const;
  // Whether the options fit `vehicle` (the minimum rotor speed below its maximum); `why` names
  // the field ("min_rotor_speed_radps: ...").
  bool FitsVehicle(const VehicleParameters& vehicle, std::string* why) const;
};

// What the allocation did.
struct AllocationResult {
  Wrench achieved = Wrench::Zero();  // the wrench of the returned speeds
  bool thrust_saturated = false;
  double roll_pitch_scale = 1;  // fraction of the requested roll/pitch torque kept
  double yaw_scale = 1;         // fraction of the requested yaw torque kept
};

class Allocator {
 public:
  Allocator(const VehicleParameters& vehicle, const AllocationOptions& options);

  // Rotor speeds (rad/s, in [min, max]) for a requested body wrench.
  RotorVector Allocate(const Wrench& wrench, AllocationResult* result = nullptr) const;
  // The largest roll/pitch torque (N m) along the body direction `direction` (tau_x, tau_y;
  // normalised here) that Allocate delivers in full beside `thrust` with no yaw torque (the
  // thrust clamped as Allocate clamps it, and lowered as it lowers it at the top). 0 for a zero
  // direction.
  double MaxRollPitchTorque(double thrust, const Eigen::Vector2d& direction) const;
  // The forward model: the wrench the rotors exert at `speeds` (rad/s).
  Wrench Mix(const RotorVector& speeds) const;

  const VehicleParameters& vehicle() const { return vehicle_; }

 private:
  VehicleParameters vehicle_;
  AllocationOptions options_;
  Eigen::Matrix<double, 4, Eigen::Dynamic, 0, 4, kMaxRotors> mixer_;
  Eigen::Matrix<double, Eigen::Dynamic, 4, 0, kMaxRotors, 4> pinv_;
  double u_min_ = 0, u_max_ = 0;
  double thrust_min_ = 0, thrust_max_ = 0;  // N, reachable with no torque
  double thrust_mid_ = 0;                   // N, the thrust with the widest torque room
};

}  // namespace mav::control
