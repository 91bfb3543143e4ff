#include "clients/plot/plot.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "mav/dataset/png.h"

namespace mav::plot {
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
                        const std::vector<PlotSeries>& series, const TopViewHeightMap* background) {
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
  if (background != nullptr && background->nx > 0 && background->ny > 0) {
    lo = lo.cwiseMin(background->origin);
    hi = hi.cwiseMax(background->origin +
                     background->cell * Eigen::Vector2d(background->nx, background->ny));
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
  if (background != nullptr) {
    const TopViewHeightMap& m = *background;
    for (int j = 0; j < m.ny; ++j) {
      for (int i = 0; i < m.nx; ++i) {
        const float top = m.top_m[static_cast<size_t>(j) * m.nx + i];
        if (!std::isfinite(top)) continue;
        const double t = std::clamp((top - m.z_min) / std::max(1e-9, m.z_max - m.z_min), 0.0, 1.0);
        cv::Mat1b level(1, 1, static_cast<uint8_t>(std::lround(t * 255)));
        cv::Mat3b colour;
        cv::applyColorMap(level, colour, cv::COLORMAP_JET);
        // Lighter, so the paths drawn on top stand out.
        const cv::Vec3b c = colour(0, 0);
        const cv::Scalar light(0.55 * c[0] + 115, 0.55 * c[1] + 115, 0.55 * c[2] + 115);
        const Eigen::Vector2d a = m.origin + m.cell * Eigen::Vector2d(i, j + 1);
        const Eigen::Vector2d b = m.origin + m.cell * Eigen::Vector2d(i + 1, j);
        cv::rectangle(canvas, to_px(a), to_px(b), light, cv::FILLED);
      }
    }
  }
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
  int legend = 0;
  for (const PlotSeries& s : series) {
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
      if (s.markers) {
        for (const cv::Point& p : pts) cv::circle(canvas, p, 7, colour, cv::FILLED, cv::LINE_AA);
      } else if (pts.size() > 1) {
        cv::polylines(canvas, pts, false, colour, 2, cv::LINE_AA);
      }
    }
    if (!pieces.front().empty()) {
      cv::circle(canvas, pieces.front().front(), 5, colour, cv::FILLED, cv::LINE_AA);
    }
    if (s.label.empty()) continue;
    const int y = margin + 20 * static_cast<int>(legend++);
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
  return dataset::WritePngFile(path, canvas);
}

}  // namespace mav::plot
