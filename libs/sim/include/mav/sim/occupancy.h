#pragma once
// A dense voxel grid of occupancy states, the simulator's exact ground truth and the common
// currency of the mapping evaluation.
//
// Voxel (i, j, k) covers [origin + (i, j, k) * resolution, origin + (i+1, j+1, k+1) * resolution).
// States: kOccupied (the voxel cube intersects a solid primitive), kFree (inside the world's
// bounds and touching no solid), kUnknown (outside the world's bounds, never observed).
//
// File formats:
//  * OctoMap binary (.bt), readable by octovis and octomap tools: occupied and free leaves at the
//    grid resolution, unknown voxels absent.
//  * Our own lossless format (.mavocc), documented in docs/formats.md: a fixed header followed by
//    run-length-encoded states; reading checks magic, version, sizes and a checksum.

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mav/common/status.h"

namespace mav::sim {

enum class VoxelState : uint8_t { kUnknown = 0, kFree = 1, kOccupied = 2 };

class World;

class OccupancyGrid {
 public:
  OccupancyGrid() = default;
  // All voxels start kUnknown. MAV_CHECKs positive resolution and sizes.
  OccupancyGrid(const Eigen::Vector3d& origin, double resolution, const Eigen::Vector3i& size);

  const Eigen::Vector3d& origin() const { return origin_; }
  double resolution() const { return resolution_; }
  const Eigen::Vector3i& size() const { return size_; }
  int64_t num_voxels() const { return static_cast<int64_t>(states_.size()); }

  bool InBounds(const Eigen::Vector3i& index) const;
  VoxelState at(const Eigen::Vector3i& index) const;  // MAV_CHECKs bounds
  void set(const Eigen::Vector3i& index, VoxelState state);
  // State of the voxel containing the world point; kUnknown outside the grid.
  VoxelState StateAt(const Eigen::Vector3d& p_world) const;
  Eigen::Vector3i IndexOf(const Eigen::Vector3d& p_world) const;  // may be out of bounds
  Eigen::Vector3d CenterOf(const Eigen::Vector3i& index) const;

  int64_t Count(VoxelState state) const;
  const std::vector<VoxelState>& states() const { return states_; }

  Status WriteOctomap(const std::string& path) const;          // .bt
  Status Write(const std::string& path) const;                 // .mavocc
  static Result<OccupancyGrid> Read(const std::string& path);  // .mavocc

 private:
  int64_t Linear(const Eigen::Vector3i& index) const {
    return (static_cast<int64_t>(index.z()) * size_.y() + index.y()) * size_.x() + index.x();
  }

  Eigen::Vector3d origin_ = Eigen::Vector3d::Zero();
  double resolution_ = 0.05;
  Eigen::Vector3i size_ = Eigen::Vector3i::Zero();
  std::vector<VoxelState> states_;
};

// Exact ground-truth occupancy of a world (see world.h, Primitive::IntersectsBox, for the
// precise rule per primitive type). The grid covers the world's bounds snapped outward to
// multiples of `resolution` (so voxel centres coincide with OctoMap's voxel centres); a voxel is
// kOccupied iff its cube intersects a solid primitive, else kFree if its centre lies inside the
// world's bounds, else kUnknown. Cost: proportional to the voxels inside each primitive's
// bounding box (not grid x primitives). MAV_CHECKs resolution > 0 and a grid below 2^31 voxels.
OccupancyGrid ComputeOccupancy(const World& world, double resolution);

}  // namespace mav::sim
