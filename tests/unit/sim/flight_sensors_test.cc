#include "mav/sim/flight_sensors.h"

#include <cmath>

#include <gtest/gtest.h>

#include "mav/sim/flight_task.h"

namespace mav::sim {
namespace {

struct Moments {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero(), sq = Eigen::Vector3d::Zero();
  int n = 0;
  void Add(const Eigen::Vector3d& x) {
    mean += x;
    sq += x.cwiseAbs2();
    ++n;
  }
  Eigen::Vector3d Mean() const { return mean / n; }
  Eigen::Vector3d Std() const { return (sq / n - Mean().cwiseAbs2()).cwiseSqrt(); }
};

TEST(FlightImuTest, OffsetsAndWhiteNoiseAsSpecified) {
  dataset::FlightImuSpec spec;
  spec.accel_drift_sigma = 0;
  spec.gyro_drift_sigma = 0;
  FlightImu imu(spec, 3);
  Moments g, a;
  for (int k = 0; k < 100000; ++k) {
    const dataset::ImuSample s =
        imu.Sample(k * 10'000'000LL, Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, 9.81));
    g.Add(s.gyro);
    a.Add(s.accel - Eigen::Vector3d(0, 0, 9.81));
  }
  EXPECT_LT((g.Mean() - spec.gyro_offset).norm(), 1e-4);
  EXPECT_LT((a.Mean() - spec.accel_offset).norm(), 1e-3);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(g.Std()[i], spec.gyro_noise_sigma, 0.01 * spec.gyro_noise_sigma);
    EXPECT_NEAR(a.Std()[i], spec.accel_noise_sigma, 0.01 * spec.accel_noise_sigma);
  }
}

TEST(FlightImuTest, DriftOver240sHasTheContestsSigma) {
  dataset::FlightImuSpec spec;
  Moments da, dg;
  for (uint64_t seed = 1; seed <= 400; ++seed) {
    FlightImu imu(spec, seed);
    for (int k = 0; k <= 2400; ++k) imu.Sample(k * 100'000'000LL, {}, {});  // 10 Hz for 240 s
    da.Add(imu.accel_offset() - spec.accel_offset);
    dg.Add(imu.gyro_offset() - spec.gyro_offset);
  }
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(da.Std()[i], 0.09, 0.012);  // 400 samples: ~3.5 % standard error
    EXPECT_NEAR(dg.Std()[i], 6e-4, 8e-5);
  }
}

TEST(FlightPoseSensorTest, RateDelayStampOffsetNoiseAndMounting) {
  dataset::FlightPoseSensorSpec spec;  // 10 Hz, 100 ms late
  spec.stamp_offset_s = 0.001;
  FlightPoseSensor sensor(spec, 1, 5);
  const geometry::SE3 T_world_body(
      Eigen::Quaterniond(geometry::RotationFromRollPitchYaw(0.1, 0.2, 0.3)),
      Eigen::Vector3d(1, 2, 3));
  const geometry::SE3 expected = T_world_body * spec.T_body_sensor();
  std::vector<PoseSample> out;
  Moments dp, dr;
  for (int64_t t = 0; t <= 100'000'000'000LL; t += 10'000'000) {  // 100 s at 100 Hz
    sensor.Observe(t, T_world_body);
    const size_t before = out.size();
    sensor.Deliver(t, &out);
    for (size_t i = before; i < out.size(); ++i) {
      EXPECT_EQ(out[i].arrival_t_ns, t);
      EXPECT_EQ(out[i].arrival_t_ns - (out[i].t_ns - 1'000'000), 100'000'000);
      EXPECT_EQ(out[i].sensor, 1);
      dp.Add(out[i].T_world_sensor.Translation() - expected.Translation());
      dr.Add(geometry::LogSO3(expected.Rotation().conjugate() * out[i].T_world_sensor.Rotation()));
    }
  }
  EXPECT_EQ(out.size(), 1000u);  // samples at 0 .. 99.9 s delivered by 100 s
  EXPECT_EQ(out[1].t_ns - out[0].t_ns, 100'000'000);
  EXPECT_LT(dp.Mean().norm(), 2e-3);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(dp.Std()[i], 0.01, 0.001);
    EXPECT_NEAR(dr.Std()[i], 0.017, 0.0017);
  }
}

TEST(FlightPoseSensorTest, DeterministicForASeedAndActiveWindow) {
  dataset::FlightPoseSensorSpec spec;
  spec.active_from_s = 1.0;
  spec.active_until_s = 2.0;
  auto run = [&](uint64_t seed) {
    FlightPoseSensor s(spec, 0, seed);
    std::vector<PoseSample> out;
    for (int64_t t = 0; t <= 3'000'000'000LL; t += 10'000'000) {
      s.Observe(t, geometry::SE3());
      s.Deliver(t, &out);
    }
    return out;
  };
  const auto a = run(7), b = run(7), c = run(8);
  ASSERT_EQ(a.size(), 10u);  // 1.0 .. 1.9 s
  EXPECT_EQ(a.front().t_ns, 1'000'000'000);
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_TRUE(a[i].T_world_sensor.IsApprox(b[i].T_world_sensor, 0));
    EXPECT_FALSE(a[i].T_world_sensor.IsApprox(c[i].T_world_sensor, 1e-9));
  }
}

TEST(FlightTaskTest, BuiltinTasksAreValidAndNamed) {
  for (const std::string& name : FlightTaskNames()) {
    Result<dataset::FlightTask> t = BuiltinFlightTask(name);
    ASSERT_TRUE(t.ok()) << name;
    std::string why;
    EXPECT_TRUE(t->IsValid(&why)) << name << ": " << why;
    EXPECT_EQ(t->name, name);
  }
  const dataset::FlightTask t32 = *BuiltinFlightTask("t3_2");
  EXPECT_LT((t32.forces[0].force_world_n - Eigen::Vector3d(1.38, 1.38, -0.41)).norm(), 0.01);
  const dataset::FlightTask t42 = *BuiltinFlightTask("t4_2");
  ASSERT_EQ(t42.pose_sensors.size(), 2u);
  EXPECT_EQ(t42.pose_sensors[1].rate_hz, 20);
  EXPECT_EQ(t42.pose_sensors[1].stamp_offset_s, 0.001);
  const Result<dataset::FlightTask> bad = BuiltinFlightTask("t5_1");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("t3_1"), std::string::npos);
}

}  // namespace
}  // namespace mav::sim
