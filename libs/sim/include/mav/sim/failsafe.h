#pragma once
// The simulated vehicle's own failsafe: what a real flight controller does when the commands from
// its companion computer stop (PX4's offboard-loss "land", ArduPilot's GCS failsafe): instead of
// stopping the motors it holds the attitude level, damps the yaw rate, descends at a safe rate and
// stops the motors once on the ground. It lives in the vehicle (mav-simulator's flight loop calls
// it when the actuator commands go stale), below the DDS link, because that is where a real one
// runs: on the flight controller, with its own sensors, so it works whatever died above it (the
// controller process, its host, the link).
//
//   DescentFailsafe failsafe = *DescentFailsafe::Create(vehicle_params);
//   RotorVector w = failsafe.Command(vehicle.state());
//
// Control law (per physics step; the flight controller's attitude and vertical speed are taken
// from the vehicle's true state, standing in for its IMU attitude filter and baro fusion):
//   thrust  T = m (g + k_v (-descent - v_z)) / max(cos(tilt), 0.5), bounded to [0.2, 1.5] m g
//   torque  tau = J (k_p e_level - k_d omega) + omega x J omega,  e_level = R^T (b3 x e3)
//   rotors  the least-squares thrusts of [T, tau] over the rotor geometry (the vehicle's own
//           allocation), each clamped to [0, k_f W_max^2], W = sqrt(f / k_f)
// On the ground (MulticopterState::on_ground: resting on its legs) the motors stop.

#include <string>

#include <Eigen/Core>

#include "mav/common/status.h"
#include "mav/sim/multicopter.h"

namespace mav::sim {

struct FailsafeOptions {
  // Vertical speed held on the way down, (0, 3]: below FlightSimulationOptions'
  // landing_speed_mps (0.5), so that its touchdown is a landing, not a collision.
  double descent_mps = 0.4;
  double climb_gain_per_s = 2.0;       // k_v: vertical-speed error -> acceleration, > 0
  double attitude_gain_per_s2 = 25.0;  // k_p: tilt error (rad) -> angular acceleration, > 0
  double rate_gain_per_s = 8.0;        // k_d: body rates -> angular deceleration, > 0

  // InvalidArgument-style message naming the field.
  bool IsValid(std::string* why) const;
};

class DescentFailsafe {
 public:
  // InvalidArgument naming the field for bad options or vehicle parameters.
  static Result<DescentFailsafe> Create(const MulticopterParams& vehicle,
                                        const FailsafeOptions& options = {});

  // The rotor speeds for the vehicle in `state`; zero on the ground.
  RotorVector Command(const MulticopterState& state) const;

  const FailsafeOptions& options() const { return options_; }

 private:
  DescentFailsafe(const MulticopterParams& vehicle, const FailsafeOptions& options);

  MulticopterParams vehicle_;
  FailsafeOptions options_;
  // Rotor thrusts from [T, tau_x, tau_y, tau_z]: the pseudo-inverse of the allocation matrix.
  Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::ColMajor, kMaxRotors, 4> thrusts_from_wrench_;
};

}  // namespace mav::sim
