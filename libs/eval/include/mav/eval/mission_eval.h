#pragma once
// The mission evaluation of mav-eval: a mission file flown in one process, lock-stepped
// (mav/mission/lockstep_driver.h: the simulated vehicle, its rendered stereo camera and IMU, the
// VO, the estimator and controller, the planner) by the mission logic (mav/mission/mission.h)
// that mavctl mission run drives against the services, with the figures of mav/mission/report.h.

#include <cstdint>
#include <memory>
#include <string>

#include "mav/common/status.h"
#include "mav/dataset/mission_file.h"
#include "mav/eval/report.h"
#include "mav/mission/lockstep_driver.h"
#include "mav/mission/mission.h"
#include "mav/mission/report.h"

namespace mav::eval {

struct MissionEvalOptions {
  dataset::MissionSpec spec;        // the mission file as read (its world possibly replaced)
  std::string mission_path;         // for the report
  mission::LockstepOptions driver;  // the simulation and the flight software
  mission::MissionOptions mission;  // the mission logic
  // For the report: what flew.
  std::string pose_source;
  std::string controller;
  uint64_t seed = 1;
};

struct MissionSummary {
  mission::MissionFigures figures;
  // The driver after the flight: its record, planning map and map (DIR/trajectory.csv,
  // mission.png, map.bt).
  std::unique_ptr<mission::LockstepDriver> driver;
};

// Builds the driver (errors with " (no take-off)" appended), flies the mission and gathers its
// figures with the driver's counters and, for an online map, the final map's quality.
// `progress` as RunMission's (may be null).
Result<MissionSummary> EvaluateMission(const MissionEvalOptions& options,
                                       const mission::MissionProgressCallback& progress = {});

// MissionTable as the report's one table; MissionJson as its JSON document.
Report MissionEvalReport(const MissionSummary& summary);

}  // namespace mav::eval
