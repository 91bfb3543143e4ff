#pragma once
// A near-optimal reference for the length of a query's path: the shortest collision-free path
// we can compute without sampling, to judge the roadmap's paths against (mav-eval planning's
// "ratio" column, docs/planning.md).
//
// Lazy Theta* (Nash, Koenig, Tovey, "Lazy Theta*: any-angle path planning and path length
// analysis in 3D", AAAI 2010) on the map's grid: nodes are the cell centres that are valid for
// the clearance rule of the planners (clearance >= the required clearance, exact point-to-cube
// distance), 26-connected, and a node may take any earlier node it can see as its parent (line
// of sight = ClearanceMap::IsSegmentValid), so paths are not bound to grid directions. The
// result is then pulled taut with ShortenPath (length only, no cost increase allowed, corner
// cutting to convergence). The length is an upper bound of the true shortest length with the
// same clearance (it is a valid path); on open maps it is within about 1 % of it.

#include <cstdint>
#include <random>
#include <vector>

#include <Eigen/Core>

#include "mav/common/status.h"
#include "mav/common/termination.h"
#include "mav/planning/planning_map.h"

namespace mav::planning {

struct ReferenceOptions {
  // Clearance of the path, m; 0 = the map's robot radius (the rule the targets are stated in).
  double required_clearance_m = 0;
  // Give up after this many node expansions (0 = no limit): NOT_FOUND is then not a proof.
  uint64_t max_expansions = 0;

  bool IsValid(std::string* why) const;
};

struct ReferencePath {
  bool found = false;  // false: the grid search exhausted the start's free component
  std::vector<Eigen::Vector3d> path;
  double length_m = 0;
  uint64_t expansions = 0;
  double search_ms = 0;
};

// INVALID_ARGUMENT: a or b not valid for the clearance (named), bad options;
// RESOURCE_EXHAUSTED: max_expansions reached; DEADLINE_EXCEEDED / CANCELLED from `stop`.
Result<ReferencePath> ShortestReferencePath(const PlanningMap& map, const Eigen::Vector3d& a,
                                            const Eigen::Vector3d& b,
                                            const ReferenceOptions& options = {},
                                            const Termination& stop = {});

// A query of the evaluation sets (mav-eval planning, the benchmark, the statistical test).
struct EvaluationQuery {
  Eigen::Vector3d start = Eigen::Vector3d::Zero();
  Eigen::Vector3d goal = Eigen::Vector3d::Zero();
  bool straight_line_free = false;  // the straight segment keeps the robot radius
  double reference_length_m = 0;    // ShortestReferencePath's length (0 when not computed)
};

struct RandomQueryOptions {
  uint64_t seed = 1;
  int blocked = 15;  // queries whose straight line is blocked
  int free = 15;     // queries whose straight line is free
  double min_distance_m = 20;
  double max_distance_m = 40;
  // Heights the ends are drawn from, m (the power plant's structures stand below ~25 m; above
  // them every straight line is free).
  double min_z_m = 1;
  double max_z_m = 25;
  // Only queries the reference connects within this many expansions (0 = keep every query, no
  // reference length).
  uint64_t reference_expansions = 500000;
  // Give up after this many candidate pairs.
  int max_candidates = 20000;
};

// Seeded random queries between valid states (uniform in x-y over the planning volume, z in
// [min_z_m, max_z_m]) `min_distance_m`..`max_distance_m` apart, `blocked` of them with the
// straight line blocked and `free` with it free, in the order drawn. With reference_expansions,
// only queries that have a solution (proven by the reference) are kept, each with its reference
// length. Fewer than asked when max_candidates runs out.
Result<std::vector<EvaluationQuery>> RandomQueries(const PlanningMap& map,
                                                   const RandomQueryOptions& options,
                                                   const Termination& stop = {});

}  // namespace mav::planning
