// yaml-cpp throws; every call into it is inside Parse's try block, and errors leave as Status.
#include "mav/dataset/flight_task_io.h"

#include <filesystem>

#include <yaml-cpp/yaml.h>

#include "mav/common/file.h"
#include "yaml_fields.h"

namespace mav::dataset {
namespace {

using Reader = internal::YamlFields;

Status ParseImu(const Reader& r, const YAML::Node& n, FlightImuSpec* imu) {
  MAV_RETURN_IF_ERROR(r.CheckKeys(
      n, "imu",
      {"rate_hz", "accel_offset", "gyro_offset", "accel_noise_sigma", "gyro_noise_sigma",
       "accel_drift_sigma", "gyro_drift_sigma", "drift_horizon_s"}));
  MAV_RETURN_IF_ERROR(r.Double(n, "imu", "rate_hz", &imu->rate_hz));
  MAV_RETURN_IF_ERROR(r.Vector(n, "imu", "accel_offset", &imu->accel_offset));
  MAV_RETURN_IF_ERROR(r.Vector(n, "imu", "gyro_offset", &imu->gyro_offset));
  MAV_RETURN_IF_ERROR(r.Double(n, "imu", "accel_noise_sigma", &imu->accel_noise_sigma));
  MAV_RETURN_IF_ERROR(r.Double(n, "imu", "gyro_noise_sigma", &imu->gyro_noise_sigma));
  MAV_RETURN_IF_ERROR(r.Double(n, "imu", "accel_drift_sigma", &imu->accel_drift_sigma));
  MAV_RETURN_IF_ERROR(r.Double(n, "imu", "gyro_drift_sigma", &imu->gyro_drift_sigma));
  return r.Double(n, "imu", "drift_horizon_s", &imu->drift_horizon_s);
}

Status ParsePoseSensor(const Reader& r, const YAML::Node& n, const std::string& p,
                       FlightPoseSensorSpec* s) {
  MAV_RETURN_IF_ERROR(r.CheckKeys(
      n, p,
      {"rate_hz", "delay_s", "stamp_offset_s", "position_sigma_m", "orientation_sigma_rad",
       "mount_xyz_m", "mount_rpy_rad", "active_from_s", "active_until_s"}));
  MAV_RETURN_IF_ERROR(r.Double(n, p, "rate_hz", &s->rate_hz));
  MAV_RETURN_IF_ERROR(r.Double(n, p, "delay_s", &s->delay_s));
  MAV_RETURN_IF_ERROR(r.Double(n, p, "stamp_offset_s", &s->stamp_offset_s));
  MAV_RETURN_IF_ERROR(r.Double(n, p, "position_sigma_m", &s->position_sigma_m));
  MAV_RETURN_IF_ERROR(r.Double(n, p, "orientation_sigma_rad", &s->orientation_sigma_rad));
  MAV_RETURN_IF_ERROR(r.Vector(n, p, "mount_xyz_m", &s->mount_xyz_m));
  MAV_RETURN_IF_ERROR(r.Vector(n, p, "mount_rpy_rad", &s->mount_rpy_rad));
  MAV_RETURN_IF_ERROR(r.Double(n, p, "active_from_s", &s->active_from_s));
  return r.Double(n, p, "active_until_s", &s->active_until_s);
}

Status ParseForce(const Reader& r, const YAML::Node& n, const std::string& p, ForceWindow* f) {
  MAV_RETURN_IF_ERROR(
      r.CheckKeys(n, p, {"force_n", "magnitude_n", "direction", "start_s", "end_s"}));
  const bool by_vector = static_cast<bool>(n["force_n"]);
  const bool by_magnitude = n["magnitude_n"] || n["direction"];
  if (by_vector == by_magnitude) {
    return Reader::Bad(p, "give either force_n or magnitude_n + direction");
  }
  if (by_vector) {
    MAV_RETURN_IF_ERROR(r.Vector(n, p, "force_n", &f->force_world_n));
  } else {
    double magnitude = 0;
    Eigen::Vector3d direction = Eigen::Vector3d::Zero();
    if (!n["magnitude_n"] || !n["direction"]) {
      return Reader::Bad(p, "magnitude_n and direction go together");
    }
    MAV_RETURN_IF_ERROR(r.Double(n, p, "magnitude_n", &magnitude));
    MAV_RETURN_IF_ERROR(r.Vector(n, p, "direction", &direction));
    if (!(direction.norm() > 0)) return Reader::Bad(p + ".direction", "must not be zero");
    f->force_world_n = magnitude * direction.normalized();
  }
  MAV_RETURN_IF_ERROR(r.Double(n, p, "start_s", &f->start_s));
  return r.Double(n, p, "end_s", &f->end_s);
}

Status ParseScoring(const Reader& r, const YAML::Node& n, FlightScoring* s) {
  const std::string p = "scoring";
  MAV_RETURN_IF_ERROR(
      r.CheckKeys(n, p,
                  {"window_s", "hover_delay_s", "settle_radius_m", "settle_hold_s",
                   "settle_limit_s", "position_limit_m", "angular_rate_limit_radps"}));
  MAV_RETURN_IF_ERROR(r.Double(n, p, "window_s", &s->window_s));
  MAV_RETURN_IF_ERROR(r.Double(n, p, "hover_delay_s", &s->hover_delay_s));
  MAV_RETURN_IF_ERROR(r.Double(n, p, "settle_radius_m", &s->settle_radius_m));
  MAV_RETURN_IF_ERROR(r.Double(n, p, "settle_hold_s", &s->settle_hold_s));
  MAV_RETURN_IF_ERROR(r.Double(n, p, "settle_limit_s", &s->settle_limit_s));
  MAV_RETURN_IF_ERROR(r.Double(n, p, "position_limit_m", &s->position_limit_m));
  return r.Double(n, p, "angular_rate_limit_radps", &s->angular_rate_limit_radps);
}

Status ParseGoals(const Reader& r, const YAML::Node& root, FlightTask* task) {
  if (root["goals"] && root["waypoints"]) {
    return Reader::Bad("goals", "give goals or waypoints, not both");
  }
  if (const YAML::Node goals = root["goals"]) {
    if (!goals.IsSequence() || goals.size() == 0) {
      return Reader::Bad("goals", "expected a non-empty list");
    }
    task->goals.clear();
    for (size_t i = 0; i < goals.size(); ++i) {
      const std::string p = "goals[" + std::to_string(i) + "]";
      MAV_RETURN_IF_ERROR(r.CheckKeys(goals[i], p, {"publish_s", "position", "yaw_rad"}));
      FlightGoal g;
      if (!goals[i]["position"]) return Reader::Bad(p + ".position", "missing");
      MAV_RETURN_IF_ERROR(r.Double(goals[i], p, "publish_s", &g.publish_s));
      MAV_RETURN_IF_ERROR(r.Vector(goals[i], p, "position", &g.position));
      MAV_RETURN_IF_ERROR(r.Double(goals[i], p, "yaw_rad", &g.yaw_rad));
      task->goals.push_back(g);
    }
  }
  double interval =
      task->goals.size() > 1 ? task->goals[1].publish_s - task->goals[0].publish_s : 60.0;
  double first = task->goals.empty() ? 0.0 : task->goals[0].publish_s;
  MAV_RETURN_IF_ERROR(r.Double(root, "", "waypoint_interval_s", &interval));
  MAV_RETURN_IF_ERROR(r.Double(root, "", "waypoint_start_s", &first));
  if (const YAML::Node wps = root["waypoints"]) {
    if (!wps.IsSequence() || wps.size() == 0) {
      return Reader::Bad("waypoints", "expected a non-empty list of [x, y, z]");
    }
    const double yaw = task->goals.empty() ? 0.0 : task->goals[0].yaw_rad;
    task->goals.clear();
    for (size_t i = 0; i < wps.size(); ++i) {
      FlightGoal g;
      MAV_RETURN_IF_ERROR(r.Vector(wps[i], "waypoints[" + std::to_string(i) + "]", &g.position));
      g.publish_s = first + static_cast<double>(i) * interval;
      g.yaw_rad = yaw;
      task->goals.push_back(g);
    }
  } else if (root["waypoint_interval_s"] || root["waypoint_start_s"]) {
    for (size_t i = 0; i < task->goals.size(); ++i) {
      task->goals[i].publish_s = first + static_cast<double>(i) * interval;
    }
  }
  if (const YAML::Node sp = root["setpoint"]) {
    if (task->goals.size() != 1) {
      return Reader::Bad("setpoint", "only for tasks with a single goal (use goals)");
    }
    MAV_RETURN_IF_ERROR(r.Vector(sp, "setpoint", &task->goals[0].position));
  }
  return Status::Ok();
}

Status Apply(const Reader& r, const YAML::Node& root, const std::string& folder, FlightTask* task) {
  MAV_RETURN_IF_ERROR(r.CheckKeys(
      root, "",
      {"base", "name", "duration_s", "setpoint", "goals", "waypoints", "waypoint_interval_s",
       "waypoint_start_s", "spawn", "ground_z_m", "takeoff_position", "forces", "imu",
       "pose_sensors", "pose_sensor_count", "map", "vehicle_radius_m", "scoring"}));
  if (const YAML::Node n = root["name"]) {
    if (!n.IsScalar() || n.Scalar().empty()) return Reader::Bad("name", "expected a name");
    task->name = n.Scalar();
  }
  MAV_RETURN_IF_ERROR(r.Double(root, "", "duration_s", &task->duration_s));
  MAV_RETURN_IF_ERROR(ParseGoals(r, root, task));
  if (const YAML::Node n = root["spawn"]) {
    MAV_RETURN_IF_ERROR(r.CheckKeys(n, "spawn", {"position", "yaw_rad"}));
    MAV_RETURN_IF_ERROR(r.Vector(n, "spawn", "position", &task->spawn_position));
    MAV_RETURN_IF_ERROR(r.Double(n, "spawn", "yaw_rad", &task->spawn_yaw_rad));
  }
  MAV_RETURN_IF_ERROR(r.Double(root, "", "ground_z_m", &task->ground_z_m));
  MAV_RETURN_IF_ERROR(r.Vector(root, "", "takeoff_position", &task->takeoff_position));
  if (const YAML::Node n = root["forces"]) {
    if (!n.IsSequence()) return Reader::Bad("forces", "expected a list");
    task->forces.clear();
    for (size_t i = 0; i < n.size(); ++i) {
      ForceWindow f;
      MAV_RETURN_IF_ERROR(ParseForce(r, n[i], "forces[" + std::to_string(i) + "]", &f));
      task->forces.push_back(f);
    }
  }
  if (const YAML::Node n = root["imu"]) MAV_RETURN_IF_ERROR(ParseImu(r, n, &task->imu));
  if (const YAML::Node n = root["pose_sensors"]) {
    if (!n.IsSequence()) return Reader::Bad("pose_sensors", "expected a list");
    for (size_t i = 0; i < n.size(); ++i) {
      if (i >= task->pose_sensors.size()) task->pose_sensors.push_back(task->pose_sensors[0]);
      MAV_RETURN_IF_ERROR(ParsePoseSensor(r, n[i], "pose_sensors[" + std::to_string(i) + "]",
                                          &task->pose_sensors[i]));
    }
  }
  if (root["pose_sensor_count"]) {
    double count = 0;
    MAV_RETURN_IF_ERROR(r.Double(root, "", "pose_sensor_count", &count));
    if (count < 1 || count > static_cast<double>(task->pose_sensors.size()) ||
        count != static_cast<int>(count)) {
      return Reader::Bad("pose_sensor_count", "must be an integer in [1, " +
                                                  std::to_string(task->pose_sensors.size()) + "]");
    }
    task->pose_sensors.resize(static_cast<size_t>(count));
  }
  if (const YAML::Node n = root["map"]) {
    if (!n.IsScalar()) return Reader::Bad("map", "expected a path");
    const std::filesystem::path p(n.Scalar());
    task->map_path = p.is_absolute() || n.Scalar().empty()
                         ? n.Scalar()
                         : (std::filesystem::path(folder) / p).lexically_normal().string();
  }
  MAV_RETURN_IF_ERROR(r.Double(root, "", "vehicle_radius_m", &task->vehicle_radius_m));
  if (const YAML::Node n = root["scoring"]) {
    MAV_RETURN_IF_ERROR(ParseScoring(r, n, &task->scoring));
  }
  return Status::Ok();
}

}  // namespace

Result<FlightTask> ParseFlightTaskYaml(const std::string& text, const std::string& source,
                                       const FlightTaskResolver& resolve,
                                       const std::string& default_base) {
  const std::string folder = std::filesystem::path(source).parent_path().string();
  FlightTask task;
  Status status;
  try {
    const YAML::Node root = YAML::Load(text);
    if (!root.IsMap()) return Status::InvalidArgument(source + ": expected a YAML mapping");
    std::string base = default_base;
    if (const YAML::Node b = root["base"]) {
      if (!b.IsScalar()) return Status::InvalidArgument(source + ": base: expected a task name");
      base = b.Scalar();
    }
    if (base.empty()) {
      return Status::InvalidArgument(source + ": base: no base task (give base: or --task)");
    }
    Result<FlightTask> resolved = resolve(base);
    if (!resolved.ok()) return resolved.status().WithContext(source + ": base");
    task = std::move(resolved).value();
    status = Apply(Reader(), root, folder, &task);
  } catch (const YAML::Exception& e) {
    return Status::InvalidArgument(source + ": not valid YAML: " + e.what());
  }
  if (!status.ok()) return status.WithContext(source);
  if (std::string why; !task.IsValid(&why)) {
    return Status::InvalidArgument(source + ": " + why);
  }
  return task;
}

Result<FlightTask> ReadFlightTaskFile(const std::string& path, const FlightTaskResolver& resolve,
                                      const std::string& default_base) {
  MAV_ASSIGN_OR_RETURN(const std::string text, ReadFileToString(path));
  return ParseFlightTaskYaml(text, path, resolve, default_base);
}

}  // namespace mav::dataset
