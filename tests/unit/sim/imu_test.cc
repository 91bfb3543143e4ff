#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "mav/geometry/se3.h"
#include "mav/sim/trajectory.h"

namespace mav::sim {
namespace {

constexpr int64_t kT0Ns = 1'403'715'273'262'142'976;  // an EuRoC-like epoch

Trajectory MakeTrajectory(MotionProfile profile, uint64_t seed, double duration_s) {
  TrajectoryOptions options;
  options.profile = profile;
  options.seed = seed;
  options.duration_s = duration_s;
  options.look_at = Eigen::Vector3d(0, 0, 1.5);
  Result<Trajectory> result = Trajectory::Create(options);
  EXPECT_TRUE(result.ok()) << result.status().ToString();
  return std::move(result).value();
}

ImuSimulationOptions NoiseFree() {
  ImuSimulationOptions options;
  options.noise.gyroscope_noise_density = 0;
  options.noise.gyroscope_random_walk = 0;
  options.noise.accelerometer_noise_density = 0;
  options.noise.accelerometer_random_walk = 0;
  return options;
}

TEST(IdealImuTest, MeasuresSpecificForceAndBodyRate) {
  TrajectoryState state;
  state.omega_body = Eigen::Vector3d(0.1, -0.2, 0.3);
  // At rest, level in the world frame: the accelerometer feels +g upwards.
  dataset::ImuSample s = IdealImu(state, 42);
  EXPECT_EQ(s.t_ns, 42);
  EXPECT_EQ(s.gyro, state.omega_body);
  EXPECT_LT((s.accel - Eigen::Vector3d(0, 0, 9.81)).norm(), 1e-12);
  // Free fall: zero specific force.
  state.a_world = kGravityWorld;
  EXPECT_LT(IdealImu(state, 0).accel.norm(), 1e-12);
  // EuRoC's mounting (body x up) at rest: about (+9.81, 0, 0), as in the real recordings.
  state.a_world.setZero();
  state.T_world_body =
      geometry::SE3(Eigen::Matrix3d(RotationVehicleBody()), Eigen::Vector3d::Zero());
  EXPECT_LT((IdealImu(state, 0).accel - Eigen::Vector3d(9.81, 0, 0)).norm(), 1e-12);
  // Accelerating forward (vehicle x = body z) at 1 m/s^2 adds to body z.
  state.a_world = Eigen::Vector3d(1, 0, 0);
  EXPECT_LT((IdealImu(state, 0).accel - Eigen::Vector3d(9.81, 0, 1)).norm(), 1e-12);
  // Yawed by 90 deg (facing world +y): accelerating along world +y is forward (body z), world +x
  // is to the right (body +y).
  state.T_world_body =
      geometry::SE3(geometry::RotationFromRollPitchYaw(0, 0, M_PI / 2) * RotationVehicleBody(),
                    Eigen::Vector3d::Zero());
  state.a_world = Eigen::Vector3d(0.5, 2.0, 0);
  EXPECT_LT((IdealImu(state, 0).accel - Eigen::Vector3d(9.81, 0.5, 2.0)).norm(), 1e-12);
}

// RK4 over the state (q, v, p) with dq/dt = q * (0, omega/2), dv/dt = R a + g, dp/dt = v; the
// measurements are interpolated linearly between samples for the midpoint stages.
struct NavState {
  Eigen::Quaterniond q;
  Eigen::Vector3d v, p;
};

struct NavDerivative {
  Eigen::Vector4d dq;  // coefficients (x, y, z, w)
  Eigen::Vector3d dv, dp;
};

NavDerivative Derivative(const NavState& x, const Eigen::Vector3d& gyro,
                         const Eigen::Vector3d& accel) {
  const Eigen::Quaterniond omega(0.0, 0.5 * gyro.x(), 0.5 * gyro.y(), 0.5 * gyro.z());
  NavDerivative d;
  d.dq = (x.q * omega).coeffs();
  d.dv = x.q.normalized() * accel + kGravityWorld;
  d.dp = x.v;
  return d;
}

NavState Step(const NavState& x, const NavDerivative& d, double h) {
  NavState out;
  out.q.coeffs() = x.q.coeffs() + h * d.dq;
  out.v = x.v + h * d.dv;
  out.p = x.p + h * d.dp;
  return out;
}

NavState IntegrateRk4(const NavState& x, const dataset::ImuSample& a, const dataset::ImuSample& b) {
  const double h = (b.t_ns - a.t_ns) * 1e-9;
  const Eigen::Vector3d gyro_mid = 0.5 * (a.gyro + b.gyro);
  const Eigen::Vector3d accel_mid = 0.5 * (a.accel + b.accel);
  const NavDerivative k1 = Derivative(x, a.gyro, a.accel);
  const NavDerivative k2 = Derivative(Step(x, k1, h / 2), gyro_mid, accel_mid);
  const NavDerivative k3 = Derivative(Step(x, k2, h / 2), gyro_mid, accel_mid);
  const NavDerivative k4 = Derivative(Step(x, k3, h), b.gyro, b.accel);
  NavState out;
  out.q.coeffs() = x.q.coeffs() + h / 6 * (k1.dq + 2 * k2.dq + 2 * k3.dq + k4.dq);
  out.q.normalize();
  out.v = x.v + h / 6 * (k1.dv + 2 * k2.dv + 2 * k3.dv + k4.dv);
  out.p = x.p + h / 6 * (k1.dp + 2 * k2.dp + 2 * k3.dp + k4.dp);
  return out;
}

TEST(SimulateImuTest, DeadReckoningNoiseFreeImuReproducesGroundTruth) {
  // Integrating the 200 Hz noise-free IMU from the true start state for 10 s must stay within
  // 1 cm of the ground truth: a wrong gravity sign, frame, or a non-analytic derivative would
  // drift by metres.
  for (MotionProfile profile :
       {MotionProfile::kEasy, MotionProfile::kMedium, MotionProfile::kHard}) {
    const Trajectory trajectory = MakeTrajectory(profile, 5, 20.0);
    std::vector<dataset::GroundTruthState> truth;
    const int64_t t_start_ns = kT0Ns + 5'000'000'000;
    const std::vector<dataset::ImuSample> imu =
        SimulateImu(trajectory, kT0Ns, kT0Ns + 20'000'000'000, NoiseFree(), &truth);
    ASSERT_EQ(imu.size(), truth.size());
    size_t k0 = 0;
    while (imu[k0].t_ns < t_start_ns) ++k0;
    const size_t k1 = k0 + 2000;  // 10 s at 200 Hz
    ASSERT_LT(k1, imu.size());

    NavState x{truth[k0].T_world_body.Rotation(), truth[k0].v_world,
               truth[k0].T_world_body.Translation()};
    double max_position_error = 0, max_rotation_error = 0, path_length = 0;
    for (size_t k = k0; k < k1; ++k) {
      x = IntegrateRk4(x, imu[k], imu[k + 1]);
      path_length +=
          (truth[k + 1].T_world_body.Translation() - truth[k].T_world_body.Translation()).norm();
      max_position_error =
          std::max(max_position_error, (x.p - truth[k + 1].T_world_body.Translation()).norm());
      max_rotation_error = std::max(
          max_rotation_error, geometry::AngleBetween(x.q, truth[k + 1].T_world_body.Rotation()));
    }
    std::printf("profile %d: path %.2f m, max position error %.2e m, rotation error %.2e rad\n",
                static_cast<int>(profile), path_length, max_position_error, max_rotation_error);
    EXPECT_GT(path_length, 2.0);  // the body really moved
    EXPECT_LT(max_position_error, 0.01) << "profile " << static_cast<int>(profile);
    EXPECT_LT(max_rotation_error, 1e-4) << "profile " << static_cast<int>(profile);
  }
}

TEST(SimulateImuTest, TimesAndGroundTruthAreConsistent) {
  const Trajectory trajectory = MakeTrajectory(MotionProfile::kMedium, 3, 5.0);
  ImuSimulationOptions options;
  options.initial_gyro_bias = Eigen::Vector3d(0.01, -0.02, 0.03);
  options.initial_accel_bias = Eigen::Vector3d(-0.1, 0.05, 0.2);
  std::vector<dataset::GroundTruthState> truth;
  const std::vector<dataset::ImuSample> imu =
      SimulateImu(trajectory, kT0Ns, kT0Ns + 2'000'000'000, options, &truth);
  ASSERT_EQ(imu.size(), 401u);  // both ends included at 200 Hz
  ASSERT_EQ(truth.size(), imu.size());
  for (size_t k = 0; k < imu.size(); ++k) {
    ASSERT_EQ(imu[k].t_ns, kT0Ns + static_cast<int64_t>(k) * 5'000'000);
    ASSERT_EQ(truth[k].t_ns, imu[k].t_ns);
    const TrajectoryState state = trajectory.Evaluate(k * 0.005);
    EXPECT_TRUE(truth[k].T_world_body.IsApprox(state.T_world_body, 1e-12));
    EXPECT_LT((truth[k].v_world - state.v_world).norm(), 1e-12);
  }
  EXPECT_EQ(truth[0].gyro_bias, options.initial_gyro_bias);
  EXPECT_EQ(truth[0].accel_bias, options.initial_accel_bias);

  // Without noise the samples are the ideal readings plus the (constant) initial biases.
  ImuSimulationOptions quiet = NoiseFree();
  quiet.initial_gyro_bias = options.initial_gyro_bias;
  quiet.initial_accel_bias = options.initial_accel_bias;
  const std::vector<dataset::ImuSample> biased =
      SimulateImu(trajectory, kT0Ns, kT0Ns + 1'000'000'000, quiet, nullptr);
  for (size_t k = 0; k < biased.size(); ++k) {
    const dataset::ImuSample ideal = IdealImu(trajectory.Evaluate(k * 0.005), biased[k].t_ns);
    EXPECT_LT((biased[k].gyro - ideal.gyro - quiet.initial_gyro_bias).norm(), 1e-12);
    EXPECT_LT((biased[k].accel - ideal.accel - quiet.initial_accel_bias).norm(), 1e-12);
  }
}

TEST(SimulateImuTest, IsDeterministicForASeed) {
  const Trajectory trajectory = MakeTrajectory(MotionProfile::kEasy, 1, 5.0);
  ImuSimulationOptions options;
  options.seed = 9;
  const auto a = SimulateImu(trajectory, 0, 3'000'000'000, options, nullptr);
  const auto b = SimulateImu(trajectory, 0, 3'000'000'000, options, nullptr);
  options.seed = 10;
  const auto c = SimulateImu(trajectory, 0, 3'000'000'000, options, nullptr);
  ASSERT_EQ(a.size(), b.size());
  int differing = 0;
  for (size_t k = 0; k < a.size(); ++k) {
    ASSERT_EQ(a[k].gyro, b[k].gyro);
    ASSERT_EQ(a[k].accel, b[k].accel);
    if (a[k].gyro != c[k].gyro) ++differing;
  }
  EXPECT_GT(differing, static_cast<int>(a.size()) - 5);
}

double StdDev(const std::vector<double>& x) {
  double mean = 0;
  for (double v : x) mean += v;
  mean /= x.size();
  double var = 0;
  for (double v : x) var += (v - mean) * (v - mean);
  return std::sqrt(var / (x.size() - 1));
}

double Lag1Correlation(const std::vector<double>& x) {
  double mean = 0;
  for (double v : x) mean += v;
  mean /= x.size();
  double num = 0, den = 0;
  for (size_t i = 0; i + 1 < x.size(); ++i) num += (x[i] - mean) * (x[i + 1] - mean);
  for (double v : x) den += (v - mean) * (v - mean);
  return num / den;
}

TEST(SimulateImuTest, NoiseStatisticsMatchTheConfiguredDensities) {
  // 150 s at 200 Hz = 30001 samples per axis, pooled over 3 axes: n ~ 9e4 per figure. The
  // sample standard deviation of n Gaussian values has relative spread 1/sqrt(2n) ~ 0.24 %, so
  // the 10 % tolerance is ~40 sigma (and a 1/sqrt(2) or sqrt(dt) scaling error, 29 % or more, is
  // far outside it). Lag-1 correlations of white sequences have spread 1/sqrt(n_axis) ~ 0.006.
  const Trajectory trajectory = MakeTrajectory(MotionProfile::kHard, 2, 150.0);
  ImuSimulationOptions options;
  options.seed = 77;
  std::vector<dataset::GroundTruthState> truth;
  const std::vector<dataset::ImuSample> imu =
      SimulateImu(trajectory, kT0Ns, kT0Ns + 150'000'000'000, options, &truth);
  ASSERT_EQ(imu.size(), 30001u);

  std::vector<double> gyro_white, accel_white, gyro_walk, accel_walk;
  std::vector<std::vector<double>> gyro_white_axis(3);
  for (size_t k = 0; k < imu.size(); ++k) {
    const dataset::ImuSample ideal = IdealImu(trajectory.Evaluate(k * 0.005), imu[k].t_ns);
    const Eigen::Vector3d wg = imu[k].gyro - ideal.gyro - truth[k].gyro_bias;
    const Eigen::Vector3d wa = imu[k].accel - ideal.accel - truth[k].accel_bias;
    for (int i = 0; i < 3; ++i) {
      gyro_white.push_back(wg[i]);
      accel_white.push_back(wa[i]);
      gyro_white_axis[i].push_back(wg[i]);
      if (k + 1 < imu.size()) {
        gyro_walk.push_back(truth[k + 1].gyro_bias[i] - truth[k].gyro_bias[i]);
        accel_walk.push_back(truth[k + 1].accel_bias[i] - truth[k].accel_bias[i]);
      }
    }
  }
  const double rate = options.rate_hz;
  const dataset::ImuNoise& n = options.noise;
  const double expected_gyro_white = n.gyroscope_noise_density * std::sqrt(rate);
  const double expected_accel_white = n.accelerometer_noise_density * std::sqrt(rate);
  const double expected_gyro_walk = n.gyroscope_random_walk * std::sqrt(1.0 / rate);
  const double expected_accel_walk = n.accelerometer_random_walk * std::sqrt(1.0 / rate);
  const double gw = StdDev(gyro_white), aw = StdDev(accel_white);
  const double gb = StdDev(gyro_walk), ab = StdDev(accel_walk);
  std::printf("gyro white %.4e (expected %.4e), accel white %.4e (%.4e)\n", gw, expected_gyro_white,
              aw, expected_accel_white);
  std::printf("gyro walk step %.4e (expected %.4e), accel walk step %.4e (%.4e)\n", gb,
              expected_gyro_walk, ab, expected_accel_walk);
  EXPECT_NEAR(gw / expected_gyro_white, 1.0, 0.1);
  EXPECT_NEAR(aw / expected_accel_white, 1.0, 0.1);
  EXPECT_NEAR(gb / expected_gyro_walk, 1.0, 0.1);
  EXPECT_NEAR(ab / expected_accel_walk, 1.0, 0.1);
  // White means uncorrelated in time; the biases really wander (they are not reset).
  for (int i = 0; i < 3; ++i) EXPECT_LT(std::abs(Lag1Correlation(gyro_white_axis[i])), 0.04);
  EXPECT_LT(std::abs(Lag1Correlation(gyro_walk)), 0.04);
  EXPECT_GT((truth.back().accel_bias - truth.front().accel_bias).norm(), 0.01);
}

}  // namespace
}  // namespace mav::sim
