#pragma once
// The mission logic: a mission file (mav/dataset/mission_file.h) flown through a MissionDriver
// (driver.h), the same code in-process and against the services.
//
//   waiting (estimator converging) -> take-off (a vertical move to the take-off height)
//   -> for each goal: planning -> flying -> hovering (the goal's hover_s) -> landing -> done
//
// Health, from the estimator's pose age (the time since it last accepted a pose):
//   * older than hold_after_s (1 s): the vehicle holds where it is on the IMU and the mission
//     pauses ("holding"); the localization is re-seeded from the estimate if it asks for it;
//   * fresh again (younger than resume_below_s): the mission resumes - a leg in flight is
//     re-planned from where the vehicle holds, a hover or take-off goes on;
//   * older than land_after_s (3 s): the vehicle lands where it is ("fault landing"), the
//     outcome is landed_on_fault.
// When the driver's map changes during a leg (an online map filling in), the rest of the leg is
// checked against it; if it is blocked the vehicle holds and the leg is planned again from there.
// A leg that cannot be planned (a goal inside an obstacle, no path) aborts the mission with an
// error naming the goal and its line in the file; the vehicle lands where it is. A collision
// ends the mission at once (outcome collision). Decisions use the estimate only; the ground
// truth (where the driver has it) is recorded for scoring.

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mav/common/status.h"
#include "mav/control/reference.h"
#include "mav/dataset/mission_file.h"
#include "mav/mission/driver.h"

namespace mav::mission {

enum class MissionPhase {
  kWaiting,
  kTakingOff,
  kPlanning,
  kFlying,
  kHovering,
  kLanding,
  kHolding,
  kFaultLanding,
  kDone,
};
const char* MissionPhaseName(MissionPhase phase);  // "waiting", "taking_off", ...

enum class MissionOutcome { kCompleted, kLandedOnFault, kAborted, kCollision };
const char* MissionOutcomeName(MissionOutcome outcome);  // "completed", "landed_on_fault", ...

struct MissionOptions {
  double tick_s = 0.05;  // the logic's period (the driver flies in between)
  // Health thresholds on the estimator's pose age, s (see the file comment).
  double hold_after_s = 1.0;
  double land_after_s = 3.0;
  double resume_below_s = 0.3;
  // Moves flown without the planner: the take-off, and the landing's descent.
  control::GoToLimits takeoff_limits{0.5, 1.0, 0.5, 0.5};
  control::GoToLimits landing_limits{0.3, 0.5, 0.5, 0.5};
  // A landing first descends at approach_limits to approach_height_m above the resting height
  // (the final descent at landing_limits starts there: a slow move over metres would take
  // minutes with the autopilot's smooth GoTo profile).
  control::GoToLimits approach_limits{1.0, 1.0, 0.5, 0.5};
  double approach_height_m = 0.5;
  // A goal without its own yaw: false keeps the yaw of the take-off; true turns (in place, at
  // takeoff_limits' yaw rate) to face the goal before each leg, so a forward camera sees the
  // way (what an online map needs).
  bool face_goals = false;
  // The take-off is done when the estimate is this close to the take-off point.
  double takeoff_tolerance_m = 0.1;
  // A goal counts as reached when its error (ground truth where known, else the estimate) at
  // the end of its hover is at most this.
  double goal_tolerance_m = 0.15;
  // The ground's height under the landing point (the worlds' floor) and the legs' height. The
  // descent aims landing_overshoot_m below the resting height at landing_limits' speed, so the
  // vehicle touches down still moving down (slower than a simulator's landing speed) whatever
  // the estimate's drift on the IMU; it has landed once the estimated velocity (which the IMU
  // keeps right when the position drifts) stays below landed_speed_mps for landed_hold_s, once
  // the descent's reference has passed 0.2 m above the resting height (and at least
  // landed_after_s into the descent).
  double ground_z_m = 0.0;
  double legs_height_m = 0.08;
  double landing_overshoot_m = 0.5;
  double landed_speed_mps = 0.06;
  double landed_hold_s = 0.5;
  double landed_after_s = 1.5;
  // The whole mission's limit in the vehicle's time, s; exceeded = aborted.
  double timeout_s = 900;
  // Waiting for the estimator before take-off, s; exceeded = aborted.
  double arm_timeout_s = 30;
  bool IsValid(std::string* why) const;
};

struct GoalReport {
  Eigen::Vector3d goal = Eigen::Vector3d::Zero();
  int line = 0;                  // in the mission file
  bool reached = false;          // see MissionOptions::goal_tolerance_m
  bool visited = false;          // its hover ended (false: the mission ended before)
  double error_m = -1;           // ground truth - goal at the hover's end (-1: unknown)
  double estimate_error_m = -1;  // estimate - goal then
  double hover_start_s = -1;     // mission time the hover began (the leg's end)
  double reached_at_s = -1;      // mission time of the hover's end
};

struct LegReport {
  int goal = 0;         // the goal it flies to
  bool replan = false;  // re-planned after a hold
  double t_s = 0;       // when it was planned
  std::vector<Eigen::Vector3d> path;
  double length_m = 0;
  double duration_s = 0;
};

struct MissionEvent {
  double t_s = 0;
  std::string what;  // "hold: no accepted pose for 1.0 s", "resume", ...
};

struct MissionReport {
  MissionOutcome outcome = MissionOutcome::kAborted;
  std::string error;  // why, unless completed
  std::vector<GoalReport> goals;
  std::vector<LegReport> legs;
  std::vector<MissionEvent> events;
  int plans = 0;
  int replans = 0;
  int holds = 0;
  double sim_time_s = 0;  // from the first Advance to the end
  double takeoff_t_s = -1;
  MissionPhase last_phase = MissionPhase::kWaiting;
};

// What the progress callback sees after each tick.
struct MissionProgress {
  double t_s = 0;
  MissionPhase phase = MissionPhase::kWaiting;
  int goal = -1;  // 0-based index of the goal being flown to (-1: none yet)
  int goals = 0;
  const VehicleView* vehicle = nullptr;
};
using MissionProgressCallback = std::function<void(const MissionProgress&)>;

// Flies `mission` through `driver`. InvalidArgument for invalid options or mission (nothing
// flown then); everything that happens in flight is in the report (outcome and error).
Result<MissionReport> RunMission(const dataset::MissionSpec& mission, const MissionOptions& options,
                                 MissionDriver& driver,
                                 const MissionProgressCallback& progress = {});

}  // namespace mav::mission
