#include "mav/mapping/voxel_grid.h"

#include <cmath>
#include <cstdio>

#include <octomap/OcTree.h>

#include "mav/common/check.h"

namespace mav::mapping {

bool GridGeometry::SameAs(const GridGeometry& other) const {
  return size == other.size && std::abs(resolution - other.resolution) <= 1e-9 * resolution &&
         (origin - other.origin).cwiseAbs().maxCoeff() <= 1e-6 * resolution;
}

bool GridGeometry::IsValid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!(resolution > 0.0) || !std::isfinite(resolution)) return fail("resolution must be > 0 [m]");
  if (!origin.allFinite()) return fail("origin must be finite");
  if ((size.array() <= 0).any()) return fail("size must be positive on every axis");
  if (num_voxels() > (int64_t{1} << 31)) return fail("size exceeds 2^31 voxels");
  return true;
}

VoxelGrid::VoxelGrid(const GridGeometry& geometry, VoxelState fill) : geometry_(geometry) {
  std::string why;
  MAV_CHECK(geometry.IsValid(&why)) << "GridGeometry: " << why;
  states_.assign(geometry.num_voxels(), fill);
}

VoxelGrid::VoxelGrid(const GridGeometry& geometry, std::vector<VoxelState> states)
    : geometry_(geometry), states_(std::move(states)) {
  std::string why;
  MAV_CHECK(geometry.IsValid(&why)) << "GridGeometry: " << why;
  MAV_CHECK(static_cast<int64_t>(states_.size()) == geometry.num_voxels())
      << "states.size() " << states_.size() << " != " << geometry.num_voxels();
}

VoxelState VoxelGrid::at(const Eigen::Vector3i& index) const {
  MAV_CHECK(InBounds(index)) << "voxel index out of bounds";
  return states_[Linear(index.x(), index.y(), index.z())];
}

void VoxelGrid::set(const Eigen::Vector3i& index, VoxelState state) {
  MAV_CHECK(InBounds(index)) << "voxel index out of bounds";
  states_[Linear(index.x(), index.y(), index.z())] = state;
}

Eigen::Vector3i VoxelGrid::IndexOf(const Eigen::Vector3d& p_world) const {
  const Eigen::Vector3d q = (p_world - geometry_.origin) / geometry_.resolution;
  return Eigen::Vector3i(static_cast<int>(std::floor(q.x())), static_cast<int>(std::floor(q.y())),
                         static_cast<int>(std::floor(q.z())));
}

VoxelState VoxelGrid::StateAt(const Eigen::Vector3d& p_world) const {
  const Eigen::Vector3i index = IndexOf(p_world);
  return InBounds(index) ? states_[Linear(index.x(), index.y(), index.z())] : VoxelState::kUnknown;
}

Eigen::Vector3d VoxelGrid::CenterOf(const Eigen::Vector3i& index) const {
  return geometry_.origin + (index.cast<double>().array() + 0.5).matrix() * geometry_.resolution;
}

int64_t VoxelGrid::Count(VoxelState state) const {
  int64_t n = 0;
  for (VoxelState s : states_) n += s == state ? 1 : 0;
  return n;
}

Status VoxelGrid::WriteOctomap(const std::string& path) const {
  octomap::OcTree tree(geometry_.resolution);
  const float occupied = tree.getClampingThresMaxLog();
  const float free = tree.getClampingThresMinLog();
  const Eigen::Vector3i& n = geometry_.size;
  for (int k = 0; k < n.z(); ++k) {
    for (int j = 0; j < n.y(); ++j) {
      for (int i = 0; i < n.x(); ++i) {
        const VoxelState s = states_[Linear(i, j, k)];
        if (s == VoxelState::kUnknown) continue;
        const Eigen::Vector3d c = CenterOf({i, j, k});
        tree.updateNode(octomap::point3d(static_cast<float>(c.x()), static_cast<float>(c.y()),
                                         static_cast<float>(c.z())),
                        s == VoxelState::kOccupied ? occupied : free, /*lazy_eval=*/true);
      }
    }
  }
  tree.updateInnerOccupancy();
  tree.prune();
  const std::string tmp = path + ".tmp";
  if (!tree.writeBinary(tmp)) return Status::IoError(path + ": cannot write OctoMap file");
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    return Status::IoError(path + ": cannot rename " + tmp + " into place");
  }
  return Status::Ok();
}

}  // namespace mav::mapping
