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

}  // namespace mav::planning
