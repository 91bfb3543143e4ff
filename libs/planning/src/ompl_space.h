#pragma once
// OMPL's view of a ClearanceMap (internal to libs/planning): a 3-D real vector space over the
// planning volume whose validity checker and motion validator ask the map, and whose samplers
// draw from our own seeded generator so a build is repeatable for a seed.

#include <cstdint>

#include <ompl/base/SpaceInformation.h>
#include <ompl/base/State.h>
#include <Eigen/Core>

#include "mav/planning/clearance_map.h"

namespace mav::planning::internal {

// Silences OMPL's console output (once per process).
void QuietOmpl();

// A space over map.bounds(); states valid when their clearance >= `required`, motions checked by
// IsSegmentValid with steps of `tolerance_m` near obstacles. The map must outlive the result.
ompl::base::SpaceInformationPtr MakeSpaceInformation(const ClearanceMap& map, double required,
                                                     double tolerance_m, uint64_t seed);

Eigen::Vector3d ToVector(const ompl::base::State* state);
void FromVector(const Eigen::Vector3d& p, ompl::base::State* state);

}  // namespace mav::planning::internal
