#pragma once
// Smooth body trajectories for the simulator and the analytic IMU readings they imply.
//
// Position and the roll/pitch/yaw angles are uniform quintic B-splines (C4 continuous, see
// mav/geometry/spline.h), so velocity, acceleration (and hence the accelerometer) and angular
// velocity/acceleration are exact analytic derivatives, never finite differences.
//
// Frames. "vehicle" V is the usual flight frame (x forward, y left, z up); roll/pitch/yaw are its
// attitude, R_world_vehicle = Rz(yaw) Ry(pitch) Rx(roll). The body frame B is EuRoC's IMU frame,
// which is mounted with x up, y right and z forward: cam0's optical axis (camera z) is body +z in
// camera::EurocStereoCalibration(). So R_world_body = R_world_vehicle * RotationVehicleBody(), and
// a hovering body's accelerometer reads about (+9.81, 0, 0), as in the real EuRoC recordings.
// Body rates follow from the analytic Euler-rate relation
//   omega_V = [1, 0, -sin(pitch); 0, cos(roll), sin(roll) cos(pitch);
//              0, -sin(roll), cos(roll) cos(pitch)] * d/dt(roll, pitch, yaw),
// omega_B = R_vehicle_body^T omega_V, and alpha_B is its exact time derivative.

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "mav/common/status.h"
#include "mav/dataset/types.h"
#include "mav/geometry/se3.h"
#include "mav/geometry/spline.h"

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
  // Point of interest the camera (vehicle x axis = body z axis = cam0's optical axis for EuRoC's
  // rig) should roughly face, so that images see textured structure rather than empty space.
  // The yaw follows the direction to it with a profile-dependent deviation (hard: fast sweeps).
  Eigen::Vector3d look_at = Eigen::Vector3d::Zero();

  bool IsValid(std::string* why) const;
};

// The fixed mount rotation from EuRoC's body (IMU) frame to the vehicle frame: body x = vehicle z
// (up), body y = -vehicle y (right), body z = vehicle x (forward).
Eigen::Matrix3d RotationVehicleBody();

// Profile figures with the default bounds (6 x 6 x 2 m), 60 s, averaged over seeds 1..4
// (printed by sim_trajectory_test; EuRoC's Vicon-room sequences, Burri et al. IJRR 2016, span
// about 0.3-0.9 m/s and 0.3-0.6 rad/s):
//   easy   mean speed 0.40 m/s, mean |omega| 0.21 rad/s, tilt <= 2 deg (cap 5)
//   medium mean speed 0.85 m/s, mean |omega| 0.42 rad/s, tilt <= 8 deg (cap 12)
//   hard   mean speed 0.53 m/s (bursts to 1.5), mean |omega| 0.86 rad/s (peaks 2), about 30 % of
//          the time pure rotation (yaw sweeps of 50-90 deg while hovering), vertical bobbing
//          (rms vertical speed 0.29 m/s), tilt <= 18 deg (cap 20)
//   plant  mean speed 1.9 m/s on a 40 x 40 x 28 m box, tilt <= 5 deg (cap 15)
class Trajectory {
 public:
  // Samples the position control points as a seeded random walk with momentum (start in the
  // central part of the box, the first three control points equal so the body starts almost at
  // rest). Every control point lies inside `bounds`, hence so does the whole spline (convex hull
  // property). With a clearance function, each spline segment is checked at most 5 cm apart as
  // soon as its six control points are known; candidates that violate min_clearance are redrawn,
  // dead ends backtrack, all within a bounded number of attempts. Yaw follows the bearing to
  // look_at (plus a scan and a random offset); roll and pitch are the quasi-static multicopter
  // tilt that aligns the thrust axis with a - g, plus profile-dependent wobble.
  // Deterministic for (options, seed). Fails with InvalidArgument naming the field if the options
  // are invalid, or FailedPrecondition if no collision-free path could be sampled within the
  // bounds.
  static Result<Trajectory> Create(const TrajectoryOptions& options);

  double duration_s() const { return duration_s_; }
  // t_s is clamped to [0, duration_s()].
  TrajectoryState Evaluate(double t_s) const;

  Trajectory() = default;

 private:
  double duration_s_ = 0;
  double knot_dt_ = 1;
  geometry::UniformQuinticBSpline<3> position_;  // p_world, control points every knot_dt_
  geometry::UniformQuinticBSpline<3> rpy_;       // roll, pitch, yaw of V (yaw unwrapped)
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
