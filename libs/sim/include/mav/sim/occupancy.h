#pragma once
// The simulator's exact ground-truth occupancy of a world, as the stack's one grid type
// (mav/dataset/occupancy_grid.h; its files: mav/dataset/occupancy_io.h). States: kOccupied (the
// voxel cube intersects a solid primitive), kFree (inside the world's bounds and touching no
// solid), kUnknown (outside the world's bounds).

#include "mav/common/status.h"
#include "mav/common/termination.h"
#include "mav/dataset/occupancy_grid.h"

namespace mav::sim {

class World;

// Exact ground-truth occupancy of a world (see world.h, Primitive::IntersectsBox, for the
// precise rule per primitive type). The grid covers the world's bounds snapped outward to
// multiples of `resolution` (so voxel centres coincide with OctoMap's voxel centres); a voxel is
// kOccupied iff its cube intersects a solid primitive, else kFree if its centre lies inside the
// world's bounds, else kUnknown. Cost: proportional to the voxels inside each primitive's
// bounding box (not grid x primitives). MAV_CHECKs resolution > 0 and a valid grid geometry:
// check OccupancyGeometry(world, resolution).num_voxels() against a limit first on user input.
dataset::OccupancyGrid ComputeOccupancy(const World& world, double resolution);
// The same, stopping with DEADLINE_EXCEEDED / CANCELLED when `termination` stops (checked per
// primitive), and InvalidArgument "resolution_m: ..." for a geometry over the type's voxel cap.
Result<dataset::OccupancyGrid> ComputeOccupancy(const World& world, double resolution,
                                                const Termination& termination);

// The geometry ComputeOccupancy would use (no allocation): lets callers refuse a huge request.
dataset::GridGeometry OccupancyGeometry(const World& world, double resolution);

}  // namespace mav::sim
