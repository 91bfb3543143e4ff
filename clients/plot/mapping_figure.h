#pragma once
// The paper's Figure 2 for mav-eval mapping (Holzmann et al. 2015): the sparse points with the
// keyframe poses, the mesh, and the occupancy grid coloured by height, side by side, seen in
// perspective from above and the side with the ceiling cut away.

#include <string>

#include "mav/common/status.h"
#include "mav/dataset/occupancy_grid.h"
#include "mav/mapping/pipeline.h"

namespace mav::plot {

// A 1920 x 520 PNG of `out` (its points, keyframes, mesh, and the sparse-mesh grid, else the
// OctoMap grid) in the frame of `truth`'s volume, `title` at the bottom. IoError naming `path`.
Status WriteMappingFigure(const std::string& path, const std::string& title,
                          const mapping::MappingOutput& out, const dataset::OccupancyGrid& truth);

}  // namespace mav::plot
