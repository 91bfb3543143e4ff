#pragma once
// The one dense occupancy grid of the stack: the simulator's exact ground truth, the maps the
// mapping library builds (sparse mesh and OctoMap baseline), the grids the mapping service
// serves and the collision-check evaluation all use this type; its files are occupancy_io.h.
//
// Voxel (i, j, k) covers [origin + (i, j, k) * resolution, origin + (i+1, j+1, k+1) * resolution)
// in the world frame (metres, z up). Voxels are stored x fastest: ((k * ny) + j) * nx + i.
// States: kOccupied (the cube holds a solid or an obstacle), kFree (observed or known empty),
// kUnknown (outside the known volume, never observed).
//
// Memory: one byte per voxel, so a grid is bounded by its geometry; GridGeometry::IsValid caps it
// at kMaxVoxels (2 GiB). Callers that take a geometry from users must check
// GridGeometry::num_voxels() against their own, smaller limit before constructing a grid.

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mav/common/status.h"

namespace mav::dataset {

enum class VoxelState : uint8_t { kUnknown = 0, kFree = 1, kOccupied = 2 };
const char* VoxelStateName(VoxelState state);  // "unknown", "free", "occupied"

struct GridGeometry {
  static constexpr int64_t kMaxVoxels = int64_t{1} << 31;

  Eigen::Vector3d origin = Eigen::Vector3d::Zero();  // world position of voxel (0,0,0)'s min corner
  double resolution = 0.05;                          // voxel edge, m
  Eigen::Vector3i size = Eigen::Vector3i::Zero();    // voxels per axis

  // Saturates at INT64_MAX for absurd sizes (a geometry computed from a user's huge box).
  int64_t num_voxels() const;
  Eigen::Vector3d max_corner() const { return origin + size.cast<double>() * resolution; }
  // Same size, and resolution and origin equal to rounding.
  bool SameAs(const GridGeometry& other) const;
  // False with the offending field in *why: resolution not positive and finite, origin not
  // finite, a size not positive, more than kMaxVoxels voxels.
  bool IsValid(std::string* why) const;

  // The grid covering `box` (finite, non-empty), its origin snapped down to a multiple of the
  // resolution (voxel boundaries then coincide with OctoMap's). Cheap: use num_voxels() to
  // refuse a huge request before any grid is allocated. The result may be invalid (too large).
  static GridGeometry Covering(const Eigen::Vector3d& min, const Eigen::Vector3d& max,
                               double resolution);
};

class OccupancyGrid {
 public:
  OccupancyGrid() = default;
  // MAV_CHECKs a valid geometry (check GridGeometry::IsValid first on user input).
  explicit OccupancyGrid(const GridGeometry& geometry, VoxelState fill = VoxelState::kUnknown);
  // MAV_CHECKs a valid geometry and states.size() == geometry.num_voxels().
  OccupancyGrid(const GridGeometry& geometry, std::vector<VoxelState> states);

  const GridGeometry& geometry() const { return geometry_; }
  const Eigen::Vector3d& origin() const { return geometry_.origin; }
  double resolution() const { return geometry_.resolution; }
  const Eigen::Vector3i& size() const { return geometry_.size; }
  int64_t num_voxels() const { return static_cast<int64_t>(states_.size()); }
  bool empty() const { return states_.empty(); }

  bool InBounds(const Eigen::Vector3i& index) const {
    return (index.array() >= 0).all() && (index.array() < geometry_.size.array()).all();
  }
  VoxelState at(const Eigen::Vector3i& index) const;  // MAV_CHECKs bounds
  void set(const Eigen::Vector3i& index, VoxelState state);
  // Unchecked linear access, x fastest.
  int64_t Linear(int i, int j, int k) const {
    return (static_cast<int64_t>(k) * geometry_.size.y() + j) * geometry_.size.x() + i;
  }
  VoxelState& operator[](int64_t linear) { return states_[static_cast<size_t>(linear)]; }
  VoxelState operator[](int64_t linear) const { return states_[static_cast<size_t>(linear)]; }

  // The voxel containing the world point (may be out of bounds; clamped to +-2e9 so that far
  // or huge points never overflow int).
  Eigen::Vector3i IndexOf(const Eigen::Vector3d& p_world) const;
  // kUnknown outside the grid and for a non-finite point.
  VoxelState StateAt(const Eigen::Vector3d& p_world) const;
  Eigen::Vector3d CenterOf(const Eigen::Vector3i& index) const;

  int64_t Count(VoxelState state) const;
  const std::vector<VoxelState>& states() const { return states_; }
  std::vector<VoxelState>& mutable_states() { return states_; }

 private:
  GridGeometry geometry_;
  std::vector<VoxelState> states_;
};

}  // namespace mav::dataset
