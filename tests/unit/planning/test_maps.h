#pragma once
// Hand-made OctoMaps for the planning tests: boxes of free, occupied and unknown voxels written
// as .bt bytes, and a brute-force clearance to check the distance map against.

#include <octomap/OcTree.h>

#include <algorithm>
#include <limits>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mav/planning/planning_map.h"

namespace mav::planning::testing {

// Every voxel of `world` is free, except those whose centre lies in an `occupied` box
// (occupied) or in an `unknown` box (left out of the tree).
inline std::string MakeMapBytes(double resolution, const Box& world,
                                const std::vector<Box>& occupied,
                                const std::vector<Box>& unknown = {}) {
  octomap::OcTree tree(resolution);
  const auto inside = [](const std::vector<Box>& boxes, const Eigen::Vector3d& p) {
    return std::any_of(boxes.begin(), boxes.end(), [&](const Box& b) { return b.Contains(p); });
  };
  for (double z = world.min.z() + resolution / 2; z < world.max.z(); z += resolution) {
    for (double y = world.min.y() + resolution / 2; y < world.max.y(); y += resolution) {
      for (double x = world.min.x() + resolution / 2; x < world.max.x(); x += resolution) {
        const Eigen::Vector3d p(x, y, z);
        if (inside(unknown, p)) continue;
        const Eigen::Vector3f pf = p.cast<float>();
        tree.updateNode(octomap::point3d(pf.x(), pf.y(), pf.z()), inside(occupied, p));
      }
    }
  }
  std::ostringstream out;
  tree.writeBinary(out);
  return out.str();
}

inline std::shared_ptr<const PlanningMap> LoadMap(const std::string& bytes,
                                                  const MapOptions& options = {}) {
  auto map = PlanningMap::LoadBytes(bytes, "test map", options);
  if (!map.ok()) return nullptr;
  return *map;
}

// A 10 x 10 x 5 m room at 0.25 m: a wall x in [4, 6], y in [0, 7] (a gap beyond y = 7), a single
// voxel at (2, 2, 2)-(2.25, 2.25, 2.25), and an unknown corner x, y in [8, 10].
inline std::string RoomBytes() {
  return MakeMapBytes(0.25, Box{{0, 0, 0}, {10, 10, 5}},
                      {Box{{4, 0, 0}, {6, 7, 5}}, Box{{2, 2, 2}, {2.25, 2.25, 2.25}}},
                      {Box{{8, 8, 0}, {10, 10, 5}}});
}

// The room map with the default options, loaded once per test binary (null if it fails to load).
inline std::shared_ptr<const PlanningMap> RoomMap() {
  static const std::shared_ptr<const PlanningMap> map = LoadMap(RoomBytes());
  return map;
}

// Distance from p to the nearest obstacle cube of the map's grid, by visiting every cell, and
// saturated like Clearance().
inline double BruteForceClearance(const PlanningMap& map, const Eigen::Vector3d& p) {
  const Eigen::Vector3i n = map.grid_size();
  const double cell = map.resolution();
  double best = std::numeric_limits<double>::infinity();
  for (int k = 0; k < n.z(); ++k) {
    for (int j = 0; j < n.y(); ++j) {
      for (int i = 0; i < n.x(); ++i) {
        if (!map.IsObstacleCell({i, j, k})) continue;
        const Eigen::Vector3d lo = map.grid_origin() + Eigen::Vector3d(i, j, k) * cell;
        const Eigen::Vector3d hi = lo + Eigen::Vector3d::Constant(cell);
        best = std::min(best, (lo - p).cwiseMax(p - hi).cwiseMax(0.0).norm());
      }
    }
  }
  return std::min(best, map.max_distance());
}

}  // namespace mav::planning::testing
