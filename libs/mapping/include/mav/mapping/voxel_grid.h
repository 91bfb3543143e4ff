#pragma once
// A dense voxel grid of occupancy states: the mapping library's own small type, laid out exactly
// like mav::sim::OccupancyGrid (same state values, same x-fastest linear order) so converting
// between them is a copy of origin, resolution, size and the state vector:
//
//   mav::mapping::VoxelGrid g({sim.origin(), sim.resolution(), sim.size()},
//                             reinterpret-copy of sim.states() as VoxelState);
//
// (mapping does not link mav::sim; see docs/mapping.md.)
//
// Voxel (i, j, k) covers [origin + (i, j, k) * resolution, origin + (i+1, j+1, k+1) * resolution).

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mav/common/status.h"

namespace mav::mapping {

// Numerically identical to mav::sim::VoxelState.
enum class VoxelState : uint8_t { kUnknown = 0, kFree = 1, kOccupied = 2 };

struct GridGeometry {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();  // world position of voxel (0,0,0)'s min corner
  double resolution = 0.05;                          // voxel edge [m]
  Eigen::Vector3i size = Eigen::Vector3i::Zero();    // voxels per axis

  int64_t num_voxels() const { return static_cast<int64_t>(size.x()) * size.y() * size.z(); }
  bool SameAs(const GridGeometry& other) const;
  bool IsValid(std::string* why) const;
};

class VoxelGrid {
 public:
  VoxelGrid() = default;
  // MAV_CHECKs a valid geometry (use GridGeometry::IsValid first on user input).
  explicit VoxelGrid(const GridGeometry& geometry, VoxelState fill = VoxelState::kUnknown);
  // MAV_CHECKs states.size() == geometry.num_voxels().
  VoxelGrid(const GridGeometry& geometry, std::vector<VoxelState> states);

  const GridGeometry& geometry() const { return geometry_; }
  const Eigen::Vector3d& origin() const { return geometry_.origin; }
  double resolution() const { return geometry_.resolution; }
  const Eigen::Vector3i& size() const { return geometry_.size; }
  int64_t num_voxels() const { return static_cast<int64_t>(states_.size()); }

  bool InBounds(const Eigen::Vector3i& index) const {
    return (index.array() >= 0).all() && (index.array() < geometry_.size.array()).all();
  }
  VoxelState at(const Eigen::Vector3i& index) const;  // MAV_CHECKs bounds
  void set(const Eigen::Vector3i& index, VoxelState state);
  // Unchecked linear access, x fastest: ((k * ny) + j) * nx + i.
  int64_t Linear(int i, int j, int k) const {
    return (static_cast<int64_t>(k) * geometry_.size.y() + j) * geometry_.size.x() + i;
  }
  VoxelState& operator[](int64_t linear) { return states_[linear]; }
  VoxelState operator[](int64_t linear) const { return states_[linear]; }

  // The voxel containing the world point (may be out of bounds); kUnknown outside the grid.
  Eigen::Vector3i IndexOf(const Eigen::Vector3d& p_world) const;
  VoxelState StateAt(const Eigen::Vector3d& p_world) const;
  Eigen::Vector3d CenterOf(const Eigen::Vector3i& index) const;

  int64_t Count(VoxelState state) const;
  const std::vector<VoxelState>& states() const { return states_; }

  // OctoMap binary (.bt): occupied and free leaves at the grid resolution, unknown voxels absent
  // (octovis opens it). The octree is centred on the world origin as OctoMap requires, so voxel
  // boundaries coincide with OctoMap's only when origin / resolution is integral.
  Status WriteOctomap(const std::string& path) const;

 private:
  GridGeometry geometry_;
  std::vector<VoxelState> states_;
};

}  // namespace mav::mapping
