#include "mav/dataset/flight_task_io.h"

#include <gtest/gtest.h>

namespace mav::dataset {
namespace {

// A stand-in for the simulator's built-in tasks.
Result<FlightTask> Builtin(const std::string& name) {
  if (name != "t3_2" && name != "t4_1") return Status::NotFound("unknown task '" + name + "'");
  FlightTask t;
  t.name = name;
  t.kind = name == "t3_2" ? FlightTaskKind::kDisturbance : FlightTaskKind::kWaypoints;
  t.duration_s = name == "t3_2" ? 65 : 250;
  t.goals = {{10, Eigen::Vector3d(0, 0, 1), 0}};
  if (name == "t4_1") t.goals.push_back({70, Eigen::Vector3d(20, 0, 9), 0});
  t.forces = {{Eigen::Vector3d(1.38, 1.38, -0.41), 40, 240}};
  return t;
}

Result<FlightTask> Parse(const std::string& yaml, const std::string& base = "t3_2") {
  return ParseFlightTaskYaml(yaml, "dir/f.yaml", Builtin, base);
}

TEST(FlightTaskIoTest, GoodFileOverridesEveryKindOfFigure) {
  const Result<FlightTask> t = Parse(R"(
name: strong_wind
duration_s: 80
setpoint: [0.5, -0.5, 1.5]
spawn: {position: [0.5, -0.5, 0.08], yaw_rad: 0.3}
forces:
  - {magnitude_n: 4, direction: [0, 1, 0], start_s: 30, end_s: 60}
  - {force_n: [0, 0, -1], start_s: 35}
imu: {rate_hz: 200, accel_offset: [0, 0, 0.5], gyro_noise_sigma: 0.001, drift_horizon_s: 120}
pose_sensors:
  - {rate_hz: 20, delay_s: 0.05, position_sigma_m: 0.005, mount_rpy_rad: [0, 0, 0]}
  - {rate_hz: 10, delay_s: 0.2, stamp_offset_s: 0.002, active_until_s: 50}
map: maps/plant.bt
vehicle_radius_m: 0.4
scoring: {settle_radius_m: 0.15, window_s: 5}
)");
  ASSERT_TRUE(t.ok()) << t.status().ToString();
  EXPECT_EQ(t->name, "strong_wind");
  EXPECT_EQ(t->duration_s, 80);
  EXPECT_EQ(t->goals[0].position, Eigen::Vector3d(0.5, -0.5, 1.5));
  EXPECT_EQ(t->spawn_yaw_rad, 0.3);
  ASSERT_EQ(t->forces.size(), 2u);
  EXPECT_LT((t->forces[0].force_world_n - Eigen::Vector3d(0, 4, 0)).norm(), 1e-12);
  EXPECT_EQ(t->forces[1].end_s, kForever);
  EXPECT_EQ(t->imu.rate_hz, 200);
  EXPECT_EQ(t->imu.accel_offset, Eigen::Vector3d(0, 0, 0.5));
  EXPECT_EQ(t->imu.gyro_noise_sigma, 0.001);
  EXPECT_EQ(t->imu.accel_noise_sigma, 0.04);  // untouched figures keep the base's values
  ASSERT_EQ(t->pose_sensors.size(), 2u);
  EXPECT_EQ(t->pose_sensors[0].rate_hz, 20);
  EXPECT_EQ(t->pose_sensors[0].mount_rpy_rad, Eigen::Vector3d::Zero());
  EXPECT_EQ(t->pose_sensors[0].mount_xyz_m, Eigen::Vector3d(0.03, -0.07, 0.1));
  EXPECT_EQ(t->pose_sensors[1].stamp_offset_s, 0.002);
  EXPECT_EQ(t->pose_sensors[1].active_until_s, 50);
  EXPECT_EQ(t->map_path, "dir/maps/plant.bt");  // relative to the task file
  EXPECT_EQ(t->vehicle_radius_m, 0.4);
  EXPECT_EQ(t->scoring.settle_radius_m, 0.15);
  EXPECT_EQ(t->scoring.window_s, 5);
}

TEST(FlightTaskIoTest, BaseAndWaypoints) {
  const Result<FlightTask> t = Parse(R"(
base: t4_1
waypoints: [[1, 2, 3], [4, 5, 6], [7, 8, 9]]
waypoint_interval_s: 30
waypoint_start_s: 5
)",
                                     "");
  ASSERT_TRUE(t.ok()) << t.status().ToString();
  EXPECT_EQ(t->kind, FlightTaskKind::kWaypoints);
  ASSERT_EQ(t->goals.size(), 3u);
  EXPECT_EQ(t->goals[2].publish_s, 65);
  EXPECT_EQ(t->goals[2].position, Eigen::Vector3d(7, 8, 9));
}

TEST(FlightTaskIoTest, UnknownKeyNamesFileAndKey) {
  Result<FlightTask> t = Parse("duration_s: 80\nwind: 3\n");
  ASSERT_FALSE(t.ok());
  EXPECT_EQ(t.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(t.status().message().find("dir/f.yaml"), std::string::npos);
  EXPECT_NE(t.status().message().find("wind: unknown key"), std::string::npos);
  t = Parse("imu: {rate: 100}\n");
  ASSERT_FALSE(t.ok());
  EXPECT_NE(t.status().message().find("imu.rate: unknown key"), std::string::npos);
  // A key that is no key is quoted and truncated, not echoed whole (found by the fuzzer: a 1 KB
  // mapping key made a 1 KB message).
  t = Parse("imu:\n  " + std::string(1000, '3') + ": 1\n");  // YAML's longest implicit key
  ASSERT_FALSE(t.ok());
  EXPECT_LT(t.status().message().size(), 300u) << t.status().message().substr(0, 400);
  EXPECT_NE(t.status().message().find("(1000 bytes): unknown key"), std::string::npos)
      << t.status().message().substr(0, 400);
  t = Parse("pose_sensors:\n  - {rate_hz: 10}\n  - {delay: 0.1}\n");
  ASSERT_FALSE(t.ok());
  EXPECT_NE(t.status().message().find("pose_sensors[1].delay"), std::string::npos);
}

TEST(FlightTaskIoTest, BadValuesNameFileAndKey) {
  struct Case {
    const char* yaml;
    const char* key;
  } cases[] = {
      {"duration_s: long\n", "duration_s"},
      {"forces:\n  - {force_n: [1, 2], start_s: 1}\n", "forces[0].force_n"},
      {"forces:\n  - {magnitude_n: 2, direction: [0, 0, 0]}\n", "forces[0].direction"},
      {"forces:\n  - {force_n: [1, 2, 3], start_s: x}\n", "forces[0].start_s"},
      {"forces:\n  - {force_n: [1, 2, 3], start_s: 5, end_s: 4}\n", "forces[0].end_s"},
      {"imu: {rate_hz: -5}\n", "imu.rate_hz"},
      {"pose_sensors:\n  - {delay_s: 2}\n", "pose_sensors[0].delay_s"},
      {"spawn: {position: [0, 0, -1]}\n", "ground_z_m"},
      {"setpoint: [0, 0]\n", "setpoint"},
      {"scoring: {window_s: 0}\n", "scoring.window_s"},
      {"pose_sensor_count: 3\n", "pose_sensor_count"},
      {"[1, 2]\n", "expected a YAML mapping"},
      {"duration_s: [\n", "not valid YAML"},
      {"base: t9_9\n", "base"},
  };
  for (const Case& c : cases) {
    const Result<FlightTask> t = Parse(c.yaml);
    ASSERT_FALSE(t.ok()) << c.yaml;
    EXPECT_EQ(t.status().code(),
              c.key == std::string("base") ? StatusCode::kNotFound : StatusCode::kInvalidArgument)
        << c.yaml;
    EXPECT_NE(t.status().message().find("dir/f.yaml"), std::string::npos) << t.status().message();
    EXPECT_NE(t.status().message().find(c.key), std::string::npos) << t.status().message();
  }
}

TEST(FlightTaskIoTest, MissingFileAndMissingBase) {
  const Result<FlightTask> t = ReadFlightTaskFile("/nonexistent/f.yaml", Builtin, "t3_2");
  ASSERT_FALSE(t.ok());
  EXPECT_NE(t.status().message().find("/nonexistent/f.yaml"), std::string::npos);
  const Result<FlightTask> nobase = Parse("duration_s: 10\n", "");
  ASSERT_FALSE(nobase.ok());
  EXPECT_NE(nobase.status().message().find("base"), std::string::npos);
}

}  // namespace
}  // namespace mav::dataset
