#pragma once
// The one set of runtime statistics of the stack (services' status replies, mav-eval's tables,
// mav-load's report): mean, median and nearest-rank percentiles of per-call times in ms.
//
// Nearest rank: the p-th percentile is the smallest sample with at least p % of the samples at
// or below it, i.e. sorted[ceil(p / 100 * n) - 1]. For 20 samples p95 is the 19th smallest, not
// the maximum; for one sample every percentile is that sample. The median is the middle sample
// (the mean of the two middle ones for an even count).

#include <cstddef>
#include <cstdint>
#include <vector>

namespace mav {

struct RuntimeStats {
  uint64_t count = 0;
  double mean_ms = 0;
  double median_ms = 0;
  double p95_ms = 0;
  double p99_ms = 0;
  double max_ms = 0;
};

// Statistics of `samples_ms` (all zero for no samples).
RuntimeStats SummarizeRuntimes(std::vector<double> samples_ms);

// Nearest-rank percentile `p` in (0, 100] of samples sorted ascending (0 when empty).
double NearestRankPercentile(const std::vector<double>& sorted, double p);

// The last `capacity` samples of a stream (a ring buffer: memory is bounded by the capacity
// whatever runs through it), with the count of all samples ever added. Not thread-safe: the
// owner guards it.
class RuntimeWindow {
 public:
  explicit RuntimeWindow(size_t capacity = 1000);

  void Add(double ms);
  void Clear();
  // Statistics of the samples in the window; `count` is the number in the window.
  RuntimeStats Summary() const;
  uint64_t total_count() const { return total_; }
  size_t size() const { return samples_.size(); }
  size_t capacity() const { return capacity_; }

 private:
  size_t capacity_;
  std::vector<double> samples_;
  size_t next_ = 0;  // where the next sample goes once the window is full
  uint64_t total_ = 0;
};

// Events per second on a monotonic clock (IMU samples, poses, published frames), the clock passed
// in so that tests drive it: counts in windows of `window_ns` and reports the last whole window's
// rate, or before the first one ends, the rate of the events so far (two or more); 0 when the
// last event is more than `stale_ns` old (the stream stopped) or none came. Not thread-safe: the
// owner serialises Add and Rate.
class RateMeter {
 public:
  explicit RateMeter(int64_t window_ns = 1'000'000'000, int64_t stale_ns = 2'000'000'000);

  void Add(int64_t now_ns);
  double Rate(int64_t now_ns) const;
  void Clear();

 private:
  int64_t window_ns_, stale_ns_;
  int64_t window_start_ns_ = 0, last_ns_ = 0;
  uint64_t count_ = 0;  // events since window_start_ns_
  bool any_ = false;
  double rate_hz_ = 0;  // of the last whole window
};

}  // namespace mav
