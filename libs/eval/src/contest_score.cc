#include "mav/eval/contest_score.h"

#include <algorithm>
#include <cmath>

namespace mav::eval {

double BandPoints(double value, double limit, bool rate) {
  const double ratio = value / limit;
  if (!(ratio <= 1.0)) return 0.0;  // also NaN
  if (ratio > 0.5) return rate ? 1.0 : 1.5;
  if (ratio > 0.1) return rate ? 2.0 : 3.5;
  return rate ? 3.0 : 5.0;
}

SettleResult FindSettling(const std::vector<FlightTraceSample>& trace, double from_s,
                          const Eigen::Vector3d& goal, const dataset::FlightScoring& scoring) {
  // Forward scan: the first run of in-ball samples that lasts hold_s settles the vehicle at the
  // run's start.
  const double r2 = scoring.settle_radius_m * scoring.settle_radius_m;
  SettleResult result;
  double run_start = -1;  // time the current in-ball run began (forward scan)
  for (const FlightTraceSample& s : trace) {
    if (s.t_s < from_s - 1e-9) continue;
    if ((s.p_world - goal).squaredNorm() <= r2) {
      if (run_start < 0) run_start = s.t_s;
      if (s.t_s - run_start >= scoring.settle_hold_s - 1e-9) {
        result.settling_time_s = std::max(0.0, run_start - from_s);
        result.settled = result.settling_time_s <= scoring.settle_limit_s + 1e-9;
        return result;
      }
    } else {
      run_start = -1;
      if (s.t_s - from_s > scoring.settle_limit_s) return result;  // too late already
    }
  }
  return result;
}

WindowRms RmsOverWindow(const std::vector<FlightTraceSample>& trace, double t0, double t1,
                        const Eigen::Vector3d& goal) {
  WindowRms w;
  double sp = 0, sr = 0, se = 0;
  for (const FlightTraceSample& s : trace) {
    if (s.t_s < t0 - 1e-9 || s.t_s >= t1 - 1e-9) continue;
    sp += (s.p_world - goal).squaredNorm();
    sr += s.omega_body.squaredNorm();
    se += (s.p_estimate - s.p_world).squaredNorm();
    ++w.samples;
  }
  if (w.samples > 0) {
    w.position_rms_m = std::sqrt(sp / w.samples);
    w.angular_rate_rms_radps = std::sqrt(sr / w.samples);
    w.estimator_rms_m = std::sqrt(se / w.samples);
  }
  return w;
}

namespace {

// The leg from `from` to `to` published at `publish_s`: leaves the start's ball, enters the
// goal's.
void LegFigures(const std::vector<FlightTraceSample>& trace, double publish_s, double end_s,
                const Eigen::Vector3d& from, const Eigen::Vector3d& to, double radius,
                GoalScore* g) {
  double leave = -1, arrive = -1, length = 0, peak = 0;
  const FlightTraceSample* prev = nullptr;
  for (const FlightTraceSample& s : trace) {
    if (s.t_s < publish_s || s.t_s >= end_s) continue;
    if (leave < 0 && (s.p_world - from).norm() > radius) leave = s.t_s;
    if (leave >= 0 && arrive < 0) {
      if (prev) length += (s.p_world - prev->p_world).norm();
      peak = std::max(peak, s.v_world.norm());
      if ((s.p_world - to).norm() <= radius) arrive = s.t_s;
    }
    prev = &s;
  }
  if (leave < 0 || arrive < 0) return;
  g->flight_time_s = arrive - leave;
  g->path_length_m = length;
  g->mean_speed_mps = g->flight_time_s > 0 ? length / g->flight_time_s : 0;
  g->peak_speed_mps = peak;
}

}  // namespace

TaskScore ScoreFlightTask(const dataset::FlightTask& task,
                          const std::vector<FlightTraceSample>& trace, int collisions) {
  const dataset::FlightScoring& sc = task.scoring;
  TaskScore out;
  out.task = task.name;
  out.collisions = collisions;
  const bool hover = task.kind == dataset::FlightTaskKind::kHover;
  const bool disturbance = task.kind == dataset::FlightTaskKind::kDisturbance;
  std::vector<int> scored;
  if (hover || disturbance) {
    scored.push_back(static_cast<int>(task.goals.size()) - 1);
  } else {
    for (int i = 1; i < static_cast<int>(task.goals.size()); ++i) scored.push_back(i);
  }
  for (int i : scored) {
    const dataset::FlightGoal& goal = task.goals[i];
    GoalScore g;
    g.goal = i;
    if (hover) {
      g.from_s = goal.publish_s;
      g.window_start_s = goal.publish_s + sc.hover_delay_s;
      g.rms = RmsOverWindow(trace, g.window_start_s, g.window_start_s + sc.window_s, goal.position);
    } else {
      g.from_s = disturbance ? task.forces.front().start_s : goal.publish_s;
      const SettleResult settle = FindSettling(trace, g.from_s, goal.position, sc);
      g.settled = settle.settled;
      if (settle.settled) {
        g.settling_time_s = settle.settling_time_s;
        g.window_start_s = g.from_s + settle.settling_time_s;
        g.rms =
            RmsOverWindow(trace, g.window_start_s, g.window_start_s + sc.window_s, goal.position);
      } else {
        g.settling_time_s = 1.01 * sc.settle_limit_s;
        g.window_start_s = g.from_s;
        g.rms.position_rms_m = 1.01 * sc.position_limit_m;
        g.rms.angular_rate_rms_radps = 1.01 * sc.angular_rate_limit_radps;
        g.rms.estimator_rms_m =
            RmsOverWindow(trace, g.from_s, g.from_s + sc.settle_limit_s, goal.position)
                .estimator_rms_m;
      }
      g.settling_points = BandPoints(g.settling_time_s, sc.settle_limit_s, false);
      out.max_points += 5.0;
      if (!disturbance && i > 0) {
        const double end_s = i + 1 < static_cast<int>(task.goals.size())
                                 ? task.goals[i + 1].publish_s
                                 : task.duration_s + 1;
        LegFigures(trace, goal.publish_s, end_s, task.goals[i - 1].position, goal.position,
                   sc.settle_radius_m, &g);
      }
    }
    g.position_points = BandPoints(g.rms.position_rms_m, sc.position_limit_m, false);
    g.angular_rate_points =
        BandPoints(g.rms.angular_rate_rms_radps, sc.angular_rate_limit_radps, true);
    out.max_points += 5.0 + 3.0;
    // A disturbance task that does not settle scores nothing at all.
    const bool nothing = disturbance && !g.settled;
    out.points += nothing ? 0.0 : g.position_points + g.angular_rate_points + g.settling_points;
    out.all_settled = out.all_settled && g.settled;
    out.goals.push_back(g);
  }
  if (collisions > 0) out.points = 0;
  const double n = static_cast<double>(out.goals.size());
  for (const GoalScore& g : out.goals) {
    out.position_rms_m += g.rms.position_rms_m / n;
    out.angular_rate_rms_radps += g.rms.angular_rate_rms_radps / n;
    out.settling_time_s += g.settling_time_s / n;
    out.estimator_rms_m += g.rms.estimator_rms_m / n;
  }
  return out;
}

}  // namespace mav::eval
