#pragma once
// The planning query file of the evaluation tools (mav-eval planning --queries, mav-load
// planning --queries): one query a line,
//   sx sy sz gx gy gz            start and goal, world frame, m
//   sx sy sz wx wy wz gx gy gz   more triples: waypoints between, in order
// '#' starts a comment; blank lines are skipped. Every value must be a finite number.

#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "mav/common/status.h"

namespace mav::dataset {

struct PlanningQuery {
  std::string where;                    // "file:line"
  std::vector<Eigen::Vector3d> points;  // start, waypoints..., goal (>= 2)
};

// NOT_FOUND: no such file; INVALID_ARGUMENT "file:line: ..." for a value that is not a finite
// number or a count that is not a multiple of 3 (at least 6); "file: no queries" when empty.
Result<std::vector<PlanningQuery>> ReadPlanningQueries(const std::string& path);
// The same from the file's text; `name` names it in messages.
Result<std::vector<PlanningQuery>> ParsePlanningQueries(std::string_view text,
                                                        const std::string& name);

}  // namespace mav::dataset
