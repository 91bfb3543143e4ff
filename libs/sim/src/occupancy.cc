#include "mav/sim/occupancy.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "mav/common/check.h"
#include "mav/sim/world.h"

namespace mav::sim {

using dataset::GridGeometry;
using dataset::OccupancyGrid;
using dataset::VoxelState;

GridGeometry OccupancyGeometry(const World& world, double resolution) {
  MAV_CHECK(resolution > 0 && std::isfinite(resolution)) << "resolution " << resolution;
  const Eigen::AlignedBox3d b = world.bounds();
  MAV_CHECK(!b.isEmpty()) << "world without bounds";
  GridGeometry g;
  g.resolution = resolution;
  for (int k = 0; k < 3; ++k) {
    // Tolerances keep e.g. -4.2 / 0.05 from flooring to -85 through round-off.
    const double lo = std::floor(b.min()[k] / resolution + 1e-9);
    const double hi = std::ceil(b.max()[k] / resolution - 1e-9);
    g.origin[k] = lo * resolution;
    // Clamped: a tiny resolution gives a huge (invalid) geometry, never an int overflow.
    g.size[k] = static_cast<int>(std::clamp(hi - lo, 1.0, 2e9));
  }
  return g;
}

OccupancyGrid ComputeOccupancy(const World& world, double resolution) {
  Result<OccupancyGrid> grid = ComputeOccupancy(world, resolution, Termination::Never());
  MAV_CHECK(grid.ok()) << grid.status().ToString();
  return std::move(grid).value();
}

Result<OccupancyGrid> ComputeOccupancy(const World& world, double resolution,
                                       const Termination& termination) {
  const GridGeometry geometry = OccupancyGeometry(world, resolution);
  std::string why;
  if (!geometry.IsValid(&why)) return Status::InvalidArgument("resolution_m: " + why);
  const Eigen::AlignedBox3d b = world.bounds();
  const Eigen::Vector3d& origin = geometry.origin;
  const Eigen::Vector3i& size = geometry.size;
  OccupancyGrid grid(geometry);
  // Free inside the bounds, unknown outside (only partial border voxels can be outside).
  std::vector<char> inside[3];
  for (int k = 0; k < 3; ++k) {
    inside[k].resize(size[k]);
    for (int i = 0; i < size[k]; ++i) {
      const double c = origin[k] + (i + 0.5) * resolution;
      inside[k][i] = c >= b.min()[k] && c <= b.max()[k];
    }
  }
  // Linear writes (in bounds by construction) and a termination check per slab: a fine grid has
  // some 10^8 voxels, and a caller whose deadline passed must get the server back promptly.
  for (int z = 0; z < size.z(); ++z) {
    MAV_RETURN_IF_ERROR(termination.Check("ground-truth occupancy"));
    if (!inside[2][z]) continue;
    for (int y = 0; y < size.y(); ++y) {
      if (!inside[1][y]) continue;
      const int64_t row = grid.Linear(0, y, z);
      for (int x = 0; x < size.x(); ++x) {
        if (inside[0][x]) grid[row + x] = VoxelState::kFree;
      }
    }
  }
  for (const Primitive& p : world.primitives()) {
    if (!p.solid) continue;
    const Eigen::AlignedBox3d pb = p.Bounds();
    Eigen::Vector3i i0, i1;
    for (int k = 0; k < 3; ++k) {
      i0[k] = std::max(0, static_cast<int>(std::floor((pb.min()[k] - origin[k]) / resolution)) - 1);
      i1[k] = std::min(size[k] - 1,
                       static_cast<int>(std::floor((pb.max()[k] - origin[k]) / resolution)) + 1);
    }
    for (int z = i0.z(); z <= i1.z(); ++z) {
      MAV_RETURN_IF_ERROR(termination.Check("ground-truth occupancy"));
      for (int y = i0.y(); y <= i1.y(); ++y) {
        for (int x = i0.x(); x <= i1.x(); ++x) {
          const Eigen::Vector3d lo = origin + Eigen::Vector3d(x, y, z) * resolution;
          if (p.IntersectsBox(
                  Eigen::AlignedBox3d(lo, lo + Eigen::Vector3d::Constant(resolution)))) {
            grid.set({x, y, z}, VoxelState::kOccupied);
          }
        }
      }
    }
  }
  return grid;
}

}  // namespace mav::sim
