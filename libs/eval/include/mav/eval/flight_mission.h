#pragma once
// Flies a contest task in one process, lock-stepped and faster than real time: the simulation
// (mav/sim/flight_simulation.h) and the flight software (mav/control/autopilot.h) exchange
// IMU, poses and rotor speeds every IMU period, and a small mission script plays the part of the
// contest's server:
//   1. arm once the estimator has converged, take off to the task's takeoff_position;
//   2. at each goal's publication (or as soon as airborne if it came earlier):
//      kHover / kDisturbance: Hover(goal) (a smooth move, a no-op at the take-off point);
//      kWaypoints: a rest-to-rest move at waypoint_limits (the fastest the vehicle takes with
//      margin: no obstacles between the contest's t4_1/t4_2 waypoints);
//      kPlannedLegs: the LegPlanner's trajectory from the current reference to the goal
//      (libs/planning plugs in here; without a planner the task fails with FailedPrecondition).
// The record has the ground truth, reference and estimate at every step for scoring and plots.

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "mav/common/stats.h"
#include "mav/common/status.h"
#include "mav/control/autopilot.h"
#include "mav/dataset/flight_task.h"
#include "mav/eval/contest_score.h"
#include "mav/geometry/polynomial_trajectory.h"
#include "mav/sim/flight_simulation.h"

namespace mav::eval {

// Plans one leg of a kPlannedLegs task: a collision-free trajectory in the world frame from
// `start` (the vehicle is hovering there) to rest at `goal`, on `world` (the task's map).
using LegPlanner = std::function<Result<geometry::PolynomialTrajectory>(
    const Eigen::Vector3d& start, const Eigen::Vector3d& goal, double yaw_rad,
    const sim::CollisionWorld* world)>;

struct FlightMissionOptions {
  control::ControllerType controller = control::ControllerType::kPaper;
  uint64_t seed = 1;
  sim::FlightSimulationOptions simulation;
  // Take-off and set-point moves.
  control::GoToLimits takeoff_limits{1.5, 2.0, 1.0, 0.5};
  // Waypoint moves of t4_1 / t4_2: ~4 s for the contest's 21.5 m legs (tilt up to ~45 deg):
  // settling within 5 s of the publication is the best band physics leaves (<= 1 s is not).
  control::GoToLimits waypoint_limits{12.0, 10.0, 1.5, 0.5};
  LegPlanner planner;  // kPlannedLegs only
  // Overrides applied to the options AutopilotOptionsForTask derives (may be null).
  std::function<void(control::AutopilotOptions*)> tune;
};

// The flight software's configuration for a task: what the contest told the teams (the
// controllers' 1.568 kg Firefly, the sensors' nominal rates and noise, each pose sensor's
// mounting T_body_sensor; not the IMU offsets, nor the 1 ms stamp offset of t4_2's second sensor).
control::AutopilotOptions AutopilotOptionsForTask(const dataset::FlightTask& task,
                                                  control::ControllerType controller);

struct FlightRecordSample {
  double t_s = 0;
  sim::MulticopterState truth;
  geometry::TrajectoryPoint reference;
  control::EstimatorState estimate;
  Eigen::Vector3d force_world_n = Eigen::Vector3d::Zero();
  int goal_index = -1;
};

struct FlightRecord {
  std::string task;
  std::string controller;
  std::vector<FlightRecordSample> samples;  // one per step (the IMU rate)
  std::vector<sim::Collision> collisions;
  // Least clearance (m) of the flown ground-truth path from the first goal's publication on
  // (the take-off from the ground is not counted), sampled at 10 Hz up to 5 m; +inf without a
  // map.
  double min_clearance_m = 0;
  control::AutopilotStatus autopilot;
  double arm_t_s = -1;  // when the vehicle armed
  double simulated_s = 0;
  double wall_s = 0;     // whole run
  RuntimeStats step_ms;  // estimator + controller + allocation per step
};

// InvalidArgument for a bad task; FailedPrecondition when a kPlannedLegs task has no planner,
// or the estimator never converged; a planner's failure is returned with the leg named.
Result<FlightRecord> FlyTask(const dataset::FlightTask& task, const FlightMissionOptions& options);

// The ground-truth trace of a record, for contest_score.h.
std::vector<FlightTraceSample> FlightTrace(const FlightRecord& record);
// ScoreFlightTask on the record's trace and collisions.
TaskScore ScoreFlight(const dataset::FlightTask& task, const FlightRecord& record);

}  // namespace mav::eval
