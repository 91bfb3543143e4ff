#include "mav/sim/flight_task.h"

#include <cstdlib>

#include "mav/common/text.h"
#include "mav/dataset/flight_task_io.h"

namespace mav::sim {

using dataset::FlightGoal;
using dataset::FlightTask;
using dataset::FlightTaskKind;

const std::vector<std::string>& FlightTaskNames() {
  static const std::vector<std::string> kNames = {"t3_1", "t3_2", "t3_3", "t4_1", "t4_2", "t4_3"};
  return kNames;
}

namespace {

FlightTask Hover(const std::string& name) {
  FlightTask t;
  t.name = name;
  t.kind = FlightTaskKind::kHover;
  t.duration_s = 30;
  t.spawn_position = Eigen::Vector3d(0, 0, 0.08);
  t.takeoff_position = Eigen::Vector3d(0, 0, 1);
  t.goals = {FlightGoal{10, Eigen::Vector3d(0, 0, 1), 0}};
  return t;
}

FlightTask Waypoints(const std::string& name, const std::vector<Eigen::Vector3d>& points,
                     double interval_s) {
  FlightTask t;
  t.name = name;
  t.kind = FlightTaskKind::kWaypoints;
  t.spawn_position = Eigen::Vector3d(0, 0, 0.08);
  t.takeoff_position = Eigen::Vector3d(0, 0, 1);
  for (size_t i = 0; i < points.size(); ++i) {
    t.goals.push_back(FlightGoal{10 + interval_s * static_cast<double>(i), points[i], 0});
  }
  t.duration_s = 10 + interval_s * static_cast<double>(points.size());
  return t;
}

}  // namespace

std::string DefaultPlantMapPath() {
  const char* env = std::getenv("MAV_PLANT_MAP");
  if (env != nullptr && env[0] != '\0') return env;
  return MAV_PLANT_MAP_DEFAULT;
}

Result<FlightTask> BuiltinFlightTask(const std::string& name, const std::string& plant_map_path) {
  if (name == "t3_1") return Hover(name);
  if (name == "t3_2" || name == "t3_3") {
    FlightTask t = Hover(name);
    t.kind = FlightTaskKind::kDisturbance;
    // Settling may take 10 s and the window 10 s more: 60 s covers every scored second.
    t.duration_s = 65;
    if (name == "t3_2") {
      t.forces = {{2.0 * Eigen::Vector3d(1, 1, -0.3).normalized(), 40, 240}};
    } else {
      t.forces = {{5.0 * Eigen::Vector3d(1, 1, 0).normalized(), 40, 42}};
    }
    return t;
  }
  const std::vector<Eigen::Vector3d> t4 = {{20, 0, 9}, {20, 20, 1}, {0, 20, 9}, {0, 0, 1}};
  if (name == "t4_1") return Waypoints(name, t4, 60);
  if (name == "t4_2") {
    FlightTask t = Waypoints(name, t4, 60);
    dataset::FlightPoseSensorSpec second;
    second.rate_hz = 20;
    second.delay_s = 0.08;
    second.stamp_offset_s = 0.001;
    second.mount_xyz_m = Eigen::Vector3d(-0.05, 0.08, 0.1);
    second.mount_rpy_rad = Eigen::Vector3d(-0.1, 0.2, -0.3);
    t.pose_sensors.push_back(second);
    return t;
  }
  if (name == "t4_3") {
    FlightTask t = Waypoints(name, {{2, -27, 15}, {20, -15, 15}, {25, 0, 5}, {0, 0, 1}}, 110);
    t.kind = FlightTaskKind::kPlannedLegs;
    // The map's ground voxels fill z in [0, 0.25); the contest spawned the body at 0.18 m.
    t.spawn_position = Eigen::Vector3d(0, 0, 0.18);
    t.ground_z_m = 0.10;
    t.takeoff_position = Eigen::Vector3d(0, 0, 2);
    t.map_path = plant_map_path;
    return t;
  }
  std::string known;
  for (const std::string& n : FlightTaskNames()) known += (known.empty() ? "" : ", ") + n;
  return Status::NotFound("task: unknown flight task " + QuoteForError(name) + " (known: " + known +
                          ")");
}

Result<FlightTask> FlightTaskFromSpec(const std::string& name_or_file,
                                      const std::string& plant_map_path) {
  const dataset::FlightTaskResolver resolve = [plant_map_path](const std::string& name) {
    return BuiltinFlightTask(name, plant_map_path);
  };
  const bool is_file =
      name_or_file.size() > 5 && name_or_file.compare(name_or_file.size() - 5, 5, ".yaml") == 0;
  if (is_file) return dataset::ReadFlightTaskFile(name_or_file, resolve, "t3_1");
  return resolve(name_or_file);
}

}  // namespace mav::sim
