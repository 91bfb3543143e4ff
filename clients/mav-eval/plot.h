#pragma once
// Top-view (x-y) trajectory plots like the paper's Figure 3, drawn with OpenCV.

#include <string>
#include <vector>

#include <Eigen/Core>

#include "mav/common/status.h"

namespace mav::eval_cli {

struct PlotSeries {
  std::string label;
  std::vector<Eigen::Vector3d> positions;  // world frame; x and y are drawn
  int b = 0, g = 0, r = 0;                 // colour
};

// Writes a PNG with equal axis scales, a grid (1 m for rooms, 5 m up to a plant, at most 30 lines
// per axis whatever the span), a legend and start markers. Positions that are not finite or lie
// beyond 1e15 m are not drawn (the line breaks there) and counted on the plot, so the cost is
// bounded by the number of points whatever their values. InvalidArgument if no position is
// drawable, IoError if the PNG cannot be written.
Status WriteTopViewPlot(const std::string& path, const std::string& title,
                        const std::vector<PlotSeries>& series);

}  // namespace mav::eval_cli
