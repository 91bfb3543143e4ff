#include "plot.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace mav::eval_cli {
namespace {

// Points farther out than this are not drawn: no trajectory is that large, a pixel would span
// more than 1e12 m, and pixel coordinates must stay far inside int range.
constexpr double kMaxPlotCoordinateM = 1e15;
// Grid lines per axis at most, whatever the span: the plot's cost must not depend on the data.
constexpr int kMaxGridLines = 30;

bool Drawable(const Eigen::Vector3d& p) {
  return std::isfinite(p.x()) && std::isfinite(p.y()) && std::abs(p.x()) <= kMaxPlotCoordinateM &&
         std::abs(p.y()) <= kMaxPlotCoordinateM;
}

// 1 m for room-sized plots and 5 m up to a plant, as before; beyond that the smallest step of the
// form {1, 2, 5} x 10^k that gives at most kMaxGridLines lines.
double GridStep(double span) {
  if (span <= 30) return 1.0;
  if (span / 5.0 <= kMaxGridLines) return 5.0;
  const double base = std::pow(10.0, std::floor(std::log10(span / kMaxGridLines)));
  for (double m : {1.0, 2.0, 5.0}) {
    if (span / (m * base) <= kMaxGridLines) return m * base;
  }
  return 10.0 * base;
}

}  // namespace

Status WriteTopViewPlot(const std::string& path, const std::string& title,
                        const std::vector<PlotSeries>& series) {
  Eigen::Vector2d lo(kMaxPlotCoordinateM, kMaxPlotCoordinateM);
  Eigen::Vector2d hi(-kMaxPlotCoordinateM, -kMaxPlotCoordinateM);
  int64_t not_drawn = 0;
  for (const PlotSeries& s : series) {
    for (const Eigen::Vector3d& p : s.positions) {
      if (!Drawable(p)) {
        ++not_drawn;
        continue;
      }
      lo = lo.cwiseMin(p.head<2>());
      hi = hi.cwiseMax(p.head<2>());
    }
  }
  if (lo.x() > hi.x()) {
    return Status::InvalidArgument(path + ": no finite position to draw (" +
                                   std::to_string(not_drawn) + " not finite or beyond 1e15 m)");
  }
  const Eigen::Vector2d centre = 0.5 * (lo + hi);
  const double span = std::max({hi.x() - lo.x(), hi.y() - lo.y(), 1.0}) * 1.1;
  const int size = 900, margin = 60;
  const double scale = (size - 2 * margin) / span;
  const auto to_px = [&](const Eigen::Vector2d& p) {
    return cv::Point(static_cast<int>(std::lround(0.5 * size + (p.x() - centre.x()) * scale)),
                     static_cast<int>(std::lround(0.5 * size - (p.y() - centre.y()) * scale)));
  };

  cv::Mat canvas(size, size, CV_8UC3, cv::Scalar(255, 255, 255));
  // Grid lines at multiples of the step, labelled on the axes. Counted by an integer: with a
  // step far below the coordinates' precision, x += step would never move.
  const double grid = GridStep(span);
  const double first_x = std::floor((centre.x() - span / 2) / grid) * grid;
  const double first_y = std::floor((centre.y() - span / 2) / grid) * grid;
  for (int i = 0; i <= kMaxGridLines + 2; ++i) {
    const double x = first_x + i * grid;
    if (x > centre.x() + span / 2) break;
    const cv::Point a = to_px({x, centre.y() - span / 2}), b = to_px({x, centre.y() + span / 2});
    cv::line(canvas, a, b, cv::Scalar(225, 225, 225), 1);
    cv::putText(canvas, cv::format("%g", x), cv::Point(a.x - 8, size - margin / 2),
                cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(90, 90, 90), 1, cv::LINE_AA);
  }
  for (int i = 0; i <= kMaxGridLines + 2; ++i) {
    const double y = first_y + i * grid;
    if (y > centre.y() + span / 2) break;
    const cv::Point a = to_px({centre.x() - span / 2, y}), b = to_px({centre.x() + span / 2, y});
    cv::line(canvas, a, b, cv::Scalar(225, 225, 225), 1);
    if (a.y < margin / 2 || a.y > size - margin) continue;  // keep labels clear of the x axis
    cv::putText(canvas, cv::format("%g", y), cv::Point(8, a.y + 4), cv::FONT_HERSHEY_SIMPLEX, 0.4,
                cv::Scalar(90, 90, 90), 1, cv::LINE_AA);
  }
  for (size_t k = 0; k < series.size(); ++k) {
    const PlotSeries& s = series[k];
    // A point that cannot be drawn breaks the line into pieces rather than joining its
    // neighbours across it.
    std::vector<std::vector<cv::Point>> pieces(1);
    for (const Eigen::Vector3d& p : s.positions) {
      if (Drawable(p)) {
        pieces.back().push_back(to_px(p.head<2>()));
      } else if (!pieces.back().empty()) {
        pieces.emplace_back();
      }
    }
    const cv::Scalar colour(s.b, s.g, s.r);
    for (const std::vector<cv::Point>& pts : pieces) {
      if (pts.size() > 1) cv::polylines(canvas, pts, false, colour, 2, cv::LINE_AA);
    }
    if (!pieces.front().empty()) {
      cv::circle(canvas, pieces.front().front(), 5, colour, cv::FILLED, cv::LINE_AA);
    }
    const int y = margin + 20 * static_cast<int>(k);
    cv::line(canvas, cv::Point(size - 230, y), cv::Point(size - 200, y), colour, 3);
    cv::putText(canvas, s.label, cv::Point(size - 190, y + 5), cv::FONT_HERSHEY_SIMPLEX, 0.5,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  }
  cv::putText(canvas, title + "  (x-y, metres)", cv::Point(margin, 30), cv::FONT_HERSHEY_SIMPLEX,
              0.6, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  if (not_drawn > 0) {
    cv::putText(canvas,
                std::to_string(not_drawn) + " position(s) not finite or beyond 1e15 m: not drawn",
                cv::Point(margin, 50), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 200), 1,
                cv::LINE_AA);
  }
  if (!cv::imwrite(path, canvas)) return Status::IoError(path + ": cannot write PNG");
  return Status::Ok();
}

}  // namespace mav::eval_cli
