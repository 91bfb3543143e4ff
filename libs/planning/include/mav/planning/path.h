#pragma once
// The paper's path cost and the shortening with a bounded cost increase (Holzmann et al. 2015,
// Sec. 3: "the path that minimizes a cost function is planned, which penalizes proximity to
// obstacles, length and unnecessary changes in altitude. Limiting the cost increase, the raw
// output path from the planning algorithm is shortened").
//
// Cost of a polyline P (world frame, m):
//   C(P) = w_length * L + w_clearance * X + w_altitude * Z,
//   L = sum |p_{i+1} - p_i|, Z = sum |z_{i+1} - z_i| (metres climbed or descended),
//   X = integral over the path of the proximity penalty rho(c(s)) ds,
//   rho(c) = max(0, 1 / c - 1 / c_max) (1/m; c = clearance, c_max = the map's max_distance), so X
//   is 0 far from obstacles and grows as the path hugs them. Costs are additive over segments,
//   which is what lets A* search the roadmap with them.

#include <vector>

#include <Eigen/Core>

#include "mav/common/status.h"
#include "mav/common/termination.h"
#include "mav/planning/clearance_map.h"

namespace mav::planning {

struct CostWeights {
  // Per metre of path. 1: the cost is in "metres of straight flight".
  double length = 1.0;
  // Per unit of the proximity integral X. 0.05: a metre flown at 0.5 m from a wall (rho = 1.8)
  // costs as much as 9 cm more path; enough to keep the raw path off the walls, small enough
  // that the shortened path stays within a few percent of the shortest one.
  double clearance = 0.05;
  // Per metre of climb or descent. 0.1: altitude changes cost energy and the paper penalises
  // the unnecessary ones; a tenth of a metre of length per metre of climb.
  double altitude = 0.1;

  // All finite and >= 0, not all zero; `why` names the field ("clearance: ...").
  bool IsValid(std::string* why) const;
};

struct PathCost {
  double length_m = 0;
  double clearance_cost = 0;     // X above (unweighted)
  double altitude_change_m = 0;  // Z above
  double total = 0;              // the weighted sum C
  double min_clearance_m = 0;    // closest approach to an obstacle (1 cm steps around the minimum)
};

// rho(c) of the file comment.
double ProximityPenalty(double clearance_m, double max_distance_m);
// Proximity integral X of the segment [a, b] (trapezoid rule every half cell, with
// ClearanceMap::ApproximateClearance).
double SegmentProximity(const ClearanceMap& map, const Eigen::Vector3d& a,
                        const Eigen::Vector3d& b);
// Cost of the segment [a, b] (without the minimum clearance).
double SegmentCost(const ClearanceMap& map, const CostWeights& weights, const Eigen::Vector3d& a,
                   const Eigen::Vector3d& b);
// All terms of the polyline, min_clearance_m included.
PathCost EvaluatePathCost(const ClearanceMap& map, const CostWeights& weights,
                          const std::vector<Eigen::Vector3d>& path);

struct ShortenOptions {
  // Accept shortcuts while C(shortened) <= (1 + max_cost_increase) * C(raw). 0.1: the paper's
  // "limiting the cost increase", 10 %. Validated [0, 10].
  double max_cost_increase = 0.1;
  // Clearance every shortcut keeps, m; 0 = the map's robot radius. Validated >= 0.
  double required_clearance_m = 0;
  // Step of the shortcut checks near obstacles, m; 0 = ClearanceMap::kDefaultToleranceM.
  double tolerance_m = 0;
  // Passes of corner cutting after the vertex shortcuts (each moves every corner towards the
  // obstacle that makes it); 0 = vertex shortcuts only. Validated [0, 100].
  int corner_passes = 6;

  bool IsValid(std::string* why) const;
};

// Shortens `raw` (start and end kept; every segment valid for the required clearance):
// 1. vertex shortcuts: from each kept vertex, jump to the farthest later vertex whose straight
//    segment is valid and keeps the total cost within the bound;
// 2. corner cutting: each corner b between a and c is replaced by the two points
//    b + t (a - b), b + t (c - b) for the largest t (bisection) whose cut is valid and within the
//    bound, which pulls the path taut around the obstacles; passes repeat until one saves less
//    than 1 cm (at most corner_passes); then nearly collinear vertices are dropped.
// The result never costs more than (1 + max_cost_increase) * C(raw) and keeps the ends. A path
// of one segment is returned as is. Stops early (returning the best so far) when `stop` fires.
std::vector<Eigen::Vector3d> ShortenPath(const ClearanceMap& map, const CostWeights& weights,
                                         const std::vector<Eigen::Vector3d>& raw,
                                         const ShortenOptions& options,
                                         const Termination& stop = {});

// The polyline's length, m.
double PathLength(const std::vector<Eigen::Vector3d>& path);

}  // namespace mav::planning
