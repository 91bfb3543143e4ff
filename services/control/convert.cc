#include "services/control/convert.h"

#include <cmath>
#include <utility>
#include <vector>

#include "mav/common/time.h"

namespace mav::control_service {

namespace {

using service_common::Number;

Status NotFinite(const std::string& field) {
  return Status::InvalidArgument(field + ": not finite");
}

// `value` if set (non-zero), else `fallback`; InvalidArgument when not finite.
Status Pick(double value, const std::string& field, double* target) {
  if (!std::isfinite(value)) return NotFinite(field);
  if (value != 0.0) *target = value;
  return Status::Ok();
}

Status PickVector(const v1::Vector3& v, const std::string& field, Eigen::Vector3d* target) {
  MAV_RETURN_IF_ERROR(Pick(v.x(), field + ".x", &target->x()));
  MAV_RETURN_IF_ERROR(Pick(v.y(), field + ".y", &target->y()));
  return Pick(v.z(), field + ".z", &target->z());
}

Status VehicleFromProto(const v1::VehicleParameters& v, control::VehicleParameters* out) {
  MAV_RETURN_IF_ERROR(Pick(v.mass_kg(), "vehicle.mass_kg", &out->mass_kg));
  MAV_RETURN_IF_ERROR(PickVector(v.inertia_kgm2(), "vehicle.inertia_kgm2", &out->inertia_kgm2));
  if (v.rotor_count() != 0) {
    if (v.rotor_count() < 4 || v.rotor_count() > static_cast<uint32_t>(control::kMaxRotors)) {
      return Status::InvalidArgument("vehicle.rotor_count: must be in [4, 8], got " +
                                     std::to_string(v.rotor_count()));
    }
    out->rotor_count = static_cast<int>(v.rotor_count());
  }
  const int n = out->rotor_count;
  // The Firefly's layout is the default only for its six rotors.
  if (v.rotor_angles_deg_size() != 0 || n != 6) {
    if (v.rotor_angles_deg_size() != n) {
      return Status::InvalidArgument(
          "vehicle.rotor_angles_deg: " + std::to_string(v.rotor_angles_deg_size()) +
          " values for " + std::to_string(n) + " rotors");
    }
    out->rotor_angles_deg.fill(0);
    for (int i = 0; i < n; ++i) {
      const double a = v.rotor_angles_deg(i);
      if (!std::isfinite(a))
        return NotFinite("vehicle.rotor_angles_deg[" + std::to_string(i) + "]");
      out->rotor_angles_deg[i] = a;
    }
  }
  if (v.rotor_directions_size() != 0 || n != 6) {
    if (v.rotor_directions_size() != n) {
      return Status::InvalidArgument(
          "vehicle.rotor_directions: " + std::to_string(v.rotor_directions_size()) +
          " values for " + std::to_string(n) + " rotors");
    }
    out->rotor_directions.fill(0);
    for (int i = 0; i < n; ++i) out->rotor_directions[i] = v.rotor_directions(i);
  }
  MAV_RETURN_IF_ERROR(Pick(v.arm_length_m(), "vehicle.arm_length_m", &out->arm_length_m));
  MAV_RETURN_IF_ERROR(Pick(v.thrust_constant(), "vehicle.thrust_constant", &out->thrust_constant));
  MAV_RETURN_IF_ERROR(
      Pick(v.moment_constant_m(), "vehicle.moment_constant_m", &out->moment_constant_m));
  MAV_RETURN_IF_ERROR(Pick(v.max_rotor_speed_radps(), "vehicle.max_rotor_speed_radps",
                           &out->max_rotor_speed_radps));
  MAV_RETURN_IF_ERROR(Pick(v.motor_time_constant_up_s(), "vehicle.motor_time_constant_up_s",
                           &out->motor_time_constant_up_s));
  MAV_RETURN_IF_ERROR(Pick(v.motor_time_constant_down_s(), "vehicle.motor_time_constant_down_s",
                           &out->motor_time_constant_down_s));
  if (!(out->motor_time_constant_up_s > 0) || !(out->motor_time_constant_down_s > 0)) {
    return Status::InvalidArgument("vehicle.motor_time_constant_up_s/down_s: must be positive");
  }
  // The library names its fields as the request does; checked here so that a later check that
  // relies on the vehicle (the allocation's fit) never blames another field for it.
  if (std::string why; !out->IsValid(&why)) return Status::InvalidArgument("vehicle." + why);
  return Status::Ok();
}

Status EstimatorFromProto(const v1::EstimatorConfig& e, control::EstimatorOptions* out,
                          std::vector<std::string>* frames,
                          std::vector<LockstepPoseOptions>* lockstep) {
  MAV_RETURN_IF_ERROR(Pick(e.imu_rate_hz(), "estimator.imu_rate_hz", &out->imu_rate_hz));
  if (out->imu_rate_hz < 10 || out->imu_rate_hz > 2000) {
    return Status::InvalidArgument("estimator.imu_rate_hz: must be in [10, 2000], got " +
                                   Number(out->imu_rate_hz));
  }
  MAV_RETURN_IF_ERROR(
      Pick(e.accel_noise_sigma(), "estimator.accel_noise_sigma", &out->accel_noise_sigma));
  MAV_RETURN_IF_ERROR(
      Pick(e.gyro_noise_sigma(), "estimator.gyro_noise_sigma", &out->gyro_noise_sigma));
  if (e.has_accel_offset_random_walk()) {
    out->accel_offset_random_walk = e.accel_offset_random_walk();
    if (!(out->accel_offset_random_walk >= 0) || !std::isfinite(out->accel_offset_random_walk)) {
      return Status::InvalidArgument("estimator.accel_offset_random_walk: must be >= 0");
    }
  }
  if (e.has_gyro_offset_random_walk()) {
    out->gyro_offset_random_walk = e.gyro_offset_random_walk();
    if (!(out->gyro_offset_random_walk >= 0) || !std::isfinite(out->gyro_offset_random_walk)) {
      return Status::InvalidArgument("estimator.gyro_offset_random_walk: must be >= 0");
    }
  }
  constexpr int kMaxSources = 8;
  if (e.pose_sources_size() > kMaxSources) {
    return Status::InvalidArgument(
        "estimator.pose_sources: " + std::to_string(e.pose_sources_size()) + " sources, at most " +
        std::to_string(kMaxSources));
  }
  const int count = std::max(1, e.pose_sources_size());
  out->pose_sources.assign(static_cast<size_t>(count), control::PoseSourceOptions());
  lockstep->assign(static_cast<size_t>(count), LockstepPoseOptions());
  frames->clear();
  double max_delay_s = 0.1;
  for (int i = 0; i < count; ++i) {
    const std::string field = "estimator.pose_sources[" + std::to_string(i) + "]";
    control::PoseSourceOptions& src = out->pose_sources[static_cast<size_t>(i)];
    std::string frame = "pose_sensor" + std::to_string(i);
    double delay_s = 0.1;
    if (i < e.pose_sources_size()) {
      const v1::ControlPoseSource& p = e.pose_sources(i);
      if (!p.frame_id().empty()) frame = p.frame_id();
      MAV_RETURN_IF_ERROR(Pick(p.rate_hz(), field + ".rate_hz", &src.rate_hz));
      MAV_RETURN_IF_ERROR(Pick(p.delay_s(), field + ".delay_s", &delay_s));
      if (delay_s < 0 || delay_s > 1) {
        return Status::InvalidArgument(field + ".delay_s: must be in [0, 1] s, got " +
                                       Number(delay_s));
      }
      MAV_RETURN_IF_ERROR(
          Pick(p.position_sigma_m(), field + ".position_sigma_m", &src.position_sigma_m));
      MAV_RETURN_IF_ERROR(Pick(p.orientation_sigma_rad(), field + ".orientation_sigma_rad",
                               &src.orientation_sigma_rad));
      MAV_RETURN_IF_ERROR(Pick(p.tilt_sigma_rad(), field + ".tilt_sigma_rad", &src.tilt_sigma_rad));
      MAV_RETURN_IF_ERROR(Pick(p.align_tilt_s(), field + ".align_tilt_s", &src.align_tilt_s));
      if (p.has_t_body_sensor()) {
        MAV_ASSIGN_OR_RETURN(src.T_body_sensor,
                             PoseFromProto(p.t_body_sensor(), field + ".t_body_sensor"));
      }
      LockstepPoseOptions& l = (*lockstep)[static_cast<size_t>(i)];
      l.latency_s = p.lockstep_latency_s();
      MAV_RETURN_IF_ERROR(Pick(p.lockstep_wait_s(), field + ".lockstep_wait_s", &l.wait_s));
      if (!std::isfinite(l.latency_s)) return NotFinite(field + ".lockstep_latency_s");
    }
    max_delay_s = std::max(max_delay_s, delay_s);
    frames->push_back(frame);
  }
  // The buffer must outlast the latest pose (as eval::AutopilotOptionsForTask sizes it).
  out->buffer_s = std::max(1.0, 2 * max_delay_s + 0.2);
  MAV_RETURN_IF_ERROR(Pick(e.buffer_s(), "estimator.buffer_s", &out->buffer_s));
  out->estimate_offsets = !e.fixed_offsets();
  out->couple_tilt = !e.decoupled_weights();
  out->transient_weights = !e.steady_state_weights_only();
  MAV_RETURN_IF_ERROR(Pick(e.converge_s(), "estimator.converge_s", &out->converge_s));
  for (const auto& [value, name] : {std::pair<double, const char*>{e.pose_gate_m(), "pose_gate_m"},
                                    {e.pose_gate_growth_mps(), "pose_gate_growth_mps"},
                                    {e.pose_gate_rad(), "pose_gate_rad"}}) {
    if (!(value >= 0) || !std::isfinite(value)) {
      return Status::InvalidArgument(std::string("estimator.") + name +
                                     ": must be >= 0 and finite, got " + Number(value));
    }
  }
  out->pose_gate_m = e.pose_gate_m();
  out->pose_gate_rad = e.pose_gate_rad();
  MAV_RETURN_IF_ERROR(
      Pick(e.pose_gate_growth_mps(), "estimator.pose_gate_growth_mps", &out->pose_gate_growth_mps));
  if (e.has_explicit_weights()) {
    const v1::DecoupledWeights& w = e.explicit_weights();
    for (const auto& [value, name] : {std::pair<double, const char*>{w.position(), "position"},
                                      {w.velocity(), "velocity"},
                                      {w.accel_offset(), "accel_offset"},
                                      {w.orientation(), "orientation"},
                                      {w.gyro_offset(), "gyro_offset"}}) {
      if (!std::isfinite(value))
        return NotFinite(std::string("estimator.explicit_weights.") + name);
    }
    out->explicit_weights = control::CorrectionWeights::Decoupled(
        w.position(), w.velocity(), w.accel_offset(), w.orientation(), w.gyro_offset());
  }
  // The library names its fields as control.proto does (pose_sources, explicit_weights).
  if (std::string why; !out->IsValid(&why)) return Status::InvalidArgument("estimator." + why);
  return Status::Ok();
}

}  // namespace

Result<control::PaperControllerGains> PaperGainsFromProto(const v1::ControllerGains& g,
                                                          const std::string& field) {
  control::PaperControllerGains out;
  MAV_RETURN_IF_ERROR(PickVector(g.position_omega_radps(), field + ".position_omega_radps",
                                 &out.position_omega_radps));
  MAV_RETURN_IF_ERROR(PickVector(g.position_zeta(), field + ".position_zeta", &out.position_zeta));
  MAV_RETURN_IF_ERROR(PickVector(g.integral_gain(), field + ".integral_gain", &out.integral_gain));
  MAV_RETURN_IF_ERROR(
      Pick(g.integral_limit_mps2(), field + ".integral_limit_mps2", &out.integral_limit_mps2));
  MAV_RETURN_IF_ERROR(
      Pick(g.attitude_omega_radps(), field + ".attitude_omega_radps", &out.attitude_omega_radps));
  MAV_RETURN_IF_ERROR(Pick(g.attitude_zeta(), field + ".attitude_zeta", &out.attitude_zeta));
  MAV_RETURN_IF_ERROR(Pick(g.yaw_omega_radps(), field + ".yaw_omega_radps", &out.yaw_omega_radps));
  MAV_RETURN_IF_ERROR(Pick(g.yaw_zeta(), field + ".yaw_zeta", &out.yaw_zeta));
  if (std::string why; !out.IsValid(&why)) return Status::InvalidArgument(field + "." + why);
  return out;
}

Result<control::LeeControllerGains> LeeGainsFromProto(const v1::LeeGains& g,
                                                      const std::string& field) {
  control::LeeControllerGains out;
  MAV_RETURN_IF_ERROR(PickVector(g.position_gain(), field + ".position_gain", &out.position_gain));
  MAV_RETURN_IF_ERROR(PickVector(g.velocity_gain(), field + ".velocity_gain", &out.velocity_gain));
  MAV_RETURN_IF_ERROR(PickVector(g.attitude_gain(), field + ".attitude_gain", &out.attitude_gain));
  MAV_RETURN_IF_ERROR(
      PickVector(g.angular_rate_gain(), field + ".angular_rate_gain", &out.angular_rate_gain));
  if (std::string why; !out.IsValid(&why)) return Status::InvalidArgument(field + "." + why);
  return out;
}

Result<control::GoToLimits> LimitsFromProto(const v1::GoToLimits& l, const std::string& field) {
  control::GoToLimits out;
  MAV_RETURN_IF_ERROR(Pick(l.max_speed_mps(), field + ".max_speed_mps", &out.max_speed_mps));
  MAV_RETURN_IF_ERROR(Pick(l.max_accel_mps2(), field + ".max_accel_mps2", &out.max_accel_mps2));
  MAV_RETURN_IF_ERROR(
      Pick(l.max_yaw_rate_radps(), field + ".max_yaw_rate_radps", &out.max_yaw_rate_radps));
  MAV_RETURN_IF_ERROR(Pick(l.min_duration_s(), field + ".min_duration_s", &out.min_duration_s));
  if (std::string why; !out.IsValid(&why)) return Status::InvalidArgument(field + "." + why);
  return out;
}

Result<ControlConfig> ConfigFromProto(const v1::ControlConfigureRequest& r) {
  ControlConfig config;
  control::AutopilotOptions& o = config.autopilot;
  MAV_RETURN_IF_ERROR(VehicleFromProto(r.vehicle(), &o.vehicle));
  MAV_RETURN_IF_ERROR(
      EstimatorFromProto(r.estimator(), &o.estimator, &config.pose_frames, &config.lockstep_poses));
  MAV_ASSIGN_OR_RETURN(o.controller, kControllerCodec.FromProto(r.controller(), "controller"));
  MAV_ASSIGN_OR_RETURN(o.paper_gains, PaperGainsFromProto(r.gains(), "gains"));
  MAV_ASSIGN_OR_RETURN(o.lee_gains, LeeGainsFromProto(r.lee_gains(), "lee_gains"));
  MAV_RETURN_IF_ERROR(Pick(r.max_tilt_rad(), "max_tilt_rad", &o.max_tilt_rad));
  MAV_ASSIGN_OR_RETURN(o.goto_limits, LimitsFromProto(r.goto_limits(), "goto_limits"));
  MAV_RETURN_IF_ERROR(Pick(r.imu_timeout_s(), "imu_timeout_s", &o.imu_timeout_s));
  MAV_ASSIGN_OR_RETURN(o.imu_loss_policy,
                       kImuLossPolicyCodec.FromProto(r.imu_loss_policy(), "imu_loss_policy"));
  MAV_RETURN_IF_ERROR(Pick(r.pose_timeout_s(), "pose_timeout_s", &o.pose_timeout_s));
  MAV_RETURN_IF_ERROR(
      Pick(r.failsafe_descent_mps(), "failsafe_descent_mps", &o.failsafe_descent_mps));
  MAV_RETURN_IF_ERROR(
      Pick(r.max_trajectory_jump_m(), "max_trajectory_jump_m", &o.max_trajectory_jump_m));
  if (r.has_disturbance_observer_s()) o.disturbance_observer_s = r.disturbance_observer_s();
  if (r.has_correction_blend_s()) o.correction_blend_s = r.correction_blend_s();
  MAV_RETURN_IF_ERROR(Pick(r.min_rotor_speed_radps(), "min_rotor_speed_radps",
                           &o.allocation.min_rotor_speed_radps));
  config.lockstep = r.lockstep();
  if (r.has_rest_z_m()) {
    if (!std::isfinite(r.rest_z_m())) return Status::InvalidArgument("rest_z_m: must be finite");
    o.rest_z_m = r.rest_z_m();
  }
  MAV_RETURN_IF_ERROR(
      Pick(r.takeover_min_height_m(), "takeover_min_height_m", &o.takeover_min_height_m));
  MAV_RETURN_IF_ERROR(Pick(r.takeover_settle_s(), "takeover_settle_s", &o.takeover_settle_s));
  // The allocation's one field is at the request's top level.
  if (std::string why; !o.allocation.IsValid(&why) || !o.allocation.FitsVehicle(o.vehicle, &why)) {
    return Status::InvalidArgument(why);
  }
  // Every field was checked above under its request path; the library's own check of the
  // whole (the same paths, but for gains, which PaperGainsFromProto checked as "gains") is the
  // backstop.
  if (std::string why; !config.IsValid(&why)) return Status::InvalidArgument(why);
  return config;
}

void ToProto(const ControlConfig& config, v1::ControlConfigureRequest* out) {
  const control::AutopilotOptions& o = config.autopilot;
  v1::VehicleParameters* v = out->mutable_vehicle();
  v->set_mass_kg(o.vehicle.mass_kg);
  ToProto(o.vehicle.inertia_kgm2, v->mutable_inertia_kgm2());
  v->set_rotor_count(static_cast<uint32_t>(o.vehicle.rotor_count));
  v->set_arm_length_m(o.vehicle.arm_length_m);
  for (int i = 0; i < o.vehicle.rotor_count; ++i) {
    v->add_rotor_angles_deg(o.vehicle.rotor_angles_deg[i]);
    v->add_rotor_directions(o.vehicle.rotor_directions[i]);
  }
  v->set_thrust_constant(o.vehicle.thrust_constant);
  v->set_moment_constant_m(o.vehicle.moment_constant_m);
  v->set_max_rotor_speed_radps(o.vehicle.max_rotor_speed_radps);
  v->set_motor_time_constant_up_s(o.vehicle.motor_time_constant_up_s);
  v->set_motor_time_constant_down_s(o.vehicle.motor_time_constant_down_s);

  const control::EstimatorOptions& e = o.estimator;
  v1::EstimatorConfig* pe = out->mutable_estimator();
  pe->set_imu_rate_hz(e.imu_rate_hz);
  pe->set_buffer_s(e.buffer_s);
  pe->set_accel_noise_sigma(e.accel_noise_sigma);
  pe->set_gyro_noise_sigma(e.gyro_noise_sigma);
  for (size_t i = 0; i < e.pose_sources.size(); ++i) {
    v1::ControlPoseSource* p = pe->add_pose_sources();
    p->set_frame_id(i < config.pose_frames.size() ? config.pose_frames[i] : "");
    p->set_rate_hz(e.pose_sources[i].rate_hz);
    // The delays only size the buffer; the effective buffer is reported above.
    p->set_position_sigma_m(e.pose_sources[i].position_sigma_m);
    p->set_orientation_sigma_rad(e.pose_sources[i].orientation_sigma_rad);
    p->set_tilt_sigma_rad(e.pose_sources[i].tilt_sigma_rad);
    p->set_align_tilt_s(e.pose_sources[i].align_tilt_s);
    ToProto(e.pose_sources[i].T_body_sensor, p->mutable_t_body_sensor());
    if (i < config.lockstep_poses.size()) {
      p->set_lockstep_latency_s(config.lockstep_poses[i].latency_s);
      p->set_lockstep_wait_s(config.lockstep_poses[i].wait_s);
    }
  }
  pe->set_pose_gate_m(e.pose_gate_m);
  pe->set_pose_gate_growth_mps(e.pose_gate_growth_mps);
  pe->set_pose_gate_rad(e.pose_gate_rad);
  pe->set_accel_offset_random_walk(e.accel_offset_random_walk);
  pe->set_gyro_offset_random_walk(e.gyro_offset_random_walk);
  pe->set_fixed_offsets(!e.estimate_offsets);
  pe->set_decoupled_weights(!e.couple_tilt);
  pe->set_steady_state_weights_only(!e.transient_weights);
  pe->set_converge_s(e.converge_s);
  if (e.explicit_weights.has_value()) {
    const control::CorrectionWeights& w = *e.explicit_weights;
    v1::DecoupledWeights* pw = pe->mutable_explicit_weights();
    pw->set_position(w.horizontal(0, 0));
    pw->set_velocity(w.horizontal(1, 0));
    pw->set_accel_offset(w.horizontal(2, 0));
    pw->set_orientation(w.horizontal(3, 1));
    pw->set_gyro_offset(w.horizontal(4, 1));
  }

  const control::PaperControllerGains& g = o.paper_gains;
  v1::ControllerGains* pg = out->mutable_gains();
  ToProto(g.position_omega_radps, pg->mutable_position_omega_radps());
  ToProto(g.position_zeta, pg->mutable_position_zeta());
  ToProto(g.integral_gain, pg->mutable_integral_gain());
  pg->set_integral_limit_mps2(g.integral_limit_mps2);
  pg->set_attitude_omega_radps(g.attitude_omega_radps);
  pg->set_attitude_zeta(g.attitude_zeta);
  pg->set_yaw_omega_radps(g.yaw_omega_radps);
  pg->set_yaw_zeta(g.yaw_zeta);
  v1::LeeGains* pl = out->mutable_lee_gains();
  ToProto(o.lee_gains.position_gain, pl->mutable_position_gain());
  ToProto(o.lee_gains.velocity_gain, pl->mutable_velocity_gain());
  ToProto(o.lee_gains.attitude_gain, pl->mutable_attitude_gain());
  ToProto(o.lee_gains.angular_rate_gain, pl->mutable_angular_rate_gain());

  out->set_controller(kControllerCodec.ToProto(o.controller));
  out->set_max_tilt_rad(o.max_tilt_rad);
  v1::GoToLimits* l = out->mutable_goto_limits();
  l->set_max_speed_mps(o.goto_limits.max_speed_mps);
  l->set_max_accel_mps2(o.goto_limits.max_accel_mps2);
  l->set_max_yaw_rate_radps(o.goto_limits.max_yaw_rate_radps);
  l->set_min_duration_s(o.goto_limits.min_duration_s);
  out->set_imu_timeout_s(o.imu_timeout_s);
  out->set_imu_loss_policy(kImuLossPolicyCodec.ToProto(o.imu_loss_policy));
  out->set_pose_timeout_s(o.pose_timeout_s);
  out->set_failsafe_descent_mps(o.failsafe_descent_mps);
  out->set_max_trajectory_jump_m(o.max_trajectory_jump_m);
  out->set_disturbance_observer_s(o.disturbance_observer_s);
  out->set_correction_blend_s(o.correction_blend_s);
  out->set_min_rotor_speed_radps(o.allocation.min_rotor_speed_radps);
  out->set_lockstep(config.lockstep);
  if (o.rest_z_m) out->set_rest_z_m(*o.rest_z_m);
  out->set_takeover_min_height_m(o.takeover_min_height_m);
  out->set_takeover_settle_s(o.takeover_settle_s);
}

v1::ControlMode ToProto(control::FlightMode mode) {
  switch (mode) {
    case control::FlightMode::kDisarmed:
      return v1::CONTROL_MODE_DISARMED;
    case control::FlightMode::kHover:
      return v1::CONTROL_MODE_HOVER;
    case control::FlightMode::kTrajectory:
      return v1::CONTROL_MODE_TRAJECTORY;
    case control::FlightMode::kFailsafe:
      return v1::CONTROL_MODE_FAILSAFE;
  }
  return v1::CONTROL_MODE_UNSPECIFIED;
}

void ToProto(const ControlCoreStatus& s, bool dds_input, v1::ControlStatus* out) {
  const control::AutopilotStatus& a = s.autopilot;
  out->set_configured(s.configured);
  out->set_mode(s.configured ? ToProto(a.mode) : v1::CONTROL_MODE_DISARMED);
  out->set_armed(a.armed);
  out->set_estimator_converged(a.estimator_converged);
  out->set_imu_samples(a.imu_samples);
  out->set_poses(a.poses);
  out->set_commands(s.commands_published);
  out->set_imu_rate_hz(s.imu_rate_hz);
  out->set_pose_rate_hz(s.pose_rate_hz);
  out->set_lockstep_frames_missed(s.lockstep_frames_missed);
  out->set_lockstep_source_silent(s.lockstep_source_silent);
  out->set_position_rms_m(a.position_rms_m);
  out->set_angular_rate_rms_radps(a.angular_rate_rms_radps);
  ToProto(a.step_ms, out->mutable_step_ms());
  if (s.config.has_value()) {
    ToProto(*s.config, out->mutable_config());
    out->mutable_config()->set_disable_dds_input(!dds_input);
    out->set_controller(out->config().controller());
  }
  out->set_poses_dropped(a.poses_dropped);
  out->set_poses_rejected(s.poses_rejected);
  out->set_imu_rejected(s.imu_rejected);
  out->set_imu_repeated(s.imu_repeated);
  out->set_saturated_steps(a.saturated_steps);
  out->set_imu_timeouts(a.imu_timeouts);
  out->set_pose_timeouts(a.pose_timeouts);
  ToProto(s.loop_ms, out->mutable_loop_ms());
  v1::PoseLatency* latency = out->mutable_pose_latency();
  ToProto(s.pose_latency.total_ms, latency->mutable_total());
  ToProto(s.pose_latency.frame_transport_ms, latency->mutable_frame_transport());
  ToProto(s.pose_latency.localization_ms, latency->mutable_localization());
  ToProto(s.pose_latency.pose_transport_ms, latency->mutable_pose_transport());
  ToProto(s.pose_latency.merge_ms, latency->mutable_merge());
  out->set_dds_input(dds_input);
  out->set_actuator_subscribers(s.actuator_subscribers);
  out->set_last_error(s.last_error);
  out->set_last_error_age_s(s.last_error_age_s);
  out->set_estimator_stale(s.estimator_stale);
  if (s.imu_age_s) out->set_imu_age_s(*s.imu_age_s);
  if (s.pose_age_s) out->set_pose_age_s(*s.pose_age_s);
  out->set_imu_publishers_alive(s.imu_publishers_alive);
  out->set_takeover_pending(s.takeover_pending);
}

void ToProto(const ControlCoreState& s, v1::ControlState* out) {
  out->set_configured(s.configured);
  out->set_armed(s.armed);
  if (!s.configured) {
    out->set_mode(v1::CONTROL_MODE_DISARMED);
    return;
  }
  const control::AutopilotState& a = s.autopilot;
  out->set_mode(ToProto(a.mode));
  v1::VehicleEstimate* e = out->mutable_estimate();
  e->set_t_ns(a.estimate.t_ns);
  ToProto(geometry::SE3(a.estimate.q_world_body, a.estimate.p_world), e->mutable_t_world_body());
  ToProto(a.estimate.v_world, e->mutable_velocity());
  ToProto(a.estimate.omega_body, e->mutable_angular_velocity());
  ToProto(a.estimate.accel_offset, e->mutable_accel_bias());
  ToProto(a.estimate.gyro_offset, e->mutable_gyro_bias());
  e->set_converged(a.estimator_converged);
  e->set_last_pose_t_ns(s.last_pose_t_ns);
  e->set_last_pose_delay_ms(s.last_pose_delay_ms);
  e->set_initialized(s.estimator_initialized);
  e->set_last_pose_arrival_t_ns(s.last_pose_arrival_ns);
  e->set_poses_gated(s.poses_gated);
  for (const geometry::SE3& frame : s.source_frames) ToProto(frame, e->add_source_frames());
  out->set_moving(s.moving);
  v1::TrajectorySample* r = out->mutable_reference();
  r->set_t_s(a.reference.t_s);
  ToProto(a.reference.position, r->mutable_position());
  ToProto(a.reference.velocity, r->mutable_velocity());
  ToProto(a.reference.acceleration, r->mutable_acceleration());
  ToProto(a.reference.jerk, r->mutable_jerk());
  ToProto(a.reference.snap, r->mutable_snap());
  r->set_yaw_rad(a.reference.yaw_rad);
  r->set_yaw_rate_radps(a.reference.yaw_rate_radps);
  ToProto(a.position_error, out->mutable_position_error());
  ToProto(a.velocity_error, out->mutable_velocity_error());
  ToProto(a.integral, out->mutable_integral());
  for (int i = 0; i < a.rotor_speeds.size(); ++i) out->add_rotor_speeds_radps(a.rotor_speeds[i]);
  out->set_trajectory_t_s(a.trajectory_t_s);
  out->set_trajectory_duration_s(a.trajectory_duration_s);
  ToProto(a.disturbance, out->mutable_disturbance());
}

}  // namespace mav::control_service
