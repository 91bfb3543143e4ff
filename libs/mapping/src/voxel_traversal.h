#pragma once
// 3D DDA voxel traversal (Amanatides and Woo, "A fast voxel traversal algorithm for ray
// tracing", Eurographics 1987), shared by the mesh -> grid conversion and the observability
// computation. Internal to the mapping library.

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Core>

#include "mav/mapping/types.h"

namespace mav::mapping::internal {

// Visits the voxels crossed by the segment from `from` to `from + t_end * (to - from)` in order,
// calling visit(index, t_enter) with t_enter in [0, t_end) the segment parameter at which the
// voxel is entered (0 for the first). Indices may lie outside the grid (the caller checks
// InBounds). Stops when visit returns false, at t_end, or at the voxel containing `to`.
template <typename Visit>
void TraverseVoxels(const GridGeometry& g, const Eigen::Vector3d& from, const Eigen::Vector3d& to,
                    double t_end, Visit&& visit) {
  const Eigen::Vector3d d = to - from;
  auto index_of = [&](const Eigen::Vector3d& p) {
    Eigen::Vector3i idx;
    for (int a = 0; a < 3; ++a) {
      idx[a] =
          static_cast<int>(std::clamp(std::floor((p[a] - g.origin[a]) / g.resolution), -2e9, 2e9));
    }
    return idx;
  };
  Eigen::Vector3i idx = index_of(from);
  const Eigen::Vector3i last = index_of(to);
  Eigen::Vector3i step;
  Eigen::Vector3d t_max, t_delta;
  for (int a = 0; a < 3; ++a) {
    if (d[a] > 0) {
      step[a] = 1;
      t_max[a] = (g.origin[a] + (idx[a] + 1) * g.resolution - from[a]) / d[a];
      t_delta[a] = g.resolution / d[a];
    } else if (d[a] < 0) {
      step[a] = -1;
      t_max[a] = (g.origin[a] + idx[a] * g.resolution - from[a]) / d[a];
      t_delta[a] = -g.resolution / d[a];
    } else {
      step[a] = 0;
      t_max[a] = std::numeric_limits<double>::infinity();
      t_delta[a] = std::numeric_limits<double>::infinity();
    }
  }
  double t = 0.0;
  while (t < t_end && idx != last) {
    if (!visit(idx, t)) return;
    int a = 0;
    if (t_max[1] < t_max[a]) a = 1;
    if (t_max[2] < t_max[a]) a = 2;
    t = t_max[a];
    t_max[a] += t_delta[a];
    idx[a] += step[a];
  }
}

}  // namespace mav::mapping::internal
