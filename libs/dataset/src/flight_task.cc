#include "mav/dataset/flight_task.h"

#include <cmath>

namespace mav::dataset {

geometry::SE3 FlightPoseSensorSpec::T_body_sensor() const {
  return geometry::SE3(
      geometry::RotationFromRollPitchYaw(mount_rpy_rad.x(), mount_rpy_rad.y(), mount_rpy_rad.z()),
      mount_xyz_m);
}

const char* FlightTaskKindName(FlightTaskKind kind) {
  switch (kind) {
    case FlightTaskKind::kHover:
      return "hover";
    case FlightTaskKind::kDisturbance:
      return "disturbance";
    case FlightTaskKind::kWaypoints:
      return "waypoints";
    case FlightTaskKind::kPlannedLegs:
      return "planned_legs";
  }
  return "?";
}

namespace {

bool Fail(std::string* why, const std::string& m) {
  if (why) *why = m;
  return false;
}
bool Positive(double x) { return x > 0 && std::isfinite(x); }
bool NonNegative(double x) { return x >= 0 && std::isfinite(x); }

}  // namespace

bool FlightTask::IsValid(std::string* why) const {
  if (!Positive(duration_s) || duration_s > 7200) {
    return Fail(why, "duration_s: must be in (0, 7200]");
  }
  if (!spawn_position.allFinite()) return Fail(why, "spawn.position: must be finite");
  if (!std::isfinite(spawn_yaw_rad)) return Fail(why, "spawn.yaw_rad: must be finite");
  if (!std::isfinite(ground_z_m) || spawn_position.z() < ground_z_m) {
    return Fail(why, "ground_z_m: must be finite and not above spawn.position");
  }
  if (!takeoff_position.allFinite()) return Fail(why, "takeoff_position: must be finite");
  if (goals.empty()) return Fail(why, "goals: at least one goal");
  for (size_t i = 0; i < goals.size(); ++i) {
    const std::string f = "goals[" + std::to_string(i) + "].";
    if (!NonNegative(goals[i].publish_s) || goals[i].publish_s >= duration_s) {
      return Fail(why, f + "publish_s: must be in [0, duration_s)");
    }
    if (i > 0 && goals[i].publish_s <= goals[i - 1].publish_s) {
      return Fail(why, f + "publish_s: goals must be published in increasing time");
    }
    if (!goals[i].position.allFinite()) return Fail(why, f + "position: must be finite");
    if (!std::isfinite(goals[i].yaw_rad)) return Fail(why, f + "yaw_rad: must be finite");
  }
  for (size_t i = 0; i < forces.size(); ++i) {
    const std::string f = "forces[" + std::to_string(i) + "].";
    if (!forces[i].force_world_n.allFinite() || forces[i].force_world_n.norm() > 100) {
      return Fail(why, f + "force_n: must be finite and at most 100 N");
    }
    if (!NonNegative(forces[i].start_s)) return Fail(why, f + "start_s: must be >= 0");
    if (!(forces[i].end_s > forces[i].start_s)) return Fail(why, f + "end_s: must exceed start_s");
  }
  if (kind == FlightTaskKind::kDisturbance && forces.empty()) {
    return Fail(why, "forces: a disturbance task needs at least one force");
  }
  if (!Positive(imu.rate_hz) || imu.rate_hz > 2000) return Fail(why, "imu.rate_hz: (0, 2000]");
  if (!imu.accel_offset.allFinite()) return Fail(why, "imu.accel_offset: must be finite");
  if (!imu.gyro_offset.allFinite()) return Fail(why, "imu.gyro_offset: must be finite");
  if (!NonNegative(imu.accel_noise_sigma)) return Fail(why, "imu.accel_noise_sigma: must be >= 0");
  if (!NonNegative(imu.gyro_noise_sigma)) return Fail(why, "imu.gyro_noise_sigma: must be >= 0");
  if (!NonNegative(imu.accel_drift_sigma)) return Fail(why, "imu.accel_drift_sigma: must be >= 0");
  if (!NonNegative(imu.gyro_drift_sigma)) return Fail(why, "imu.gyro_drift_sigma: must be >= 0");
  if (!Positive(imu.drift_horizon_s)) return Fail(why, "imu.drift_horizon_s: must be positive");
  if (pose_sensors.empty()) return Fail(why, "pose_sensors: at least one pose sensor");
  for (size_t i = 0; i < pose_sensors.size(); ++i) {
    const FlightPoseSensorSpec& s = pose_sensors[i];
    const std::string f = "pose_sensors[" + std::to_string(i) + "].";
    if (!Positive(s.rate_hz) || s.rate_hz > imu.rate_hz) {
      return Fail(why, f + "rate_hz: must be in (0, imu.rate_hz]");
    }
    if (!NonNegative(s.delay_s) || s.delay_s > 0.5) return Fail(why, f + "delay_s: [0, 0.5]");
    if (!std::isfinite(s.stamp_offset_s) || std::abs(s.stamp_offset_s) > 0.1) {
      return Fail(why, f + "stamp_offset_s: must be in [-0.1, 0.1]");
    }
    if (!NonNegative(s.position_sigma_m)) return Fail(why, f + "position_sigma_m: must be >= 0");
    if (!NonNegative(s.orientation_sigma_rad)) {
      return Fail(why, f + "orientation_sigma_rad: must be >= 0");
    }
    if (!s.mount_xyz_m.allFinite()) return Fail(why, f + "mount_xyz_m: must be finite");
    if (!s.mount_rpy_rad.allFinite()) return Fail(why, f + "mount_rpy_rad: must be finite");
    if (!NonNegative(s.active_from_s) || !(s.active_until_s > s.active_from_s)) {
      return Fail(why, f + "active_from_s/active_until_s: need 0 <= from < until");
    }
  }
  if (!Positive(vehicle_radius_m) || vehicle_radius_m > 2) {
    return Fail(why, "vehicle_radius_m: must be in (0, 2]");
  }
  const FlightScoring& sc = scoring;
  if (!Positive(sc.window_s)) return Fail(why, "scoring.window_s: must be positive");
  if (!NonNegative(sc.hover_delay_s)) return Fail(why, "scoring.hover_delay_s: must be >= 0");
  if (!Positive(sc.settle_radius_m)) return Fail(why, "scoring.settle_radius_m: must be positive");
  if (!NonNegative(sc.settle_hold_s)) return Fail(why, "scoring.settle_hold_s: must be >= 0");
  if (!Positive(sc.settle_limit_s)) return Fail(why, "scoring.settle_limit_s: must be positive");
  if (!Positive(sc.position_limit_m)) return Fail(why, "scoring.position_limit_m: must be > 0");
  if (!Positive(sc.angular_rate_limit_radps)) {
    return Fail(why, "scoring.angular_rate_limit_radps: must be positive");
  }
  return true;
}

}  // namespace mav::dataset
