#include "plot.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace mav::eval_cli {

Status WriteTopViewPlot(const std::string& path, const std::string& title,
                        const std::vector<PlotSeries>& series, const TopViewHeightMap* background) {
  Eigen::Vector2d lo(1e18, 1e18), hi(-1e18, -1e18);
  for (const PlotSeries& s : series) {
    for (const Eigen::Vector3d& p : s.positions) {
      lo = lo.cwiseMin(p.head<2>());
      hi = hi.cwiseMax(p.head<2>());
    }
  }
  if (background != nullptr && background->nx > 0 && background->ny > 0) {
    lo = lo.cwiseMin(background->origin);
    hi = hi.cwiseMax(background->origin +
                     background->cell * Eigen::Vector2d(background->nx, background->ny));
  }
  if (lo.x() > hi.x()) return Status::InvalidArgument("plot: no positions to draw");
  const Eigen::Vector2d centre = 0.5 * (lo + hi);
  const double span = std::max({hi.x() - lo.x(), hi.y() - lo.y(), 1.0}) * 1.1;
  const int size = 900, margin = 60;
  const double scale = (size - 2 * margin) / span;
  const auto to_px = [&](const Eigen::Vector2d& p) {
    return cv::Point(static_cast<int>(std::lround(size / 2 + (p.x() - centre.x()) * scale)),
                     static_cast<int>(std::lround(size / 2 - (p.y() - centre.y()) * scale)));
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
  // Grid every 1 m (every 5 m for large spans), labelled on the axes.
  const double grid = span > 30 ? 5.0 : 1.0;
  for (double x = std::floor((centre.x() - span / 2) / grid) * grid; x <= centre.x() + span / 2;
       x += grid) {
    const cv::Point a = to_px({x, centre.y() - span / 2}), b = to_px({x, centre.y() + span / 2});
    cv::line(canvas, a, b, cv::Scalar(225, 225, 225), 1);
    cv::putText(canvas, cv::format("%g", x), cv::Point(a.x - 8, size - margin / 2),
                cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(90, 90, 90), 1, cv::LINE_AA);
  }
  for (double y = std::floor((centre.y() - span / 2) / grid) * grid; y <= centre.y() + span / 2;
       y += grid) {
    const cv::Point a = to_px({centre.x() - span / 2, y}), b = to_px({centre.x() + span / 2, y});
    cv::line(canvas, a, b, cv::Scalar(225, 225, 225), 1);
    if (a.y < margin / 2 || a.y > size - margin) continue;  // keep labels clear of the x axis
    cv::putText(canvas, cv::format("%g", y), cv::Point(8, a.y + 4), cv::FONT_HERSHEY_SIMPLEX, 0.4,
                cv::Scalar(90, 90, 90), 1, cv::LINE_AA);
  }
  int legend = 0;
  for (size_t k = 0; k < series.size(); ++k) {
    const PlotSeries& s = series[k];
    std::vector<cv::Point> pts;
    pts.reserve(s.positions.size());
    for (const Eigen::Vector3d& p : s.positions) pts.push_back(to_px(p.head<2>()));
    const cv::Scalar colour(s.b, s.g, s.r);
    if (pts.size() > 1) cv::polylines(canvas, pts, false, colour, 2, cv::LINE_AA);
    if (!pts.empty()) cv::circle(canvas, pts.front(), 5, colour, cv::FILLED, cv::LINE_AA);
    if (s.label.empty()) continue;
    const int y = margin + 20 * static_cast<int>(legend++);
    cv::line(canvas, cv::Point(size - 230, y), cv::Point(size - 200, y), colour, 3);
    cv::putText(canvas, s.label, cv::Point(size - 190, y + 5), cv::FONT_HERSHEY_SIMPLEX, 0.5,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  }
  cv::putText(canvas, title + "  (x-y, metres)", cv::Point(margin, 30), cv::FONT_HERSHEY_SIMPLEX,
              0.6, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  if (!cv::imwrite(path, canvas)) return Status::IoError(path + ": cannot write PNG");
  return Status::Ok();
}

}  // namespace mav::eval_cli
