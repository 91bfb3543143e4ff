#include "mav/dataset/occupancy_grid.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "mav/common/check.h"

namespace mav::dataset {

const char* VoxelStateName(VoxelState state) {
  switch (state) {
    case VoxelState::kUnknown:
      return "unknown";
    case VoxelState::kFree:
      return "free";
    case VoxelState::kOccupied:
      return "occupied";
  }
  return "?";
}

int64_t GridGeometry::num_voxels() const {
  const double n = static_cast<double>(size.x()) * size.y() * size.z();
  if (n >= 9.0e18) return std::numeric_limits<int64_t>::max();
  return static_cast<int64_t>(size.x()) * size.y() * size.z();
}

bool GridGeometry::SameAs(const GridGeometry& other) const {
  return size == other.size && std::abs(resolution - other.resolution) <= 1e-9 * resolution &&
         (origin - other.origin).cwiseAbs().maxCoeff() <= 1e-6 * resolution;
}

bool GridGeometry::IsValid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why != nullptr) *why = m;
    return false;
  };
  if (!(resolution > 0.0) || !std::isfinite(resolution)) {
    return fail("resolution: must be positive and finite [m]");
  }
  if (!origin.allFinite()) return fail("origin: must be finite");
  if ((size.array() <= 0).any()) return fail("size: must be positive on every axis");
  if (num_voxels() > kMaxVoxels) {
    return fail("size: " + std::to_string(num_voxels()) + " voxels exceed the limit of " +
                std::to_string(kMaxVoxels));
  }
  return true;
}

GridGeometry GridGeometry::Covering(const Eigen::Vector3d& min, const Eigen::Vector3d& max,
                                    double resolution) {
  GridGeometry g;
  g.resolution = resolution;
  // The tolerance keeps e.g. 0.3 / 0.1 = 2.9999999999999996 from flooring to 2.
  g.origin =
      (min / resolution).array().unaryExpr([](double v) { return std::floor(v + 1e-9); }).matrix() *
      resolution;
  const Eigen::Vector3d extent = (max - g.origin) / resolution;
  for (int i = 0; i < 3; ++i) {
    // Clamped so that a huge box gives a huge (invalid) geometry, never an int overflow.
    const double n = std::clamp(std::ceil(extent[i] - 1e-9), 1.0, 2e9);
    g.size[i] = static_cast<int>(n);
  }
  return g;
}

OccupancyGrid::OccupancyGrid(const GridGeometry& geometry, VoxelState fill) : geometry_(geometry) {
  std::string why;
  MAV_CHECK(geometry.IsValid(&why)) << "GridGeometry: " << why;
  states_.assign(static_cast<size_t>(geometry.num_voxels()), fill);
}

OccupancyGrid::OccupancyGrid(const GridGeometry& geometry, std::vector<VoxelState> states)
    : geometry_(geometry), states_(std::move(states)) {
  std::string why;
  MAV_CHECK(geometry.IsValid(&why)) << "GridGeometry: " << why;
  MAV_CHECK(static_cast<int64_t>(states_.size()) == geometry.num_voxels())
      << "states.size() " << states_.size() << " != " << geometry.num_voxels();
}

VoxelState OccupancyGrid::at(const Eigen::Vector3i& index) const {
  MAV_CHECK(InBounds(index)) << "voxel " << index.transpose() << " outside "
                             << geometry_.size.transpose();
  return states_[static_cast<size_t>(Linear(index.x(), index.y(), index.z()))];
}

void OccupancyGrid::set(const Eigen::Vector3i& index, VoxelState state) {
  MAV_CHECK(InBounds(index)) << "voxel " << index.transpose() << " outside "
                             << geometry_.size.transpose();
  states_[static_cast<size_t>(Linear(index.x(), index.y(), index.z()))] = state;
}

Eigen::Vector3i OccupancyGrid::IndexOf(const Eigen::Vector3d& p_world) const {
  const Eigen::Vector3d f = ((p_world - geometry_.origin) / geometry_.resolution).array().floor();
  return f.cwiseMax(-2e9).cwiseMin(2e9).cast<int>();
}

VoxelState OccupancyGrid::StateAt(const Eigen::Vector3d& p_world) const {
  if (!p_world.allFinite()) return VoxelState::kUnknown;
  const Eigen::Vector3i i = IndexOf(p_world);
  return InBounds(i) ? states_[static_cast<size_t>(Linear(i.x(), i.y(), i.z()))]
                     : VoxelState::kUnknown;
}

Eigen::Vector3d OccupancyGrid::CenterOf(const Eigen::Vector3i& index) const {
  return geometry_.origin + (index.cast<double>().array() + 0.5).matrix() * geometry_.resolution;
}

int64_t OccupancyGrid::Count(VoxelState state) const {
  return std::count(states_.begin(), states_.end(), state);
}

}  // namespace mav::dataset
