#include "mav/sim/multicopter.h"

#include <algorithm>
#include <cmath>

#include "mav/common/check.h"

namespace mav::sim {

bool MulticopterParams::IsValid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  auto positive = [](double x) { return x > 0 && std::isfinite(x); };
  if (!positive(mass_kg)) return fail("mass_kg: must be positive");
  if (!(inertia_kgm2.array() > 0).all() || !inertia_kgm2.allFinite()) {
    return fail("inertia_kgm2: must be positive");
  }
  if (rotor_count < 1 || rotor_count > kMaxRotors) return fail("rotor_count: must be in [1, 8]");
  if (!positive(arm_length_m)) return fail("arm_length_m: must be positive");
  for (int i = 0; i < rotor_count; ++i) {
    if (rotor_directions[i] != 1 && rotor_directions[i] != -1) {
      return fail("rotor_directions[" + std::to_string(i) + "]: must be +1 or -1");
    }
  }
  if (!positive(thrust_constant)) return fail("thrust_constant: must be positive");
  if (!(moment_constant_m >= 0 && std::isfinite(moment_constant_m))) {
    return fail("moment_constant_m: must be >= 0");
  }
  if (!(rotor_drag_coefficient >= 0 && std::isfinite(rotor_drag_coefficient))) {
    return fail("rotor_drag_coefficient: must be >= 0");
  }
  if (!positive(motor_time_constant_up_s)) return fail("motor_time_constant_up_s: must be > 0");
  if (!positive(motor_time_constant_down_s)) {
    return fail("motor_time_constant_down_s: must be > 0");
  }
  if (!positive(max_rotor_speed_radps)) return fail("max_rotor_speed_radps: must be positive");
  if (!(gravity_mps2 >= 0 && std::isfinite(gravity_mps2))) return fail("gravity_mps2: >= 0");
  if (!(rest_height_m >= 0 && std::isfinite(rest_height_m))) return fail("rest_height_m: >= 0");
  return true;
}

Multicopter::Multicopter(const MulticopterParams& params, double max_substep_s)
    : params_(params), max_substep_s_(max_substep_s) {
  std::string why;
  MAV_CHECK(params.IsValid(&why)) << why;
  MAV_CHECK(max_substep_s > 0 && max_substep_s <= 0.01) << "max_substep_s " << max_substep_s;
  rotor_positions_.setZero();
  for (int i = 0; i < params.rotor_count; ++i) {
    const double a = params.rotor_angles_deg[i] * M_PI / 180.0;
    rotor_positions_.col(i) = params.arm_length_m * Eigen::Vector3d(std::cos(a), std::sin(a), 0.0);
  }
  state_.rotor_speeds_radps = RotorVector::Zero(params.rotor_count);
  command_ = RotorVector::Zero(params.rotor_count);
}

void Multicopter::Reset(const Eigen::Vector3d& p_world, double yaw_rad, bool on_ground,
                        double ground_z) {
  state_ = MulticopterState();
  state_.p_world = p_world;
  state_.q_world_body = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ());
  state_.rotor_speeds_radps = RotorVector::Zero(params_.rotor_count);
  state_.on_ground = on_ground;
  ground_z_ = ground_z;
  if (on_ground) state_.p_world.z() = ground_z + params_.rest_height_m;
  command_ = RotorVector::Zero(params_.rotor_count);
}

void Multicopter::SetState(const MulticopterState& state) {
  MAV_CHECK(state.rotor_speeds_radps.size() == params_.rotor_count)
      << "state has " << state.rotor_speeds_radps.size() << " rotor speeds";
  state_ = state;
  state_.q_world_body.normalize();
}

Eigen::Vector3d Multicopter::BodyForce(const MulticopterState& x) const {
  double thrust = 0, speed_sum = 0;
  for (int i = 0; i < params_.rotor_count; ++i) {
    const double w = x.rotor_speeds_radps[i];
    thrust += params_.thrust_constant * w * w;
    speed_sum += std::abs(w);
  }
  Eigen::Vector3d v_body = x.q_world_body.conjugate() * x.v_world;
  v_body.z() = 0;  // the component perpendicular to the rotor axes
  return Eigen::Vector3d(0, 0, thrust) - params_.rotor_drag_coefficient * speed_sum * v_body;
}

Eigen::Vector4d Multicopter::RotorWrench() const {
  Eigen::Vector4d out = Eigen::Vector4d::Zero();
  for (int i = 0; i < params_.rotor_count; ++i) {
    const double w = state_.rotor_speeds_radps[i];
    const double f = params_.thrust_constant * w * w;
    out[0] += f;
    const Eigen::Vector3d r = rotor_positions_.col(i);
    out.tail<3>() +=
        r.cross(Eigen::Vector3d(0, 0, f)) +
        Eigen::Vector3d(0, 0, -params_.rotor_directions[i] * params_.moment_constant_m * f);
  }
  return out;
}

void Multicopter::Derivatives(const MulticopterState& x, Eigen::Vector3d* dp, Eigen::Vector3d* dv,
                              Eigen::Vector4d* dq, Eigen::Vector3d* dw, RotorVector* dr) const {
  const double m = params_.mass_kg;
  Eigen::Vector3d torque = Eigen::Vector3d::Zero();
  for (int i = 0; i < params_.rotor_count; ++i) {
    const double w = x.rotor_speeds_radps[i];
    const double f = params_.thrust_constant * w * w;
    const Eigen::Vector3d& r = rotor_positions_.col(i);
    // r x (0, 0, f) = (r_y f, -r_x f, 0); reactive yaw torque opposite to the spin.
    torque += Eigen::Vector3d(r.y() * f, -r.x() * f,
                              -params_.rotor_directions[i] * params_.moment_constant_m * f);
    const double target = command_[i];
    const double tau =
        target >= w ? params_.motor_time_constant_up_s : params_.motor_time_constant_down_s;
    (*dr)[i] = (target - w) / tau;
  }
  *dp = x.v_world;
  *dv = (x.q_world_body * BodyForce(x) + external_force_) / m -
        Eigen::Vector3d(0, 0, params_.gravity_mps2);
  const Eigen::Vector3d& J = params_.inertia_kgm2;
  *dw = (torque - x.omega_body.cross(J.cwiseProduct(x.omega_body))).cwiseQuotient(J);
  const Eigen::Quaterniond qw =
      x.q_world_body * Eigen::Quaterniond(0, x.omega_body.x(), x.omega_body.y(), x.omega_body.z());
  *dq = 0.5 * qw.coeffs();
}

Eigen::Vector3d Multicopter::AccelerationWorld() const {
  if (state_.on_ground) return Eigen::Vector3d::Zero();
  return (state_.q_world_body * BodyForce(state_) + external_force_) / params_.mass_kg -
         Eigen::Vector3d(0, 0, params_.gravity_mps2);
}

Eigen::Vector3d Multicopter::SpecificForceBody() const {
  return state_.q_world_body.conjugate() *
         (AccelerationWorld() + Eigen::Vector3d(0, 0, params_.gravity_mps2));
}

GroundContact Multicopter::Step(const RotorVector& command_radps, double dt_s) {
  MAV_CHECK(command_radps.size() == params_.rotor_count)
      << "command has " << command_radps.size() << " rotors, vehicle " << params_.rotor_count;
  MAV_CHECK(dt_s >= 0 && std::isfinite(dt_s)) << "dt_s " << dt_s;
  for (int i = 0; i < params_.rotor_count; ++i) {
    command_[i] = std::isfinite(command_radps[i])
                      ? std::clamp(command_radps[i], 0.0, params_.max_rotor_speed_radps)
                      : 0.0;
  }
  GroundContact contact;
  const int n = std::max(1, static_cast<int>(std::ceil(dt_s / max_substep_s_ - 1e-9)));
  const double h = dt_s / n;
  const double rest_z = ground_z_ + params_.rest_height_m;
  for (int k = 0; k < n; ++k) {
    MulticopterState& x = state_;
    if (x.on_ground) {
      // Resting: only the rotors move; lift off once the vertical force exceeds the weight.
      for (int i = 0; i < params_.rotor_count; ++i) {
        const double w = x.rotor_speeds_radps[i];
        const double tau = command_[i] >= w ? params_.motor_time_constant_up_s
                                            : params_.motor_time_constant_down_s;
        // Exact first-order step (stable for any h).
        x.rotor_speeds_radps[i] = command_[i] + (w - command_[i]) * std::exp(-h / tau);
      }
      const double up = (x.q_world_body * BodyForce(x)).z() + external_force_.z() -
                        params_.mass_kg * params_.gravity_mps2;
      if (up <= 0) continue;
      x.on_ground = false;
    }
    // Classical RK4 on (p, v, q, w, W).
    Eigen::Vector3d dp[4], dv[4], dw[4];
    Eigen::Vector4d dq[4];
    RotorVector dr[4];
    for (auto& d : dr) d.resize(params_.rotor_count);
    MulticopterState s = x;
    const double c[4] = {0, 0.5 * h, 0.5 * h, h};
    for (int stage = 0; stage < 4; ++stage) {
      if (stage > 0) {
        s.p_world = x.p_world + c[stage] * dp[stage - 1];
        s.v_world = x.v_world + c[stage] * dv[stage - 1];
        Eigen::Vector4d qc = x.q_world_body.coeffs() + c[stage] * dq[stage - 1];
        s.q_world_body.coeffs() = qc.normalized();
        s.omega_body = x.omega_body + c[stage] * dw[stage - 1];
        s.rotor_speeds_radps = x.rotor_speeds_radps + c[stage] * dr[stage - 1];
      }
      Derivatives(s, &dp[stage], &dv[stage], &dq[stage], &dw[stage], &dr[stage]);
    }
    const double w6 = h / 6.0;
    x.p_world += w6 * (dp[0] + 2 * dp[1] + 2 * dp[2] + dp[3]);
    x.v_world += w6 * (dv[0] + 2 * dv[1] + 2 * dv[2] + dv[3]);
    x.q_world_body.coeffs() += w6 * (dq[0] + 2 * dq[1] + 2 * dq[2] + dq[3]);
    x.q_world_body.normalize();
    x.omega_body += w6 * (dw[0] + 2 * dw[1] + 2 * dw[2] + dw[3]);
    x.rotor_speeds_radps += w6 * (dr[0] + 2 * dr[1] + 2 * dr[2] + dr[3]);
    for (int i = 0; i < params_.rotor_count; ++i) {
      x.rotor_speeds_radps[i] =
          std::clamp(x.rotor_speeds_radps[i], 0.0, params_.max_rotor_speed_radps);
    }
    if (x.p_world.z() < rest_z) {
      // Touchdown: the legs stop the vehicle; it rests level at its heading.
      contact.touched_down = true;
      contact.impact_speed_mps = std::max(contact.impact_speed_mps, -x.v_world.z());
      const Eigen::Matrix3d R = x.q_world_body.toRotationMatrix();
      x.q_world_body = Eigen::AngleAxisd(std::atan2(R(1, 0), R(0, 0)), Eigen::Vector3d::UnitZ());
      x.p_world.z() = rest_z;
      x.v_world.setZero();
      x.omega_body.setZero();
      x.on_ground = true;
    }
  }
  return contact;
}

}  // namespace mav::sim
