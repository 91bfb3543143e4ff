#include "services/simulator/convert.h"

#include <cmath>
#include <sstream>

#include "mav/common/time.h"

namespace mav::simulator_service {

using service_common::Number;

Result<LoadRequest> FromProto(const v1::LoadScenarioRequest& request) {
  LoadRequest out;
  switch (request.source_case()) {
    case v1::LoadScenarioRequest::kPreset:
      out.is_preset = true;
      out.preset.name = request.preset().name();
      out.preset.frames = request.preset().frames();
      out.preset.seed = request.preset().seed();
      out.preset.rectified = request.preset().rectified();
      return out;
    case v1::LoadScenarioRequest::kEuroc:
      out.is_preset = false;
      out.euroc_directory = request.euroc().directory();
      return out;
    case v1::LoadScenarioRequest::SOURCE_NOT_SET:
      break;
  }
  return Status::InvalidArgument("source: set either preset or euroc");
}

Result<Pacing> FromProto(const v1::SimulatorStartRequest& request) {
  Pacing pacing;
  switch (request.pacing_case()) {
    case v1::SimulatorStartRequest::kRealTimeFactor: {
      const double factor = request.real_time_factor();
      if (!std::isfinite(factor) || factor <= 0.0) {
        return Status::InvalidArgument("real_time_factor: must be > 0 and finite, got " +
                                       Number(factor));
      }
      pacing.real_time_factor = factor;
      pacing.as_fast_as_subscribers = false;
      break;
    }
    case v1::SimulatorStartRequest::kAsFastAsSubscribers:
      if (!request.as_fast_as_subscribers()) {
        return Status::InvalidArgument(
            "as_fast_as_subscribers: false is not a pacing; set real_time_factor instead");
      }
      pacing.real_time_factor = 0.0;
      pacing.as_fast_as_subscribers = true;
      break;
    case v1::SimulatorStartRequest::PACING_NOT_SET:
      return Status::InvalidArgument(
          "real_time_factor: no pacing given; set real_time_factor > 0 or "
          "as_fast_as_subscribers");
  }
  const double timeout = request.wait_timeout_s();
  if (!std::isfinite(timeout) || timeout < 0.0) {
    return Status::InvalidArgument("wait_timeout_s: must be >= 0 and finite, got " +
                                   Number(timeout));
  }
  pacing.wait_timeout_s = timeout == 0.0 ? 5.0 : timeout;
  pacing.wait_for_subscribers = request.wait_for_subscribers();
  pacing.loop = request.loop();
  return pacing;
}

void ToProto(const ScenarioInfo& info, v1::ScenarioSummary* out) {
  out->set_name(info.name);
  out->set_is_preset(info.is_preset);
  out->set_frames(info.frames);
  out->set_imu_samples(info.imu_samples);
  out->set_start_t_ns(info.start_t_ns);
  out->set_end_t_ns(info.end_t_ns);
  out->set_camera_rate_hz(info.camera_rate_hz);
  out->set_imu_rate_hz(info.imu_rate_hz);
  out->set_rectified(info.rectified);
  out->set_seed(info.seed);
  out->set_has_ground_truth(info.has_ground_truth);
  out->set_has_ground_truth_occupancy(info.has_ground_truth_occupancy);
  out->set_image_width(static_cast<uint32_t>(info.width));
  out->set_image_height(static_cast<uint32_t>(info.height));
}

v1::SimulatorState ToProto(PlayerState state) {
  switch (state) {
    case PlayerState::kIdle:
      return v1::SIMULATOR_STATE_IDLE;
    case PlayerState::kLoaded:
      return v1::SIMULATOR_STATE_LOADED;
    case PlayerState::kRunning:
      return v1::SIMULATOR_STATE_RUNNING;
    case PlayerState::kPaused:
      return v1::SIMULATOR_STATE_PAUSED;
    case PlayerState::kFinished:
      return v1::SIMULATOR_STATE_FINISHED;
  }
  return v1::SIMULATOR_STATE_UNSPECIFIED;
}

void ToProto(const PlayerStatus& status, v1::SimulatorStatus* out) {
  out->set_state(ToProto(status.state));
  if (status.scenario.has_value()) ToProto(*status.scenario, out->mutable_scenario());
  out->set_next_frame(status.next_frame);
  out->set_frames_published(status.frames_published);
  out->set_imu_samples_published(status.imu_samples_published);
  out->set_ground_truth_published(status.ground_truth_published);
  out->set_current_t_ns(status.current_t_ns);
  out->set_achieved_rate_hz(status.achieved_rate_hz);
  out->set_real_time_factor(status.pacing.as_fast_as_subscribers ? 0.0
                                                                 : status.pacing.real_time_factor);
  out->set_as_fast_as_subscribers(status.pacing.as_fast_as_subscribers);
  out->set_loop(status.pacing.loop);
  out->set_stereo_subscribers(status.stereo_subscribers);
  out->set_imu_subscribers(status.imu_subscribers);
  ToProto(status.render_ms, out->mutable_render_ms());
  ToProto(status.publish_ms, out->mutable_publish_ms());
  out->set_dds_domain(status.dds_domain);
  out->set_dds_shared_memory(status.dds_shared_memory);
  out->set_last_error(status.last_error);
}

void ToProto(const camera::StereoCalibration& calibration, double rate_hz, bool rectified,
             v1::StereoCalibration* out) {
  v1::CameraCalibration* left = out->mutable_left();
  left->set_camera_id("cam0");
  ToProto(calibration.cam0, left->mutable_intrinsics());
  ToProto(calibration.T_body_cam0, left->mutable_t_body_cam());
  left->set_rate_hz(rate_hz);
  v1::CameraCalibration* right = out->mutable_right();
  right->set_camera_id("cam1");
  ToProto(calibration.cam1, right->mutable_intrinsics());
  ToProto(calibration.T_body_cam1, right->mutable_t_body_cam());
  right->set_rate_hz(rate_hz);
  out->set_rectified(rectified);
  out->set_baseline_m(calibration.Baseline());
}

void ToProto(const dataset::ImuNoise& noise, double rate_hz, v1::ImuNoise* out) {
  out->set_gyroscope_noise_density(noise.gyroscope_noise_density);
  out->set_gyroscope_random_walk(noise.gyroscope_random_walk);
  out->set_accelerometer_noise_density(noise.accelerometer_noise_density);
  out->set_accelerometer_random_walk(noise.accelerometer_random_walk);
  out->set_rate_hz(rate_hz);
}

// ---- Flight mode ------------------------------------------------------------------------------

Result<mission::VehicleOptions> FromProto(const v1::MissionFlight& request, uint64_t seed) {
  mission::VehicleOptions v;
  v.seed = seed;
  if (!request.pose_source().empty()) {
    const std::optional<mission::PoseSource> source =
        mission::ParsePoseSource(request.pose_source());
    if (!source) {
      return Status::InvalidArgument("mission.pose_source: '" + request.pose_source() +
                                     "' is not vo, contest or truth");
    }
    v.pose_source = *source;
  }
  v.camera_pitch_rad = request.camera_pitch_rad();
  if (request.camera_rate_hz() != 0.0) v.camera_rate_hz = request.camera_rate_hz();
  if (request.imu_rate_hz() != 0.0) v.imu_rate_hz = request.imu_rate_hz();
  if (std::string why; !v.IsValid(&why)) return Status::InvalidArgument("mission." + why);
  return v;
}

Result<FlightLoadRequest> FromProto(const v1::LoadFlightTaskRequest& request) {
  FlightLoadRequest out;
  switch (request.task_case()) {
    case v1::LoadFlightTaskRequest::kBuiltin:
      out.source = FlightLoadRequest::Source::kBuiltin;
      out.value = request.builtin();
      if (out.value.empty()) return Status::InvalidArgument("builtin: empty task name");
      break;
    case v1::LoadFlightTaskRequest::kYaml:
      out.source = FlightLoadRequest::Source::kYaml;
      out.value = request.yaml();
      if (out.value.empty()) return Status::InvalidArgument("yaml: empty task file");
      break;
    case v1::LoadFlightTaskRequest::kPath:
      out.source = FlightLoadRequest::Source::kPath;
      out.value = request.path();
      if (out.value.empty()) return Status::InvalidArgument("path: empty path");
      break;
    case v1::LoadFlightTaskRequest::kMission: {
      out.source = FlightLoadRequest::Source::kMission;
      MAV_ASSIGN_OR_RETURN(out.vehicle, FromProto(request.mission(), request.seed()));
      const std::string& name = request.mission().source_name();
      MAV_ASSIGN_OR_RETURN(out.mission, dataset::ParseMissionYaml(request.mission().yaml(),
                                                                  name.empty() ? "mission" : name));
      out.config.task = mission::MissionFlightTask(out.mission, out.vehicle);
      if (!request.map_path().empty()) {
        return Status::InvalidArgument(
            "map_path: a mission flies in its world's exact geometry; leave map_path empty");
      }
      break;
    }
    case v1::LoadFlightTaskRequest::TASK_NOT_SET:
      return Status::InvalidArgument("task: set builtin (t3_1 ... t4_3), yaml, path or mission");
  }
  out.map_path = request.map_path();
  FlightConfig& c = out.config;
  c.seed = request.seed();
  c.lockstep = request.lockstep();
  if (request.real_time_factor() != 0.0) c.real_time_factor = request.real_time_factor();
  if (request.lockstep_timeout_s() != 0.0) c.lockstep_timeout_s = request.lockstep_timeout_s();
  if (request.command_stale_s() != 0.0) c.command_stale_s = request.command_stale_s();
  // The ranges (the task is checked once resolved).
  if (std::string why; !c.OptionsValid(&why)) return Status::InvalidArgument(why);
  return out;
}

Result<FlightRun> FromProto(const v1::StartFlightRequest& request) {
  FlightRun run;
  run.until_s = request.run_until_s();
  run.pause_on_goal = request.pause_on_goal();
  if (!std::isfinite(run.until_s) || run.until_s < 0) {
    return Status::InvalidArgument("run_until_s: must be >= 0 and finite, got " +
                                   Number(run.until_s));
  }
  return run;
}

v1::FlightState ToProto(FlightState state) {
  switch (state) {
    case FlightState::kIdle:
      return v1::FLIGHT_STATE_IDLE;
    case FlightState::kLoaded:
      return v1::FLIGHT_STATE_LOADED;
    case FlightState::kRunning:
      return v1::FLIGHT_STATE_RUNNING;
    case FlightState::kPaused:
      return v1::FLIGHT_STATE_PAUSED;
    case FlightState::kFinished:
      return v1::FLIGHT_STATE_FINISHED;
  }
  return v1::FLIGHT_STATE_UNSPECIFIED;
}

void ToProto(const FlightConfig& config, v1::FlightTaskSummary* out) {
  const dataset::FlightTask& task = config.task;
  out->set_name(task.name);
  out->set_kind(dataset::FlightTaskKindName(task.kind));
  out->set_duration_s(task.duration_s);
  out->set_imu_rate_hz(task.imu.rate_hz);
  for (size_t i = 0; i < task.pose_sensors.size(); ++i) {
    const dataset::FlightPoseSensorSpec& spec = task.pose_sensors[i];
    v1::FlightPoseSensorInfo* info = out->add_pose_sensors();
    info->set_frame_id("pose_sensor" + std::to_string(i));
    info->set_rate_hz(spec.rate_hz);
    info->set_delay_s(spec.delay_s);
    info->set_position_sigma_m(spec.position_sigma_m);
    info->set_orientation_sigma_rad(spec.orientation_sigma_rad);
    ToProto(spec.T_body_sensor(), info->mutable_t_body_sensor());
  }
  for (const dataset::FlightGoal& goal : task.goals) {
    v1::FlightGoalInfo* info = out->add_goals();
    info->set_publish_s(goal.publish_s);
    ToProto(goal.position, info->mutable_position());
    info->set_yaw_rad(goal.yaw_rad);
  }
  ToProto(task.takeoff_position, out->mutable_takeoff_position());
  out->set_map_path(task.map_path);
  out->set_seed(config.seed);
  out->set_lockstep(config.lockstep);
  out->set_real_time_factor(config.lockstep ? 0.0 : config.real_time_factor);
  out->set_lockstep_timeout_s(config.lockstep_timeout_s);
  out->set_command_stale_s(config.command_stale_s);
  out->set_rotor_count(static_cast<uint32_t>(config.simulation.vehicle.rotor_count));
}

void ToProto(const eval::TaskScore& score, v1::FlightScore* out) {
  out->set_points(score.points);
  out->set_max_points(score.max_points);
  out->set_position_rms_m(score.position_rms_m);
  out->set_angular_rate_rms_radps(score.angular_rate_rms_radps);
  out->set_settling_time_s(score.settling_time_s);
  out->set_all_settled(score.all_settled);
  out->set_collisions(static_cast<uint32_t>(score.collisions));
  for (const eval::GoalScore& g : score.goals) {
    v1::FlightGoalScore* o = out->add_goals();
    o->set_goal(g.goal);
    o->set_from_s(g.from_s);
    o->set_settled(g.settled);
    o->set_settling_time_s(g.settling_time_s);
    o->set_window_start_s(g.window_start_s);
    o->set_position_rms_m(g.rms.position_rms_m);
    o->set_angular_rate_rms_radps(g.rms.angular_rate_rms_radps);
    o->set_position_points(g.position_points);
    o->set_angular_rate_points(g.angular_rate_points);
    o->set_settling_points(g.settling_points);
    o->set_flight_time_s(g.flight_time_s);
    o->set_mean_speed_mps(g.mean_speed_mps);
    o->set_peak_speed_mps(g.peak_speed_mps);
    o->set_path_length_m(g.path_length_m);
  }
}

void ToProto(const FlightStatus& status, v1::FlightStatus* out) {
  out->set_state(ToProto(status.state));
  if (status.config.has_value()) ToProto(*status.config, out->mutable_task());
  out->set_t_ns(status.t_ns);
  out->set_steps(status.steps);
  out->set_imu_published(status.imu_published);
  out->set_poses_published(status.poses_published);
  out->set_ground_truth_published(status.ground_truth_published);
  out->set_commands_received(status.commands_received);
  out->set_commands_rejected(status.commands_rejected);
  out->set_stale_steps(status.stale_steps);
  out->set_failsafe_active(status.failsafe_active);
  out->set_failsafe_engagements(status.failsafe_engagements);
  out->set_failsafe_s(status.failsafe_s);
  out->set_goal_index(status.goal_index);
  for (const sim::Collision& c : status.collisions) {
    v1::FlightCollision* o = out->add_collisions();
    o->set_t_s(NsToSeconds(c.t_ns));
    ToProto(c.p_world, o->mutable_position());
    o->set_what(c.what);
  }
  out->set_lifted_off(status.lifted_off);
  ToProto(status.position, out->mutable_position());
  out->set_speed_factor(status.speed_factor);
  ToProto(status.step_ms, out->mutable_step_ms());
  ToProto(status.command_wait_ms, out->mutable_command_wait_ms());
  out->set_pause_reason(status.pause_reason);
  out->set_last_error(status.last_error);
  out->set_last_error_age_s(status.last_error_age_s);
  if (status.score.has_value()) ToProto(*status.score, out->mutable_score());
  out->set_min_clearance_m(status.min_clearance_m);
  out->set_actuator_writers(status.actuator_writers);
  out->set_dds_domain(status.dds_domain);
  v1::GroundTruthState* truth = out->mutable_truth();
  truth->set_t_ns(status.t_ns);
  ToProto(geometry::SE3(status.truth.q_world_body, status.truth.p_world),
          truth->mutable_t_world_body());
  ToProto(status.truth.v_world, truth->mutable_velocity());
  ToProto(status.gyro_offset, truth->mutable_gyro_bias());
  ToProto(status.accel_offset, truth->mutable_accel_bias());
  ToProto(status.truth.omega_body, truth->mutable_angular_velocity());
  out->set_frames_published(status.frames_published);
  ToProto(status.render_ms, out->mutable_render_ms());
  out->set_stereo_subscribers(status.stereo_readers);
}

}  // namespace mav::simulator_service
