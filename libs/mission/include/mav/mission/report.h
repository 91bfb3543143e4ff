#pragma once
// A flown mission's figures and their forms (the table, the JSON report, trajectory.csv), the
// same whichever driver flew it: mav-eval mission (in process) and mavctl mission run (through
// the services) fill one MissionFigures each and print, write and compare the same fields.

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "mav/common/stats.h"
#include "mav/common/status.h"
#include "mav/eval/contest_score.h"
#include "mav/mission/mission.h"
#include "mav/mission/record.h"

namespace mav::mission {

// A map against the world's exact occupancy (the collision-check protocol of
// mav/mapping/collision_eval.h, over the volume the keyframes could observe).
struct MapQuality {
  double mcc = 0;
  double missed_percent = 0;  // of the box positions: occupied in truth, free in the map
  double false_percent = 0;
  int64_t positions = 0;
  bool observable_only = false;
};

struct MissionFigures {
  // What flew.
  std::string mission_path, world, pose_source, controller;
  std::string driver;  // "in-process" or "services"
  uint64_t seed = 0;
  MissionReport report;
  std::vector<eval::WindowRms> hover;  // per goal: the t3_1 figures of its hover
  double ate_m = 0;
  double path_m = 0;
  double wall_s = 0;
  double setup_s = 0;  // the world, map and roadmap (and the services' configuration)
  int64_t collisions = 0;
  std::vector<std::string> collision_descriptions;
  // Localization: frames rendered, tracked, lost, not processed (down or unseeded).
  uint64_t frames = 0, vo_tracked = 0, vo_lost = 0, vo_skipped = 0;
  RuntimeStats vo_ms, render_ms;
  uint64_t poses_merged = 0, poses_rejected = 0;
  // Mapping and planning.
  std::string map_description;
  int64_t keyframes = 0;
  uint64_t map_rebuilds = 0, map_errors = 0;
  uint64_t roadmap_builds = 0;  // the planner's (the first map's, then per plan on a new map)
  RuntimeStats map_build_ms, plan_ms;
  std::optional<MapQuality> map_quality;
  // Through the services only: frames mav-control flew on without (the localization silent),
  // and one mission tick's wall time.
  std::optional<uint64_t> lockstep_frames_missed;
  std::optional<RuntimeStats> tick_ms;
  // Through the services with vision: each pose's path from its frame's capture stamp (the
  // simulator's publish) into mav-control's estimator, wall clock, and its hops (mav-control's
  // ControlStatus.pose_latency).
  struct PoseLatency {
    RuntimeStats total, frame_transport, localization, pose_transport, merge;
  };
  std::optional<PoseLatency> pose_latency;
};

// The live progress line on stderr: the vehicle's time, the phase, goal i of n, the speed, the
// pose source's state and age and (an online map) its keyframes and version, every 0.5 s of the
// vehicle's time on a terminal (one line rewritten, ended by the next output) and every 5 s
// otherwise; nothing when `quiet`. `extra` (may be null) adds to the line (e.g. the services' map
// size).
MissionProgressCallback ProgressLinePrinter(bool quiet,
                                            std::function<std::string()> extra = nullptr);

// The figures' head (what flew, its report, the wall time) and what the flight record gives
// (ATE, the hovers' t3_1 figures); the driver's counters are the caller's to add.
MissionFigures FiguresOf(const std::string& mission_path, const std::string& world,
                         const std::string& pose_source, const std::string& controller,
                         const std::string& driver, uint64_t seed, MissionReport report,
                         double wall_s, const std::vector<FlightSample>& record);

// The human table (stdout of the two commands).
std::string MissionTable(const MissionFigures& figures);
// The JSON report (docs/mission.md lists its fields).
std::string MissionJson(const MissionFigures& figures);
// t,gt_x,gt_y,gt_z,est_x,est_y,est_z,gt_q*,est_q*,armed at the record's rate.
Status WriteTrajectoryCsv(const std::string& path, const std::vector<FlightSample>& record);

}  // namespace mav::mission
