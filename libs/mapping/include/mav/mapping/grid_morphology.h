#pragma once
// Morphology of a grid's occupied set, one voxel step at a time: dilation turns free voxels next
// to an occupied one into occupied, erosion turns occupied voxels next to a free one into free.
// Unknown voxels never change, and voxels outside the grid are not neighbours.
//
// Its use is the evaluation protocol's sensitivity (docs/mapping.md): the ground truth scored
// against itself with every surface one voxel too thick or too thin tells how much of the MCC
// scale a map loses for a surface placed within one voxel of the right one; and the distance of
// a map's wrong voxels to the true surface tells where its errors are.

#include <cstdint>
#include <string>
#include <vector>

#include "mav/common/status.h"
#include "mav/mapping/types.h"

namespace mav::mapping {

struct MorphologyOptions {
  static constexpr int kMaxSteps = 64;

  int steps = 1;                    // voxels; 0 returns the grid unchanged
  bool full_neighbourhood = false;  // false: the 6 face neighbours; true: all 26 neighbours
  // The axes a step may move along (e.g. x and y only: thicker walls, floors and ceilings as
  // they were).
  bool along_x = true;
  bool along_y = true;
  bool along_z = true;

  // False with the offending field in *why: steps outside [0, kMaxSteps], no axis selected.
  bool IsValid(std::string* why) const;
};

// INVALID_ARGUMENT when the options are invalid (the message names the field).
Result<OccupancyGrid> DilateOccupied(const OccupancyGrid& grid, const MorphologyOptions& options);
Result<OccupancyGrid> ErodeOccupied(const OccupancyGrid& grid, const MorphologyOptions& options);

// Per voxel (x fastest), the number of neighbour steps (the neighbourhood and axes of `options`)
// to the nearest occupied voxel: 0 on an occupied voxel, `options.steps + 1` for every voxel
// farther than `options.steps` or cut off from all occupied voxels. Steps cross any voxel, free or
// unknown. A breadth-first search: O(voxels x neighbours).
Result<std::vector<uint8_t>> StepsToOccupied(const OccupancyGrid& grid,
                                             const MorphologyOptions& options);

}  // namespace mav::mapping
