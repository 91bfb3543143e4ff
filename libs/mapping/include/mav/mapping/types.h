#pragma once
// Input of the multi-view mesher: sparse 3D points with their visibility, and the camera centres
// that saw them. Plain structs so any front end (the stereo matcher, a simulator, a test) can fill
// them without pulling in the heavy geometry libraries.

#include <vector>

#include <Eigen/Core>

#include "mav/dataset/occupancy_grid.h"

namespace mav::mapping {

// The stack's one grid type (mav/dataset/occupancy_grid.h), named here for the mapping code.
using dataset::GridGeometry;
using dataset::OccupancyGrid;
using dataset::VoxelState;

// A camera (keyframe) that observed points. Only its optical centre matters for the lines of sight
// of Labatut et al. (ICCV 2007): a line of sight is the segment from `center_world` to a point.
struct KeyframeView {
  int id = -1;                                             // unique, referenced by MapPoint
  Eigen::Vector3d center_world = Eigen::Vector3d::Zero();  // optical centre in the world frame [m]
};

// A triangulated 3D point and the keyframes that observed it (its visibility).
struct MapPoint {
  Eigen::Vector3d p_world = Eigen::Vector3d::Zero();  // [m], world frame
  std::vector<int> keyframes;                         // KeyframeView::id of every observer
};

}  // namespace mav::mapping
