#pragma once
// Smooth body trajectories for the simulator and the analytic IMU readings they imply.
//
// Position and the roll/pitch/yaw angles are uniform quintic B-splines (C4 continuous), so
// velocity, acceleration (and hence the accelerometer) and angular velocity/acceleration are
// exact analytic derivatives, never finite differences.

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "mav/common/status.h"
#include "mav/dataset/types.h"
#include "mav/geometry/se3.h"

namespace mav::sim {

// Full kinematic state of the body frame at one instant.
struct TrajectoryState {
  geometry::SE3 T_world_body;
  Eigen::Vector3d v_world = Eigen::Vector3d::Zero();     // m/s
  Eigen::Vector3d a_world = Eigen::Vector3d::Zero();     // m/s^2 (kinematic, without gravity)
  Eigen::Vector3d omega_body = Eigen::Vector3d::Zero();  // rad/s, body frame
  Eigen::Vector3d alpha_body = Eigen::Vector3d::Zero();  // rad/s^2, body frame
};

// Motion style, matching the paper's three data sets and the plant flights.
enum class MotionProfile {
  kEasy,    // slow and smooth (~0.4 m/s, gentle turns)
  kMedium,  // faster (~0.9 m/s), more turning
  kHard,    // jerky up-and-down motion with a lot of pure rotation
  kPlant,   // long, fast-ish flight through a large site
};

struct TrajectoryOptions {
  MotionProfile profile = MotionProfile::kEasy;
  double duration_s = 60.0;
  uint64_t seed = 1;
  // The body must stay inside this box.
  Eigen::AlignedBox3d bounds{Eigen::Vector3d(-3, -3, 0.5), Eigen::Vector3d(3, 3, 2.5)};
  // Distance from a point to the nearest obstacle surface (negative inside); the generator keeps
  // the sampled path at least `min_clearance` away. Unset means an empty world.
  std::function<double(const Eigen::Vector3d&)> clearance;
  double min_clearance = 0.6;
  // Point of interest the camera (body x axis for EuRoC's rig: cam0 looks along body +x) should
  // roughly face, so that images see textured structure rather than empty space.
  Eigen::Vector3d look_at = Eigen::Vector3d::Zero();

  bool IsValid(std::string* why) const;
};

class Trajectory {
 public:
  // Fails with InvalidArgument if the options are invalid, or FailedPrecondition if no
  // collision-free path could be sampled within the bounds.
  static Result<Trajectory> Create(const TrajectoryOptions& options);

  double duration_s() const { return duration_s_; }
  // t_s is clamped to [0, duration_s()].
  TrajectoryState Evaluate(double t_s) const;

  Trajectory() = default;

 private:
  double duration_s_ = 0;
  double knot_dt_ = 1;
  std::vector<Eigen::Vector3d> position_ctrl_;  // quintic B-spline control points
  std::vector<Eigen::Vector3d> rpy_ctrl_;       // roll, pitch, yaw control points (unwrapped)
};

// Gravity in the world frame (z up).
inline const Eigen::Vector3d kGravityWorld(0.0, 0.0, -9.81);

// Noise-free IMU reading: gyro = omega_body, accel = R_world_body^T (a_world - g).
dataset::ImuSample IdealImu(const TrajectoryState& state, int64_t t_ns);

// Discrete-time IMU model with EuRoC's continuous-time densities: at rate f,
// white noise sigma = density * sqrt(f); bias random walk b_k+1 = b_k + rw * sqrt(1/f) * n.
// Deterministic for a seed. `ground_truth` (if given) receives states with the true biases.
struct ImuSimulationOptions {
  dataset::ImuNoise noise;
  double rate_hz = 200.0;
  uint64_t seed = 1;
  Eigen::Vector3d initial_gyro_bias = Eigen::Vector3d::Zero();
  Eigen::Vector3d initial_accel_bias = Eigen::Vector3d::Zero();
};
std::vector<dataset::ImuSample> SimulateImu(const Trajectory& trajectory, int64_t t0_ns,
                                            int64_t t1_ns, const ImuSimulationOptions& options,
                                            std::vector<dataset::GroundTruthState>* ground_truth);

}  // namespace mav::sim
