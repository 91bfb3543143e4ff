#include "mav/common/termination.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "mav/common/check.h"
#include "mav/common/time.h"

namespace mav {

Termination Termination::AfterMs(double budget_ms, const TimeSource* source) {
  Termination t;
  t.source_ = source;
  const int64_t now = t.NowNs();
  if (!(budget_ms > 0)) {
    t.deadline_ns_ = now;
  } else if (budget_ms * 1e6 >= static_cast<double>(kNever - now)) {
    t.deadline_ns_ = kNever;
  } else {
    t.deadline_ns_ = now + static_cast<int64_t>(std::ceil(budget_ms * 1e6));
  }
  return t;
}

Termination Termination::AtMonotonicNs(int64_t deadline_ns) { return AtNs(deadline_ns, nullptr); }

Termination Termination::AtNs(int64_t deadline_ns, const TimeSource* source) {
  Termination t;
  t.deadline_ns_ = deadline_ns;
  t.source_ = source;
  return t;
}

Termination Termination::WithCancel(const CancelFlag& flag) const {
  Termination t = *this;
  if (t.cancel_ == nullptr || t.cancel_ == flag.flag_) {
    t.cancel_ = flag.flag_;
  } else {
    MAV_CHECK(t.cancel2_ == nullptr || t.cancel2_ == flag.flag_)
        << "a Termination observes two cancel flags at most";
    t.cancel2_ = flag.flag_;
  }
  return t;
}

Termination Termination::WithDeadlineNs(int64_t deadline_ns) const {
  Termination t = *this;
  t.deadline_ns_ = std::min(deadline_ns_, deadline_ns);
  return t;
}

bool Termination::cancelled() const {
  return (cancel_ != nullptr && cancel_->load(std::memory_order_relaxed)) ||
         (cancel2_ != nullptr && cancel2_->load(std::memory_order_relaxed));
}

bool Termination::expired() const { return deadline_ns_ != kNever && NowNs() >= deadline_ns_; }

Status Termination::Check(std::string_view what) const {
  if (cancelled()) return Status::Cancelled(std::string(what) + ": cancelled");
  if (expired()) return Status::DeadlineExceeded(std::string(what) + ": deadline exceeded");
  return Status::Ok();
}

int64_t Termination::RemainingNs() const {
  if (deadline_ns_ == kNever) return kNever;
  return deadline_ns_ - NowNs();
}

}  // namespace mav
