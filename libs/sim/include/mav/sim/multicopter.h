#pragma once
// Rigid-body dynamics of a multicopter that can be stepped: Step(rotor_speed_command, dt).
//
// State: position p and velocity v (world), orientation q = R_world_body, body rates w, rotor
// speeds W_i. With thrust f_i = k_f W_i^2 along body z at r_i = L (cos a_i, sin a_i, 0):
//   m dv/dt = R (sum f_i e3 + F_drag) + F_ext - m g e3,
//     F_drag = -sum |W_i| c_d v_perp (RotorS' rotor drag: the body-frame air velocity
//     perpendicular to the rotor axis; still air, wind enters as F_ext),
//   J dw/dt = sum (r_i x f_i e3 - d_i k_m f_i e3) - w x J w,   dq/dt = q (0, w) / 2,
//   dW_i/dt = (W_cmd,i - W_i) / tau,  tau = tau_up when speeding up, tau_down when slowing,
// the command clamped to [0, W_max] (the vehicle's own limit). Integrated with classical RK4
// at max_substep_s (default 1 ms, i.e. >= 1 kHz) inside each Step.
//
// Ground contact: the ground plane z = ground_z. Resting on it (body origin rest_height above),
// the vehicle stays put (v = w = 0, level) until the net vertical force lifts it; an airborne
// vehicle whose origin reaches rest height touches down (a contact the simulation reports) and
// rests again.
//
// The default parameters are the AscTec Firefly of the EuRoC 2014 contest (RotorS' model).

#include <array>
#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace mav::sim {

inline constexpr int kMaxRotors = 8;
using RotorVector = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, kMaxRotors, 1>;

struct MulticopterParams {
  double mass_kg = 1.5;
  Eigen::Vector3d inertia_kgm2 = Eigen::Vector3d(0.0347563, 0.0458929, 0.0977);
  int rotor_count = 6;
  double arm_length_m = 0.215;
  std::array<double, kMaxRotors> rotor_angles_deg = {30, 90, 150, 210, 270, 330, 0, 0};
  std::array<int, kMaxRotors> rotor_directions = {1, -1, 1, -1, 1, -1, 0, 0};  // +1 ccw
  double thrust_constant = 8.54858e-6;                                         // N/(rad/s)^2
  double moment_constant_m = 0.016;            // yaw torque per thrust
  double rotor_drag_coefficient = 8.06428e-5;  // N/(rad/s)/(m/s)
  double motor_time_constant_up_s = 0.0125;
  double motor_time_constant_down_s = 0.025;
  double max_rotor_speed_radps = 838;
  double gravity_mps2 = 9.81;
  double rest_height_m = 0.08;  // body origin above the ground when resting on the legs

  bool IsValid(std::string* why) const;
};

struct MulticopterState {
  Eigen::Vector3d p_world = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_world = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_world_body = Eigen::Quaterniond::Identity();
  Eigen::Vector3d omega_body = Eigen::Vector3d::Zero();
  RotorVector rotor_speeds_radps;
  bool on_ground = false;
};

// A touchdown during the last Step (the vertical speed at contact, m/s, >= 0).
struct GroundContact {
  bool touched_down = false;
  double impact_speed_mps = 0;
};

class Multicopter {
 public:
  // MAV_CHECKs valid params and a substep in (0, 0.01].
  explicit Multicopter(const MulticopterParams& params = MulticopterParams(),
                       double max_substep_s = 0.001);

  // Places the vehicle at rest (rotors stopped). on_ground: resting on ground_z (p.z is then
  // ground_z + rest_height).
  void Reset(const Eigen::Vector3d& p_world, double yaw_rad, bool on_ground, double ground_z);
  // Replaces the whole state (e.g. to start airborne with the rotors at speed); the rotor speeds
  // must have rotor_count entries. The ground stays where Reset put it.
  void SetState(const MulticopterState& state);
  // Advances by dt_s holding the rotor speed command (size rotor_count, rad/s).
  GroundContact Step(const RotorVector& command_radps, double dt_s);
  // External force on the centre of mass (world frame, N), held until changed.
  void SetExternalForce(const Eigen::Vector3d& force_world_n) { external_force_ = force_world_n; }

  const MulticopterState& state() const { return state_; }
  const MulticopterParams& params() const { return params_; }
  // Kinematic acceleration (world, gravity removed) and specific force (what an ideal
  // accelerometer at the body origin reads, body frame) at the current state and command.
  Eigen::Vector3d AccelerationWorld() const;
  Eigen::Vector3d SpecificForceBody() const;
  // Sum of the rotor thrusts (N) and the body torque of the rotors (N m) at the current speeds.
  Eigen::Vector4d RotorWrench() const;

 private:
  void Derivatives(const MulticopterState& x, Eigen::Vector3d* dp, Eigen::Vector3d* dv,
                   Eigen::Vector4d* dq, Eigen::Vector3d* dw, RotorVector* dr) const;
  Eigen::Vector3d BodyForce(const MulticopterState& x) const;  // rotors + drag, body frame

  MulticopterParams params_;
  double max_substep_s_;
  MulticopterState state_;
  RotorVector command_;
  Eigen::Vector3d external_force_ = Eigen::Vector3d::Zero();
  double ground_z_ = 0;
  Eigen::Matrix<double, 3, kMaxRotors> rotor_positions_;
};

}  // namespace mav::sim
