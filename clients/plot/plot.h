#pragma once
// Top-view (x-y) trajectory plots like the paper's Figure 3, drawn with OpenCV.

#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mav/common/status.h"

namespace mav::planning {
class PlanningMap;
}

namespace mav::plot {

struct PlotSeries {
  std::string label;
  std::vector<Eigen::Vector3d> positions;  // world frame; x and y are drawn
  int b = 0, g = 0, r = 0;                 // colour
  bool markers = false;                    // each position a filled circle, no line
};

// A map drawn under the series, seen from above: column (i, j) covers
// [origin + (i, j) * cell, origin + (i + 1, j + 1) * cell) in x-y and holds the height of its
// highest obstacle (m), NaN where the column is empty. Coloured from blue (z_min) to red (z_max).
struct TopViewHeightMap {
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();
  double cell = 1;
  int nx = 0, ny = 0;
  std::vector<float> top_m;  // nx * ny, x fastest
  double z_min = 0, z_max = 1;
};

// The map seen from above: the top of the highest obstacle of each column inside the map's
// bounds, counting only obstacles between z_min_m and z_max_m when given (e.g. below a room's
// ceiling).
TopViewHeightMap HeightMapOf(const planning::PlanningMap& map,
                             double z_min_m = -std::numeric_limits<double>::infinity(),
                             double z_max_m = std::numeric_limits<double>::infinity());

// Writes a PNG with equal axis scales, a grid (1 m for rooms, 5 m up to a plant, at most 30 lines
// per axis whatever the span), a legend and start markers. Series with an empty label get no
// legend entry. With `background`, the view spans the map too. Positions that are not finite or
// lie beyond 1e15 m are not drawn (the line breaks there) and counted on the plot, so the cost is
// bounded by the number of points whatever their values. InvalidArgument if no position is
// drawable, IoError if the PNG cannot be written.
Status WriteTopViewPlot(const std::string& path, const std::string& title,
                        const std::vector<PlotSeries>& series,
                        const TopViewHeightMap* background = nullptr);

}  // namespace mav::plot
