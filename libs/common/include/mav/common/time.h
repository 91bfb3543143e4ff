#pragma once
// Time is an int64_t count of nanoseconds (`t_ns`), as in EuRoC's file names and CSV columns.
// Doubles in seconds appear only inside maths (spline evaluation, integration steps).

#include <cstdint>

namespace mav {

inline constexpr int64_t kNsPerSecond = 1'000'000'000;

constexpr double NsToSeconds(int64_t t_ns) { return static_cast<double>(t_ns) * 1e-9; }
// Rounds to the nearest nanosecond.
constexpr int64_t SecondsToNs(double seconds) {
  return static_cast<int64_t>(seconds * 1e9 + (seconds >= 0 ? 0.5 : -0.5));
}
// Period of a rate in Hz, in ns (20 Hz -> 50'000'000).
constexpr int64_t PeriodNs(double rate_hz) { return SecondsToNs(1.0 / rate_hz); }

// Monotonic clock for measuring durations.
int64_t MonotonicNowNs();
// Wall clock (UNIX epoch) for stamping live data.
int64_t WallNowNs();

// A monotonic clock that can be replaced, for code whose tests must control time: a work queue's
// paced sleeps and run times, a Termination's deadline. Production code passes no source (null)
// and reads MonotonicNowNs() directly, so the hot paths pay a null test, not a virtual call; a
// test passes its own source and moves it by hand instead of sleeping. A source must outlive
// everything that was given it.
class TimeSource {
 public:
  virtual ~TimeSource() = default;
  virtual int64_t NowNs() const = 0;
};

// `source`'s time, or MonotonicNowNs() when `source` is null.
inline int64_t NowNs(const TimeSource* source) {
  return source == nullptr ? MonotonicNowNs() : source->NowNs();
}

// The one way to time a piece of work: take `const int64_t start_ns = MonotonicNowNs();`, then
// read MsSince(start_ns) for a per-call time (fields named `_ms`) or SecondsSince(start_ns) for
// a whole run (fields named `_s`).
double MsSince(int64_t start_ns);
double SecondsSince(int64_t start_ns);

}  // namespace mav
