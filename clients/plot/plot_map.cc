// HeightMapOf (plot.h): kept apart from plot.cc so that the plot alone does not need libs/planning.

#include <algorithm>
#include <cmath>

#include "clients/plot/plot.h"
#include "mav/planning/planning_map.h"

namespace mav::plot {

TopViewHeightMap HeightMapOf(const planning::PlanningMap& map, double z_min_m, double z_max_m) {
  TopViewHeightMap h;
  const Eigen::Vector3i n = map.grid_size();
  const Eigen::Vector3d origin = map.grid_origin();
  const double cell = map.resolution();
  const planning::Box& bounds = map.info().bounds;
  h.origin = origin.head<2>();
  h.cell = cell;
  h.nx = n.x();
  h.ny = n.y();
  h.top_m.assign(static_cast<size_t>(h.nx) * h.ny, NAN);
  h.z_min = std::max(bounds.min.z(), z_min_m);
  h.z_max = std::min(bounds.max.z(), z_max_m);
  for (int j = 0; j < n.y(); ++j) {
    for (int i = 0; i < n.x(); ++i) {
      const Eigen::Vector3d centre =
          origin + (Eigen::Vector3d(i, j, 0).array() + 0.5).matrix() * cell;
      if (centre.x() < bounds.min.x() || centre.x() > bounds.max.x() ||
          centre.y() < bounds.min.y() || centre.y() > bounds.max.y()) {
        continue;
      }
      for (int k = n.z() - 1; k >= 0; --k) {
        const double z = origin.z() + (k + 0.5) * cell;
        if (z < h.z_min || z > h.z_max) continue;
        if (map.IsObstacleCell({i, j, k})) {
          h.top_m[static_cast<size_t>(j) * h.nx + i] = static_cast<float>(z + 0.5 * cell);
          break;
        }
      }
    }
  }
  return h;
}

}  // namespace mav::plot
