#pragma once
// Files of the dense occupancy grid (occupancy_grid.h), docs/formats.md:
//  * .mavocc, our lossless format: a fixed header and run-length-encoded states with a checksum
//    (free/occupied/unknown survive exactly). Reading checks magic, version, sizes, every run and
//    the checksum, and fails with DATA_LOSS naming the file and the problem.
//  * OctoMap binary (.bt, octomap::OcTree::writeBinary), readable by octovis, OctoMap's tools and
//    our planner: occupied and free leaves at the grid resolution, unknown voxels absent, uniform
//    octants pruned. Because a grid origin is a multiple of the resolution, grid voxel centres
//    coincide with OctoMap's voxel centres.
// Files are written atomically ("<path>.tmp" renamed into place).

#include <string>
#include <string_view>

#include "mav/common/status.h"
#include "mav/dataset/occupancy_grid.h"

namespace mav::dataset {

// .mavocc bytes of a grid, and the file.
std::string EncodeMavocc(const OccupancyGrid& grid);
Status WriteMavocc(const OccupancyGrid& grid, const std::string& path);
// NotFound for a missing file; DataLoss "<name>: ..." for a corrupt one (see docs/formats.md).
// A grid above `max_voxels` is refused with ResourceExhausted before it is allocated.
Result<OccupancyGrid> DecodeMavocc(std::string_view bytes, const std::string& name,
                                   int64_t max_voxels = GridGeometry::kMaxVoxels);
Result<OccupancyGrid> ReadMavocc(const std::string& path,
                                 int64_t max_voxels = GridGeometry::kMaxVoxels);

// OctoMap .bt bytes of a grid, and the file. InvalidArgument when a voxel centre lies outside
// OctoMap's key range (+-32768 voxels around the world origin).
Result<std::string> EncodeOctomapBt(const OccupancyGrid& grid);
Status WriteOctomapBt(const OccupancyGrid& grid, const std::string& path);

}  // namespace mav::dataset
