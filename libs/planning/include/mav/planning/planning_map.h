#pragma once
// The planning map: an OctoMap (Hornung, Wurm, Bennewitz, Stachniss, Burgard, "OctoMap: an
// efficient probabilistic 3D mapping framework based on octrees", Autonomous Robots 2013) turned
// into a dense obstacle grid over the planning volume plus an obstacle distance map, the
// "obstacle proximity map" the paper computes before the mission (Holzmann et al. 2015, Sec. 3).
//
// Obstacles are voxel cubes: the occupied leaves, plus the unknown space when the policy says
// so (the default: unknown is an obstacle, the safe choice for flying; outside the OctoMap's
// bounding box everything is unknown). That one policy is baked into the grid, so every stage
// (roadmap, search, shortening, trajectory check) sees the same obstacles.
//
// Clearance(p) = Euclidean distance from p to the nearest obstacle cube (not to its centre), exact
// up to max_distance_m:
// * the distance map holds, for every cell centre c, the exact distance D(c) from c to the union
//   of obstacle cubes. It is a separable exact transform (Felzenszwalb & Huttenlocher, "Distance
//   transforms of sampled functions", Theory of Computing 2012) run on the half-cell lattice:
//   the distance from c to a cube is the distance from c to the nearest of the cube's 27
//   half-cell lattice points, so D(c)^2 = min over those points of |c - x|^2 - a plain squared
//   EDT over points. DynamicEDT3D (Lau, Sprunk, Burgard, "Efficient grid-based spatial
//   representations for robot navigation in dynamic environments", RAS 2013), the paper's choice,
//   is kept as the baseline (DistanceMethod::kDynamicEdt3d): its distances are between cell
//   centres, D(c) is then taken as max(0, d_centres - half cell diagonal), a lower bound;
// * for a point p in the cell of centre c, |Clearance(p) - D(c)| <= |p - c| (1-Lipschitz), so
//   most validity checks end with one look-up; the undecided ones (and Clearance() itself) scan
//   the obstacle rows within the bound with a bit mask per x-row: the nearest obstacle cube of a
//   row is found by bit search, so the scan is exact and costs O(rows) not O(cells).
//
// A PlanningMap is immutable once loaded and safe to query from any number of threads.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include <Eigen/Core>

#include "mav/common/status.h"
#include "mav/common/termination.h"
#include "mav/planning/clearance_map.h"

namespace mav::planning {

enum class UnknownSpace {
  kObstacle,  // unknown voxels are obstacles (the default: never fly into what was not seen)
  kFree,      // unknown voxels are free
};

enum class DistanceMethod {
  kExact,         // our separable exact point-to-cube transform (the default: faster, 5 B/cell)
  kDynamicEdt3d,  // DynamicEDT3D, the paper's choice (centre-to-centre distances; ~30 B/cell)
};

struct MapOptions {
  // Radius of a sphere containing the vehicle, m: states closer than this to an obstacle are
  // invalid. 0.5 m: the AscTec Firefly's 0.215 m arms plus its ~0.1 m propellers (~0.32 m) plus
  // ~0.18 m for tracking errors. Validated (0, 10].
  double robot_radius_m = 0.5;
  UnknownSpace unknown_space = UnknownSpace::kObstacle;
  // Saturation of the distance map and of Clearance(), m: beyond it the exact value does not
  // matter (the proximity cost is 0 there). Validated (robot_radius_m, 50].
  double max_distance_m = 5.0;
  // The planning volume, world frame; unset = the OctoMap's bounding box (all its leaves, free
  // ones included). Must intersect the map when unknown space is an obstacle.
  std::optional<Box> planning_bounds;
  DistanceMethod distance_method = DistanceMethod::kExact;
  // Refuse (RESOURCE_EXHAUSTED) a map whose grids would need more than this many bytes, checked
  // after parsing the OctoMap and before allocating anything else; 0 = no limit.
  uint64_t max_memory_bytes = 0;
  // Threads for the distance transform (1 or 2 on the 2-core target machine). Validated [1, 64].
  int threads = 2;

  // false with `why` naming the field ("robot_radius_m: ...").
  bool IsValid(std::string* why) const;
};

// The memory the map's grids need, known before allocating them.
struct MemoryEstimate {
  Eigen::Vector3i grid_size = Eigen::Vector3i::Zero();  // cells per axis (padded volume)
  uint64_t grid_voxels = 0;
  uint64_t bytes_per_voxel = 0;  // peak, during the distance transform
  uint64_t bytes = 0;            // grid_voxels * bytes_per_voxel
};

// The cells covering `volume` at `resolution_m` (padded as PlanningMap pads it) and their bytes.
MemoryEstimate EstimateMapMemory(const Box& volume, double resolution_m, const MapOptions& options);

struct MapInfo {
  std::string source;  // the file path, or the name given with the bytes
  double resolution_m = 0;
  Box bounds;           // of the OctoMap (all leaves)
  Box planning_bounds;  // the effective planning volume
  // Cells of the grid (the planning volume, padded by the distance the clearance needs) by state.
  uint64_t occupied_voxels = 0;
  uint64_t free_voxels = 0;
  uint64_t unknown_voxels = 0;
  uint64_t octree_leaves = 0;
  MemoryEstimate memory;
  double load_ms = 0;          // parsing the OctoMap and filling the grid
  double distance_map_ms = 0;  // the distance transform
  uint64_t fingerprint = 0;
};

class PlanningMap final : public ClearanceMap {
 public:
  // Loads an OctoMap binary (.bt) file. NOT_FOUND: no such file; DATA_LOSS: not a readable .bt
  // (message names the file); INVALID_ARGUMENT: bad options (field named) or a planning volume
  // that does not intersect the map; RESOURCE_EXHAUSTED: above options.max_memory_bytes;
  // DEADLINE_EXCEEDED / CANCELLED from `stop`. Progress stages: "octomap", "grid",
  // "distance map".
  static Result<std::shared_ptr<const PlanningMap>> LoadFile(const std::string& path,
                                                             const MapOptions& options,
                                                             const Termination& stop = {},
                                                             const ProgressCallback& progress = {});
  // The same from the bytes of a .bt (an upload, the mapping service's map); `source` names them
  // in messages and MapInfo.
  static Result<std::shared_ptr<const PlanningMap>> LoadBytes(
      std::string_view bt_bytes, const std::string& source, const MapOptions& options,
      const Termination& stop = {}, const ProgressCallback& progress = {});

  ~PlanningMap() override;
  PlanningMap(const PlanningMap&) = delete;
  PlanningMap& operator=(const PlanningMap&) = delete;

  const MapInfo& info() const;
  const MapOptions& options() const;

  // ClearanceMap.
  double Clearance(const Eigen::Vector3d& p) const override;
  double ClearanceUpTo(const Eigen::Vector3d& p, double limit) const override;
  double ClearanceLowerBound(const Eigen::Vector3d& p) const override;
  bool HasClearance(const Eigen::Vector3d& p, double required) const override;
  double ApproximateClearance(const Eigen::Vector3d& p) const override;
  const Box& bounds() const override;
  double resolution() const override;
  double robot_radius() const override;
  double max_distance() const override;
  uint64_t fingerprint() const override;

  // The grid (for tools such as the reference search and the top-view plot): cell (i, j, k)
  // covers [origin + (i, j, k) * resolution, origin + (i + 1, j + 1, k + 1) * resolution).
  Eigen::Vector3d grid_origin() const;
  Eigen::Vector3i grid_size() const;
  // Whether cell (i, j, k) is an obstacle (occupied, or unknown under kObstacle); cells outside
  // the grid are not.
  bool IsObstacleCell(const Eigen::Vector3i& cell) const;
  // D(c) of the file comment for cell (i, j, k), m (saturated a little above max_distance()).
  double CellCentreClearance(const Eigen::Vector3i& cell) const;

  struct Impl;

 private:
  explicit PlanningMap(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace mav::planning
