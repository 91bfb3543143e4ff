#include "clients/plot/control_plot.h"

#include <algorithm>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "mav/dataset/png.h"

namespace mav::plot {

Status WriteControlErrorPlot(const std::string& path, const dataset::FlightTask& task,
                             const std::vector<const eval::FlightRecord*>& records,
                             const std::vector<eval::TaskScore>& scores) {
  const int w = 1100, h = 420, left = 70, right = 20, top = 40, bottom = 50;
  cv::Mat img(h, w, CV_8UC3, cv::Scalar(255, 255, 255));
  // Time span: from the first scored goal's reference time minus 2 s to its window's end.
  double t0 = 0, t1 = task.duration_s;
  if (task.kind == dataset::FlightTaskKind::kDisturbance) {
    t0 = task.forces.front().start_s - 3;
    t1 = std::min(task.duration_s, t0 + 28);
  } else if (task.kind == dataset::FlightTaskKind::kHover) {
    t0 = task.goals.back().publish_s;
    t1 = std::min(task.duration_s, t0 + task.scoring.hover_delay_s + task.scoring.window_s + 2);
  }
  double e_max = 0.05;
  auto goal_at = [&](int g) { return task.goals[std::max(0, g)].position; };
  for (const auto* r : records) {
    for (const auto& s : r->samples) {
      if (s.t_s < t0 || s.t_s > t1 || s.goal_index < 0) continue;
      e_max = std::max(e_max, (s.truth.p_world - goal_at(s.goal_index)).norm());
    }
  }
  e_max = std::min(e_max * 1.1, task.kind == dataset::FlightTaskKind::kHover ? 0.2 : 0.6);
  auto px = [&](double t, double e) {
    return cv::Point(
        left + static_cast<int>((t - t0) / (t1 - t0) * (w - left - right)),
        h - bottom - static_cast<int>(std::min(e, e_max) / e_max * (h - top - bottom)));
  };
  for (const dataset::ForceWindow& f : task.forces) {
    const double a = std::max(f.start_s, t0), b = std::min(f.end_s, t1);
    if (b > a) cv::rectangle(img, px(a, e_max), px(b, 0), cv::Scalar(215, 235, 255), cv::FILLED);
  }
  for (size_t k = 0; k < scores.size(); ++k) {
    for (const eval::GoalScore& g : scores[k].goals) {
      const double a = std::max(g.window_start_s, t0);
      const double b = std::min(g.window_start_s + task.scoring.window_s, t1);
      if (b > a) {
        const cv::Scalar c = k == 0 ? cv::Scalar(40, 160, 40) : cv::Scalar(40, 40, 200);
        const cv::Point lift(0, -5 * static_cast<int>(k));  // one bar above the other
        cv::line(img, px(a, 0) + lift, px(b, 0) + lift, c, 4);
      }
    }
  }
  // 0.1 m settling ball and the full-score band (0.02 m).
  for (double e : {task.scoring.settle_radius_m, 0.1 * task.scoring.position_limit_m}) {
    if (e < e_max) cv::line(img, px(t0, e), px(t1, e), cv::Scalar(160, 160, 160), 1);
  }
  cv::rectangle(img, px(t0, e_max), px(t1, 0), cv::Scalar(0, 0, 0), 1);
  const cv::Scalar colours[2] = {cv::Scalar(40, 160, 40), cv::Scalar(40, 40, 200)};
  for (size_t k = 0; k < records.size(); ++k) {
    std::vector<cv::Point> pts;
    for (const auto& s : records[k]->samples) {
      if (s.t_s < t0 || s.t_s > t1 || s.goal_index < 0) continue;
      pts.push_back(px(s.t_s, (s.truth.p_world - goal_at(s.goal_index)).norm()));
    }
    if (pts.size() > 1) cv::polylines(img, pts, false, colours[k % 2], 1, cv::LINE_AA);
    cv::putText(img, records[k]->controller,
                cv::Point(w - 160, top + 20 + 20 * static_cast<int>(k)), cv::FONT_HERSHEY_SIMPLEX,
                0.55, colours[k % 2], 2, cv::LINE_AA);
  }
  for (int i = 0; i <= 5; ++i) {
    const double e = e_max * i / 5;
    cv::putText(img, cv::format("%.3f", e), cv::Point(5, px(t0, e).y + 4), cv::FONT_HERSHEY_SIMPLEX,
                0.4, cv::Scalar(60, 60, 60), 1, cv::LINE_AA);
    const double t = t0 + (t1 - t0) * i / 5;
    cv::putText(img, cv::format("%.0f s", t), cv::Point(px(t, 0).x - 12, h - bottom + 18),
                cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(60, 60, 60), 1, cv::LINE_AA);
  }
  cv::putText(img,
              task.name +
                  ": position error |p - goal| [m] (shaded: external force; bars: "
                  "scoring windows; lines: 0.1 m ball, 0.02 m full band)",
              cv::Point(left, 25), cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 0), 1,
              cv::LINE_AA);
  return dataset::WritePngFile(path, img);
}

}  // namespace mav::plot
