#include <cmath>

#include "mav/common/check.h"
#include "mav/sim/trajectory.h"
#include "random.h"

namespace mav::sim {
namespace {

// The library's portable generator (random.h): identical noise on every standard library.
Eigen::Vector3d NormalVector(internal::Rng* rng) {
  const double x = rng->Normal();
  const double y = rng->Normal();
  const double z = rng->Normal();
  return {x, y, z};
}

}  // namespace

dataset::ImuSample IdealImu(const TrajectoryState& state, int64_t t_ns) {
  dataset::ImuSample sample;
  sample.t_ns = t_ns;
  sample.gyro = state.omega_body;
  sample.accel = state.T_world_body.Rotation().conjugate() * (state.a_world - kGravityWorld);
  return sample;
}

std::vector<dataset::ImuSample> SimulateImu(const Trajectory& trajectory, int64_t t0_ns,
                                            int64_t t1_ns, const ImuSimulationOptions& options,
                                            std::vector<dataset::GroundTruthState>* ground_truth) {
  MAV_CHECK(options.rate_hz > 0 && std::isfinite(options.rate_hz)) << "rate_hz " << options.rate_hz;
  MAV_CHECK(t1_ns >= t0_ns) << "empty span [" << t0_ns << ", " << t1_ns << "] ns";
  const dataset::ImuNoise& noise = options.noise;
  MAV_CHECK(noise.gyroscope_noise_density >= 0 && noise.gyroscope_random_walk >= 0 &&
            noise.accelerometer_noise_density >= 0 && noise.accelerometer_random_walk >= 0)
      << "noise densities must be non-negative";

  // Discretisation of continuous-time white noise (density sigma_c) sampled at rate f:
  // sigma_d = sigma_c * sqrt(f); bias random walk per step: sigma_c * sqrt(1/f). (Standard, e.g.
  // the Kalibr IMU noise model used for EuRoC's sensor.yaml.)
  const double sqrt_rate = std::sqrt(options.rate_hz);
  const double gyro_white = noise.gyroscope_noise_density * sqrt_rate;
  const double accel_white = noise.accelerometer_noise_density * sqrt_rate;
  const double gyro_walk = noise.gyroscope_random_walk / sqrt_rate;
  const double accel_walk = noise.accelerometer_random_walk / sqrt_rate;

  const double period_ns = 1e9 / options.rate_hz;
  const int64_t count = static_cast<int64_t>(std::floor((t1_ns - t0_ns) / period_ns + 1e-9)) + 1;
  std::vector<dataset::ImuSample> samples;
  samples.reserve(count);
  if (ground_truth) {
    ground_truth->clear();
    ground_truth->reserve(count);
  }

  internal::Rng rng(options.seed);
  Eigen::Vector3d gyro_bias = options.initial_gyro_bias;
  Eigen::Vector3d accel_bias = options.initial_accel_bias;
  for (int64_t k = 0; k < count; ++k) {
    const int64_t t_ns = t0_ns + std::llround(static_cast<double>(k) * period_ns);
    const TrajectoryState state = trajectory.Evaluate(static_cast<double>(t_ns - t0_ns) * 1e-9);
    dataset::ImuSample sample = IdealImu(state, t_ns);
    // Fixed draw order (gyro white, accel white, gyro walk, accel walk) keeps a seed's stream
    // stable.
    sample.gyro += gyro_bias + gyro_white * NormalVector(&rng);
    sample.accel += accel_bias + accel_white * NormalVector(&rng);
    samples.push_back(sample);
    if (ground_truth) {
      dataset::GroundTruthState gt;
      gt.t_ns = t_ns;
      gt.T_world_body = state.T_world_body;
      gt.v_world = state.v_world;
      gt.gyro_bias = gyro_bias;
      gt.accel_bias = accel_bias;
      ground_truth->push_back(gt);
    }
    gyro_bias += gyro_walk * NormalVector(&rng);
    accel_bias += accel_walk * NormalVector(&rng);
  }
  return samples;
}

}  // namespace mav::sim
