#pragma once
// Real-time pacing of simulated data: when data time t is due on the monotonic clock, at a
// real-time factor (2 = twice as fast as real time). The one helper of the simulator's replay
// (frames) and flight mode (steps). The clock is passed in, so tests state the times.
//
//   RealTimePacer pacer(factor, /*max_lateness_ns=*/200'000'000);
//   pacer.Anchor(t0_ns, MonotonicNowNs());
//   for (...) context.SleepUntil(pacer.DueNs(t_ns, MonotonicNowNs()));

#include <cstdint>

namespace mav {

class RealTimePacer {
 public:
  // `factor` > 0; a pacer more than `max_lateness_ns` behind starts anew (see DueNs).
  RealTimePacer(double factor, int64_t max_lateness_ns);

  // Data time `t_ns` is due at monotonic time `wall_ns`.
  void Anchor(int64_t t_ns, int64_t wall_ns);
  void set_factor(double factor);

  // anchor_wall + (t_ns - anchor_t) / factor, computed in double and saturated, so that no
  // factor and no span overflows (a factor of 0.001 stretches a 10-day data set past int64). When
  // `now_ns` is more than max_lateness_ns past that (a slow consumer, a paused debugger), the
  // pacer re-anchors at (t_ns, now_ns) and returns now_ns: it catches up by skipping the backlog
  // of sleeps rather than running flat out until it is on time again.
  int64_t DueNs(int64_t t_ns, int64_t now_ns);

  double factor() const { return factor_; }
  int64_t anchor_t_ns() const { return anchor_t_ns_; }
  int64_t anchor_wall_ns() const { return anchor_wall_ns_; }

 private:
  double factor_;
  int64_t max_lateness_ns_;
  int64_t anchor_t_ns_ = 0, anchor_wall_ns_ = 0;
};

}  // namespace mav
