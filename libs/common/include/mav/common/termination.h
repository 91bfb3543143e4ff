#pragma once
// When long work must stop, and how it reports progress.
//
// A Termination is polled by long library calls (a roadmap build, a map build, a render): it is
// a deadline on the monotonic clock and/or a cancel flag, the earlier of the two wins. It plays
// the role of OMPL's PlannerTerminationCondition; progress is reported through a callback, as
// Ceres' IterationCallback does, so a library never needs to know who is waiting.
//
//   CancelFlag cancel;                                   // shared with whoever may cancel
//   const Termination stop = Termination::AfterMs(750).WithCancel(cancel);
//   for (...) {
//     MAV_RETURN_IF_ERROR(stop.Check("roadmap build"));  // DEADLINE_EXCEEDED / CANCELLED
//     ...
//   }
//
// Copies are cheap (an int64, a pointer and shared pointers) and may be polled from any thread.
// The deadline is on the monotonic clock, or on a TimeSource given at creation (tests drive it by
// hand); the source must outlive the Termination and its copies.

#include <atomic>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <string_view>

#include "mav/common/status.h"
#include "mav/common/time.h"

namespace mav {

// A flag that one side raises and any number of Terminations observe. Copies share the flag.
class CancelFlag {
 public:
  CancelFlag() : flag_(std::make_shared<std::atomic<bool>>(false)) {}
  void Cancel() const { flag_->store(true, std::memory_order_relaxed); }
  bool cancelled() const { return flag_->load(std::memory_order_relaxed); }

 private:
  friend class Termination;
  std::shared_ptr<std::atomic<bool>> flag_;
};

class Termination {
 public:
  static constexpr int64_t kNever = std::numeric_limits<int64_t>::max();

  // Never stops on its own (no deadline, no flag).
  Termination() = default;
  static Termination Never() { return {}; }
  // Stops `budget_ms` from now (<= 0: already expired), on `source`'s time (null: monotonic).
  static Termination AfterMs(double budget_ms, const TimeSource* source = nullptr);
  // Stops when MonotonicNowNs() reaches `deadline_ns` (kNever = no deadline).
  static Termination AtMonotonicNs(int64_t deadline_ns);
  // Stops when `source`'s time reaches `deadline_ns` (null: as AtMonotonicNs).
  static Termination AtNs(int64_t deadline_ns, const TimeSource* source);

  // A copy that also stops when `flag` is raised. Two flags at most (the caller's, e.g. a
  // client that went away, and the owner's, e.g. a shutdown); a third is a bug (MAV_CHECK).
  Termination WithCancel(const CancelFlag& flag) const;
  // A copy whose deadline is the earlier of this one's and `deadline_ns` (on this one's clock).
  Termination WithDeadlineNs(int64_t deadline_ns) const;

  bool cancelled() const;
  bool expired() const;  // the deadline has passed
  bool ShouldStop() const { return cancelled() || expired(); }
  // OK, or Cancelled / DeadlineExceeded with "<what>: cancelled" / "<what>: deadline exceeded".
  Status Check(std::string_view what) const;

  // kNever when there is no deadline.
  int64_t deadline_ns() const { return deadline_ns_; }
  // Nanoseconds left before the deadline (<= 0 when passed; kNever without a deadline).
  int64_t RemainingNs() const;
  // The time the deadline is measured on: its TimeSource's, else MonotonicNowNs().
  int64_t NowNs() const { return mav::NowNs(source_); }

 private:
  int64_t deadline_ns_ = kNever;
  const TimeSource* source_ = nullptr;  // null: the monotonic clock
  std::shared_ptr<const std::atomic<bool>> cancel_;
  std::shared_ptr<const std::atomic<bool>> cancel2_;
};

// Progress of long work: `stage` names the step ("distance map", "roadmap"), `fraction` in
// [0, 1] is the share of that step done. Called from the thread doing the work; keep it short.
using ProgressCallback = std::function<void(std::string_view stage, double fraction)>;

}  // namespace mav
