#pragma once
// One flight task in simulation: the vehicle (multicopter.h), the task's sensors
// (flight_sensors.h), its force schedule and goals, and collision checking, stepped in lock-step
// with a controller. The mav-simulator service's flight mode runs this class (rotor speeds in,
// IMU / poses / ground truth out) and so does mav-eval:
//
//   FlightSimulation sim = *FlightSimulation::Create(task, seed);
//   const FlightStep* out = &sim.Initial();            // the readings at t = 0
//   while (!sim.done()) {
//     for (const PoseSample& p : out->poses) controller.FeedPose(p);   // delivered by now
//     out = &sim.Step(controller.FeedImu(out->imu));   // command held for one step
//   }
//
// A step lasts one IMU period; the physics runs at physics_substep_s inside it. Forces are the
// sum of the task's windows active at the start of the step. Collisions: a touchdown faster than
// landing_speed_mps is a collision with the ground; with a map, any contact of the vehicle's
// sphere (FlightTask::vehicle_radius_m) with an obstacle is one — checked from the moment the
// vehicle, having lifted off, is first clear of everything (the spawn pad touches the ground
// voxels). Each contact episode is reported once, when it begins.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "mav/common/status.h"
#include "mav/dataset/flight_task.h"
#include "mav/dataset/types.h"
#include "mav/sim/collision_world.h"
#include "mav/sim/flight_sensors.h"
#include "mav/sim/multicopter.h"

namespace mav::sim {

struct FlightSimulationOptions {
  MulticopterParams vehicle;         // the simulated vehicle (1.5 kg Firefly)
  double physics_substep_s = 0.001;  // RK4 step (>= 1 kHz)
  double landing_speed_mps = 0.5;    // slower touchdowns are landings, faster ones collisions
  // The flown path's clearance (FlightSimulation::min_clearance_m) is sampled at this rate, up
  // to clearance_range_m (a map query per sample).
  double clearance_rate_hz = 10;
  double clearance_range_m = 5;
  bool IsValid(std::string* why) const;
};

struct Collision {
  int64_t t_ns = 0;
  Eigen::Vector3d p_world = Eigen::Vector3d::Zero();
  std::string what;  // "ground (impact 1.2 m/s)", "octomap power_plant.bt (clearance 0.21 m)"
};

// What one step produced (valid until the next Step).
struct FlightStep {
  int64_t t_ns = 0;
  MulticopterState truth;                                   // at t_ns
  Eigen::Vector3d a_world = Eigen::Vector3d::Zero();        // true kinematic acceleration
  Eigen::Vector3d force_world_n = Eigen::Vector3d::Zero();  // external force during the step
  dataset::ImuSample imu;                                   // the IMU reading at t_ns
  std::vector<PoseSample> poses;                            // delivered during the step
  int goal_index = -1;          // the latest goal published by t_ns (-1: none yet)
  bool goal_published = false;  // goal_index changed during this step
  bool collision = false;       // a collision began during this step (see collisions())
};

class FlightSimulation {
 public:
  // InvalidArgument for an invalid task or options; the task's map (if any) is loaded here
  // (NotFound / DataLoss naming the file) unless `world` is given.
  static Result<FlightSimulation> Create(const dataset::FlightTask& task, uint64_t seed,
                                         const FlightSimulationOptions& options = {},
                                         std::shared_ptr<const CollisionWorld> world = nullptr);

  // The readings at t = 0 (before the first command).
  const FlightStep& Initial() const { return out_; }
  // Holds `command_radps` (size = rotor count) for one IMU period.
  const FlightStep& Step(const RotorVector& command_radps);

  int64_t t_ns() const { return out_.t_ns; }
  int64_t step_ns() const { return step_ns_; }
  bool done() const;  // t >= the task's duration
  const dataset::FlightTask& task() const { return task_; }
  const Multicopter& vehicle() const { return vehicle_; }
  // The first kMaxRecordedCollisions contacts (a flight scores zero at the first one; the list
  // says where it hit); collision_count() counts them all.
  static constexpr size_t kMaxRecordedCollisions = 1000;
  const std::vector<Collision>& collisions() const { return collisions_; }
  int64_t collision_count() const { return collision_count_; }
  // The true mounting of pose sensor i.
  const geometry::SE3& T_body_sensor(int i) const { return pose_sensors_[i].T_body_sensor(); }
  int pose_sensor_count() const { return static_cast<int>(pose_sensors_.size()); }
  // The IMU's true offsets now.
  const FlightImu& imu() const { return imu_; }
  // Null without a map.
  const CollisionWorld* world() const { return world_.get(); }
  std::shared_ptr<const CollisionWorld> shared_world() const { return world_; }
  // The least clearance of the body origin since collision checking began (+inf before, or
  // without a map).
  double min_clearance_m() const { return min_clearance_m_; }
  bool lifted_off() const { return lifted_off_; }

  FlightSimulation(FlightSimulation&&) noexcept;
  FlightSimulation& operator=(FlightSimulation&&) noexcept;
  ~FlightSimulation();

 private:
  FlightSimulation(const dataset::FlightTask& task, uint64_t seed,
                   const FlightSimulationOptions& options,
                   std::shared_ptr<const CollisionWorld> world);
  void Sense();
  void CheckCollisions(const GroundContact& contact);

  dataset::FlightTask task_;
  FlightSimulationOptions options_;
  Multicopter vehicle_;
  FlightImu imu_;
  std::vector<FlightPoseSensor> pose_sensors_;
  std::shared_ptr<const CollisionWorld> world_;
  int64_t step_ns_ = 0;
  int64_t duration_ns_ = 0;
  int64_t clearance_period_ns_ = 0, next_clearance_ns_ = 0;
  FlightStep out_;
  void RecordCollision(Collision collision);
  std::vector<Collision> collisions_;
  int64_t collision_count_ = 0;
  bool lifted_off_ = false;
  bool checking_map_ = false;
  bool in_contact_ = false;
  double min_clearance_m_;
};

}  // namespace mav::sim
