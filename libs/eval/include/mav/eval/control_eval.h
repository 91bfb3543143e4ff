#pragma once
// The control evaluation of mav-eval: the EuRoC 2014 Challenge 3 simulation tasks (t3_1 ...
// t4_3) flown in one process (FlyTask, mav/eval/flight_mission.h) with each controller, scored
// as the contest's scripts did (ScoreFlight, mav/eval/contest_score.h), with the paper's figures
// of Section 3 (Holzmann et al. 2015) beside ours. The planned-legs task plans its legs with the
// roadmap planner (mav/eval/leg_planner.h).

#include <cstdint>
#include <string>
#include <vector>

#include "mav/common/status.h"
#include "mav/control/autopilot.h"
#include "mav/dataset/flight_task.h"
#include "mav/eval/contest_score.h"
#include "mav/eval/flight_mission.h"
#include "mav/eval/leg_planner.h"
#include "mav/eval/report.h"
#include "mav/planning/trajectory.h"

namespace mav::eval {

// The paper controller's design, for the trade-off measurements of docs/control.md; the defaults
// leave AutopilotOptionsForTask's options as they are.
struct ControllerTuning {
  // The three translational poles at -P rad/s: (s + P)^3 = s^3 + 3P s^2 + 3P^2 s + P^3 (0 = the
  // default design).
  double position_pole_radps = 0;
  double attitude_omega_radps = control::PaperControllerGains().attitude_omega_radps;
  double attitude_zeta = control::PaperControllerGains().attitude_zeta;
  double observer_s = control::AutopilotOptions().disturbance_observer_s;  // 0 = off
  double blend_s = control::AutopilotOptions().correction_blend_s;         // 0 = off
  bool decoupled_estimator = false;  // the paper's decoupled estimator weights
  double tilt_braking_fraction = control::AutopilotOptions().tilt_braking_fraction;
  bool strict_thrust_priority = false;  // the allocation keeps the thrust even at the top
  double model_mass_kg = 0;             // the mass the controllers are told; 0 = the contest's
  // Gain scheduling while a gust is rejected: poles at -P rad/s (0 = none) and the planar loop's
  // natural frequency; the observed disturbance step that switches to them.
  double gust_pole_radps = 0;
  double gust_attitude_omega_radps = control::AutopilotOptions::GustGains().attitude_omega_radps;
  double gust_threshold_mps2 = control::AutopilotOptions().gust_threshold_mps2;

  // Sets the fields of `options` this tuning covers.
  void Apply(control::AutopilotOptions* options) const;
};

struct ControlEvalOptions {
  std::vector<dataset::FlightTask> tasks;  // flown in order
  std::vector<control::ControllerType> controllers = {control::ControllerType::kPaper,
                                                      control::ControllerType::kLee};
  uint64_t seed = 1;  // sensor noise
  ControllerTuning tuning;
  // Planned-legs tasks: the legs' limits and the roadmap file (empty: in the temporary
  // directory, named by the map's fingerprint).
  planning::SpeedLimits leg_limits;
  std::string roadmap_path;
};

// One controller on one task.
struct ControlRun {
  std::string controller;
  std::string task;
  Status status;                 // FlyTask's; not ok: no record, no score
  std::vector<PlannedLeg> legs;  // planned-legs tasks: as the planner planned them
  FlightRecord record;
  TaskScore score;
};

struct ControlTaskResult {
  dataset::FlightTask task;
  std::vector<std::string> planner_log;  // the leg planner's set-up, when this task made it
  std::vector<ControlRun> runs;          // one per controller, in order
};

struct ControlSummary {
  std::vector<ControlTaskResult> tasks;
  int failures = 0;  // runs whose FlyTask failed
};

// Flies every task with every controller. A run that fails is kept with its status (and counted);
// the leg planner's set-up errors are returned with the task named ("t4_3: ...").
Result<ControlSummary> EvaluateControl(const ControlEvalOptions& options);

// The runs' scores per goal, the leg plans and collisions; the paper's figures beside ours; the
// JSON {"<controller>/<task>": {metric: value}}.
Report ControlReport(const ControlSummary& summary);

}  // namespace mav::eval
