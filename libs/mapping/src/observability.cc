#include "mav/mapping/observability.h"

#include <cmath>

#include "mav/common/parallel.h"
#include "voxel_traversal.h"

namespace mav::mapping {

bool ObservabilityOptions::IsValid(std::string* why) const {
  if (!(max_range_m > 0) || !std::isfinite(max_range_m)) {
    if (why) *why = "max_range_m: must be finite and > 0 [m]";
    return false;
  }
  if (pixel_step < 1 || pixel_step > 64) {
    if (why) *why = "pixel_step: must be in [1, 64]";
    return false;
  }
  return true;
}

Result<std::vector<uint8_t>> ObservableVoxels(const OccupancyGrid& truth,
                                              const std::vector<geometry::SE3>& T_world_cams,
                                              const camera::RectifiedStereo& rig,
                                              const ObservabilityOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument("options." + why);
  if (!rig.IsValid(&why)) return Status::InvalidArgument("rig: " + why);
  for (size_t i = 0; i < T_world_cams.size(); ++i) {
    if (!T_world_cams[i].Translation().allFinite() ||
        !T_world_cams[i].Rotation().coeffs().allFinite()) {
      return Status::InvalidArgument("T_world_cams[" + std::to_string(i) + "]: non-finite pose");
    }
  }
  const GridGeometry& g = truth.geometry();
  // Two workers over alternate cameras, each into its own mask; OR-ed, so the split does not
  // change the result.
  auto trace = [&](size_t first, std::vector<uint8_t>* mask) {
    for (size_t c = first; c < T_world_cams.size(); c += 2) {
      const Eigen::Matrix3d R = T_world_cams[c].RotationMatrix();
      const Eigen::Vector3d centre = T_world_cams[c].Translation();
      for (int v = options.pixel_step / 2; v < rig.height; v += options.pixel_step) {
        for (int u = options.pixel_step / 2; u < rig.width; u += options.pixel_step) {
          const Eigen::Vector3d ray =
              R * Eigen::Vector3d((u + 0.5 - rig.cx) / rig.fx, (v + 0.5 - rig.cy) / rig.fy, 1.0)
                      .normalized();
          internal::TraverseVoxels(g, centre, centre + options.max_range_m * ray, 1.0,
                                   [&](const Eigen::Vector3i& idx, double) {
                                     if (!truth.InBounds(idx)) return true;
                                     const int64_t i = truth.Linear(idx.x(), idx.y(), idx.z());
                                     (*mask)[static_cast<size_t>(i)] = 1;
                                     return truth[i] == VoxelState::kFree;
                                   });
        }
      }
    }
  };
  const size_t n = static_cast<size_t>(truth.num_voxels());
  std::vector<uint8_t> observed(n, 0), other(n, 0);
  ParallelFor(2, 2, [&](int part, int64_t, int64_t) {
    trace(static_cast<size_t>(part), part == 0 ? &observed : &other);
  });
  for (size_t i = 0; i < n; ++i) observed[i] |= other[i];
  return observed;
}

}  // namespace mav::mapping
