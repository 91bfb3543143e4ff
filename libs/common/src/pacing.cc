#include "mav/common/pacing.h"

#include "mav/common/check.h"

namespace mav {

namespace {

// Far beyond any due time, far below INT64_MAX (no sum with it overflows).
constexpr double kFarFutureNs = 4e18;

}  // namespace

RealTimePacer::RealTimePacer(double factor, int64_t max_lateness_ns)
    : factor_(factor), max_lateness_ns_(max_lateness_ns) {
  MAV_CHECK(factor > 0) << "RealTimePacer: factor " << factor;
}

void RealTimePacer::Anchor(int64_t t_ns, int64_t wall_ns) {
  anchor_t_ns_ = t_ns;
  anchor_wall_ns_ = wall_ns;
}

void RealTimePacer::set_factor(double factor) {
  MAV_CHECK(factor > 0) << "RealTimePacer: factor " << factor;
  factor_ = factor;
}

int64_t RealTimePacer::DueNs(int64_t t_ns, int64_t now_ns) {
  const double due_d =
      static_cast<double>(anchor_wall_ns_) + static_cast<double>(t_ns - anchor_t_ns_) / factor_;
  const int64_t due = due_d >= kFarFutureNs    ? static_cast<int64_t>(kFarFutureNs)
                      : due_d <= -kFarFutureNs ? static_cast<int64_t>(-kFarFutureNs)
                                               : static_cast<int64_t>(due_d);
  if (now_ns - due > max_lateness_ns_) {
    Anchor(t_ns, now_ns);
    return now_ns;
  }
  return due;
}

}  // namespace mav
