#pragma once
// The planning evaluation of mav-eval: the same queries on one map planned by our roadmap planner
// and by the OMPL peers (a fresh PRM* or RRTConnect per query with a time budget, OMPL's
// simplifier), every method followed by the same speed plan and spline, with each path's length
// against a near-optimal reference (Lazy Theta* on the map's grid, pulled taut) and the figures of
// the paper's Section 3 (Holzmann et al. 2015) beside ours.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mav/common/stats.h"
#include "mav/common/status.h"
#include "mav/eval/report.h"
#include "mav/geometry/polynomial_trajectory.h"
#include "mav/planning/planning_map.h"
#include "mav/planning/roadmap.h"

namespace mav::eval {

struct PlanningEvalOptions {
  std::string map_path;  // OctoMap binary (.bt)
  // One query a line (mav/dataset/planning_queries.h); empty: the contest's t4_3 legs plus
  // `blocked` random queries whose straight line is blocked and `free` whose line is free.
  std::string queries_path;
  int blocked = 15;
  int free = 15;
  double robot_radius_m = 0.5;
  uint64_t seed = 1;  // of the roadmap, the peers and the random queries
  // "roadmap", "ompl-prmstar", "ompl-rrtconnect", in the order given.
  std::vector<std::string> methods = {"roadmap", "ompl-prmstar", "ompl-rrtconnect"};
  double budget_s = 0.75;  // per query of the OMPL peers (the paper's)
  // Loaded when it exists and belongs to the map, else built and saved there; empty: built.
  std::string roadmap_path;
};

struct PlanningEvalQuery {
  std::string kind;                     // "t4_3", "blocked", "free" or "file:line"
  std::vector<Eigen::Vector3d> points;  // start, waypoints..., goal
  double reference_m = 0;               // 0: no reference (waypoints or not found)
};

// One method's outcome for one query.
struct PlanningRun {
  bool ok = false;
  std::string status;
  std::string message;
  double length_m = 0;             // shortened path
  double trajectory_length_m = 0;  // the spline's
  double planning_ms = 0;          // the whole query
  double duration_s = 0;
  double avg_speed_mps = 0;
  double peak_speed_mps = 0;
  double min_clearance_m = 0;  // re-checked here, exact, every <= 1 cm
  geometry::PolynomialTrajectory trajectory;
};

// One method over all queries.
struct PlanningMethodStats {
  int ok = 0, queries = 0, violations = 0;  // violations: min clearance below the robot radius
  RuntimeStats planning;
  double mean_ratio = 0, max_ratio = 0;  // trajectory length / reference, over `ratios` queries
  int ratios = 0;
  // The 35 m legs of the paper: queries whose reference is 32-38 m long.
  int legs35 = 0;
  double legs35_duration_s = 0, legs35_max_duration_s = 0, legs35_avg_speed = 0, legs35_peak = 0;
  double mean_duration_s = 0, mean_avg_speed = 0, peak_speed = 0, min_clearance = 1e9;
  double mean_length_m = 0;
};

struct PlanningMethodResult {
  std::string method;
  std::vector<PlanningRun> runs;  // one per query
  PlanningMethodStats stats;
};

struct PlanningSummary {
  std::string map_path;
  double robot_radius_m = 0;
  std::shared_ptr<const planning::PlanningMap> map;
  std::vector<std::string> setup_log;  // the map, the queries and the roadmap, one line each
  std::vector<PlanningEvalQuery> queries;
  std::shared_ptr<const planning::Roadmap> roadmap;  // null without the roadmap method
  std::vector<PlanningMethodResult> methods;
};

// Loads the map, makes the queries and their references, loads or builds the roadmap and plans
// every query with every method. InvalidArgument "methods: ..." for an unknown method; the
// libraries' errors (map, queries file, roadmap) as they are.
Result<PlanningSummary> EvaluatePlanning(const PlanningEvalOptions& options);

// The per-query table, the summary table with the paper's figures, and the JSON {method:
// {queries: [...], summary figures}}, "paper" and "roadmap_build".
Report PlanningReport(const PlanningSummary& summary);

}  // namespace mav::eval
