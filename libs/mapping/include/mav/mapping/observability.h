#pragma once
// The part of a known world that a set of camera poses could observe, for the second collision
// evaluation of docs/mapping.md ("MCC over the observable volume"): information about how much
// of a map's error lies where no keyframe ever looked, not a target.
//
// A voxel is observable when the ray of some sampled pixel of some keyframe's rectified left
// camera crosses it before (or ends in) the first occupied voxel of the ground truth, within
// `max_range_m` of the camera centre. Rays are traced through the truth grid with a 3D DDA
// (Amanatides and Woo, "A fast voxel traversal algorithm for ray tracing", Eurographics 1987)
// from the camera centre through the centre of every `pixel_step`-th pixel; at 4 px on EuRoC's
// rig (fx ~ 450 px) neighbouring rays are 4.4 cm apart at 5 m, under the 5 cm voxel, so no voxel
// between two sampled rays is skipped. Occupancy of the truth is what occludes; unknown truth
// voxels (outside the world) stop a ray too.

#include <cstdint>
#include <string>
#include <vector>

#include "mav/camera/stereo.h"
#include "mav/common/status.h"
#include "mav/geometry/se3.h"
#include "mav/mapping/types.h"

namespace mav::mapping {

struct ObservabilityOptions {
  // How far a camera observes [m, > 0]. Default: farther than any room preset's diagonal, so
  // only the field of view and occlusion limit what counts as observable.
  double max_range_m = 20.0;
  // Every pixel_step-th pixel in u and v casts a ray ([1, 64]).
  int pixel_step = 4;

  bool IsValid(std::string* why) const;
};

// One byte per voxel of `truth` (x fastest, the grid's layout): 1 where some camera could observe
// the voxel, 0 elsewhere. `T_world_cams` are rectified left-camera poses (x right, y down, z
// forward) in the truth's world frame; `rig` gives the image size and intrinsics.
// INVALID_ARGUMENT naming "options.<field>", "rig: ..." or "T_world_cams[i]" (non-finite).
Result<std::vector<uint8_t>> ObservableVoxels(const OccupancyGrid& truth,
                                              const std::vector<geometry::SE3>& T_world_cams,
                                              const camera::RectifiedStereo& rig,
                                              const ObservabilityOptions& options = {});

}  // namespace mav::mapping
