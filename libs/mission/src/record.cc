#include "mav/mission/record.h"

#include <cmath>

#include "mav/common/time.h"

namespace mav::mission {

FlightRecorder::FlightRecorder(double rate_hz) : period_ns_(PeriodNs(rate_hz)) {}

void FlightRecorder::Offer(const VehicleView& v) {
  if (v.t_ns < next_ns_ || !v.estimator_initialized || !v.truth) return;
  next_ns_ = (v.t_ns / period_ns_ + 1) * period_ns_;
  FlightSample r;
  r.t_s = NsToSeconds(v.t_ns);
  r.p_true = v.truth->p_world;
  r.q_true = v.truth->q_world_body;
  r.v_true = v.truth->v_world;
  r.omega_true = v.truth->omega_body;
  r.p_est = v.p_est;
  r.q_est = v.q_est;
  r.armed = v.armed;
  samples_.push_back(r);
}

double EstimateRmsError(const std::vector<FlightSample>& record) {
  double sum = 0;
  size_t n = 0;
  for (const FlightSample& s : record) {
    if (!s.armed) continue;
    sum += (s.p_est - s.p_true).squaredNorm();
    ++n;
  }
  return n ? std::sqrt(sum / static_cast<double>(n)) : std::nan("");
}

eval::WindowRms ScoreHover(const std::vector<FlightSample>& record, const GoalReport& goal,
                           double settle_s) {
  if (!goal.visited) return {};
  std::vector<eval::FlightTraceSample> trace;
  trace.reserve(record.size());
  for (const FlightSample& s : record) {
    trace.push_back({s.t_s, s.p_true, s.v_true, s.omega_true, s.p_est});
  }
  return eval::RmsOverWindow(trace, goal.hover_start_s + settle_s, goal.reached_at_s, goal.goal);
}

}  // namespace mav::mission
