#pragma once
// What the collision-check protocol of collision_eval.h (Holzmann et al. 2015, Tables 3-4) can
// and cannot tell on one data set, as mav-eval mapping prints it (docs/mapping.md, "Protocol
// sensitivity"):
//  * KnownRegion: the evaluation volume, the bounding box of the ground truth's known voxels;
//  * ProtocolSensitivity: the ground truth scored against itself with every surface moved by one
//    voxel, or with the free space no keyframe could observe made unknown. It bounds what a map
//    whose surfaces are right to within one voxel, or a map perfect wherever the cameras looked,
//    can score;
//  * AttributeErrors: where a map's wrong voxels are (distance to the true surface, height in the
//    evaluation volume) and what the map would score with one class of them set right.
// A voxel is blocked when it is occupied or unknown (both collide in the protocol).

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mav/common/status.h"
#include "mav/mapping/collision_eval.h"
#include "mav/mapping/grid_morphology.h"
#include "mav/mapping/types.h"

namespace mav::mapping {

// The bounding box (voxel indices, [min, max)) of the truth's known voxels: the world's bounds
// (room interior plus walls, floor and ceiling). False when no voxel is known.
bool KnownRegion(const OccupancyGrid& truth, Eigen::Vector3i* region_min,
                 Eigen::Vector3i* region_max);

// One change of the truth and its score against the unchanged truth.
struct SensitivityRow {
  enum class Change { kDilate, kErode, kHideUnobservable };
  std::string name;  // a key: "dilated_1", ..., "unobservable_unknown"
  std::string what;  // a description: "1 voxel thicker (6 face neighbours)", ...
  Change change = Change::kDilate;
  MorphologyOptions morphology;  // kDilate and kErode
  CollisionOutcomes outcomes;
};

// The rows mav-eval prints, unscored: dilated by 1 voxel (6 and 26 neighbours, xy only, z only),
// by 2, eroded by 1, and the unobservable free space unknown.
std::vector<SensitivityRow> ProtocolSensitivityRows();

// The truth as `row` changes it; `observable` is the ObservableVoxels mask of the truth
// (observability.h), used by kHideUnobservable only. InvalidArgument for a mask of another size.
Result<OccupancyGrid> ChangedTruth(const OccupancyGrid& truth, const SensitivityRow& row,
                                   const std::vector<uint8_t>& observable);

// ProtocolSensitivityRows() scored with `eval` (the truth against each changed truth).
Result<std::vector<SensitivityRow>> ProtocolSensitivity(const OccupancyGrid& truth,
                                                        const std::vector<uint8_t>& observable,
                                                        const CollisionEvalOptions& eval);

// One class of a map's wrong voxels, and the map's outcomes with that class set to the truth's
// state (the rest as it was).
struct AttributionRow {
  std::string name;  // a key: "blocked_at_1", ..., "free_all"
  std::string what;  // a description
  int64_t voxels = 0;
  CollisionOutcomes outcomes;
};

// The classes: map blocked and truth free at 1, 2, 3 and > 3 steps (26 neighbours) from the
// nearest truth-occupied voxel; the same by quarter of the evaluation volume's height; all of
// them; and every miss (map free, truth blocked). `map` has the truth's geometry.
Result<std::vector<AttributionRow>> AttributeErrors(const OccupancyGrid& truth,
                                                    const OccupancyGrid& map,
                                                    const CollisionEvalOptions& eval);

}  // namespace mav::mapping
