#pragma once
// A clock that moves only when the test says so, for code that takes a TimeSource
// (mav/common/time.h): a Termination's deadline, a WorkQueue's sleeps and run times. A test
// advances it instead of sleeping, so a deadline passes exactly when the test decides.

#include <atomic>
#include <cstdint>

#include "mav/common/time.h"

namespace mav::test_support {

class FakeTimeSource final : public TimeSource {
 public:
  explicit FakeTimeSource(int64_t start_ns = 1'000'000'000) : now_ns_(start_ns) {}
  int64_t NowNs() const override { return now_ns_.load(); }
  void AdvanceNs(int64_t ns) { now_ns_.fetch_add(ns); }
  void AdvanceMs(int64_t ms) { AdvanceNs(ms * 1'000'000); }

 private:
  std::atomic<int64_t> now_ns_;
};

}  // namespace mav::test_support
