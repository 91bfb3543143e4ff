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

// Writes a PNG with equal axis scales, a 1 m grid, a legend and start markers.
Status WriteTopViewPlot(const std::string& path, const std::string& title,
                        const std::vector<PlotSeries>& series);

}  // namespace mav::eval_cli
