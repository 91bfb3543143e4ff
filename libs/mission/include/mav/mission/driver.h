#pragma once
// The one interface between the mission logic (mission.h) and a vehicle. Two drivers implement
// it: the in-process lock-step simulation (lockstep_driver.h, mav-eval mission) and the running
// services over gRPC + DDS (mavctl mission run). The mission only sees what a real vehicle's
// ground station would: the flight software's estimate and health, plus the ground truth where a
// simulator provides it (for scoring, never for decisions).

#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "mav/common/status.h"
#include "mav/control/autopilot.h"
#include "mav/control/reference.h"
#include "mav/geometry/polynomial_trajectory.h"
#include "mav/geometry/se3.h"

namespace mav::mission {

// The true state of a simulated vehicle (for scoring, never for decisions).
struct TrueState {
  Eigen::Vector3d p_world = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_world_body = Eigen::Quaterniond::Identity();
  Eigen::Vector3d v_world = Eigen::Vector3d::Zero();
  Eigen::Vector3d omega_body = Eigen::Vector3d::Zero();
};

// The vehicle as the mission sees it after an Advance.
struct VehicleView {
  int64_t t_ns = 0;  // the vehicle's clock (simulated time in a simulation)
  bool armed = false;
  bool estimator_initialized = false;  // the estimate below means something
  bool estimator_converged = false;
  control::FlightMode mode = control::FlightMode::kDisarmed;
  bool moving = false;  // a commanded move or trajectory is still being flown
  Eigen::Vector3d p_est = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_est = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_est = Eigen::Quaterniond::Identity();  // body to world
  double yaw_est_rad = 0;
  // Since the estimator last accepted a pose (+inf: never).
  double pose_age_s = std::numeric_limits<double>::infinity();
  // The localization runs but has no reference pose (a restarted service): the mission seeds it
  // from the estimate with SeedLocalization.
  bool localization_needs_seed = false;
  std::string localization_state;  // "ok", "lost", "down", ... (for the progress line)
  uint64_t poses_rejected = 0;     // by the estimator's gate, since the start
  int64_t collisions = 0;          // contacts with the world so far (a simulator knows them)
  uint64_t map_version = 0;        // changes whenever the planner's map changed
  int64_t map_keyframes = 0;       // keyframes in an online map (0: a fixed map)
  std::optional<TrueState> truth;  // ground truth, where a simulator gives it
};

// One planned leg.
struct LegPlan {
  geometry::PolynomialTrajectory trajectory;
  std::vector<Eigen::Vector3d> path;  // the shortened path the spline follows
  double length_m = 0;
  double duration_s = 0;
};

class MissionDriver {
 public:
  virtual ~MissionDriver() = default;
  // Lets the vehicle fly for dt_s (a lock-step simulation steps it; a live driver waits) and
  // returns its state then. An error ends the mission (aborted, the error reported).
  virtual Result<VehicleView> Advance(double dt_s) = 0;
  virtual Status Arm() = 0;
  virtual Status Disarm() = 0;
  // A smooth move to (position, yaw) within `limits`, then hold there.
  virtual Status GoTo(const Eigen::Vector3d& position, double yaw_rad,
                      const control::GoToLimits& limits) = 0;
  // Hold (position, yaw) at once.
  virtual Status Hold(const Eigen::Vector3d& position, double yaw_rad) = 0;
  // Fly `trajectory` from now; hold its end.
  virtual Status Follow(const geometry::PolynomialTrajectory& trajectory) = 0;
  // A collision-free trajectory from `start` (the vehicle rests there) to rest at `goal` with
  // constant yaw. FailedPrecondition with the planner's status and message when there is no plan.
  virtual Result<LegPlan> Plan(const Eigen::Vector3d& start, const Eigen::Vector3d& goal,
                               double yaw_rad) = 0;
  // Whether the vehicle may be at `p` in the driver's map: InvalidArgument saying why not
  // (outside the planning volume, or closer to an obstacle than the vehicle's radius).
  virtual Status CheckPoint(const Eigen::Vector3d& p) = 0;
  // The nearest point at the altitude of `above` (searched outwards in x-y) whose column down to
  // the ground is free in the driver's map: where the vehicle can land. NotFound when none is
  // within the search radius.
  virtual Result<Eigen::Vector3d> LandingSpot(const Eigen::Vector3d& above) = 0;
  // Restarts the localization at this body pose (after it lost its reference).
  virtual Status SeedLocalization(const geometry::SE3& T_world_body) = 0;
};

}  // namespace mav::mission
