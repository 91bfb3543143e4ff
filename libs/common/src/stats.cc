#include "mav/common/stats.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "mav/common/check.h"

namespace mav {

double NearestRankPercentile(const std::vector<double>& sorted, double p) {
  MAV_CHECK(p > 0 && p <= 100) << "percentile " << p;
  if (sorted.empty()) return 0;
  const double n = static_cast<double>(sorted.size());
  // The small slack keeps 0.95 * 20 = 19 from becoming 19.000000000000004 -> rank 20.
  const size_t rank = static_cast<size_t>(std::ceil(p / 100.0 * n - 1e-9));
  return sorted[std::clamp<size_t>(rank, 1, sorted.size()) - 1];
}

RuntimeStats SummarizeRuntimes(std::vector<double> samples_ms) {
  RuntimeStats s;
  s.count = samples_ms.size();
  if (samples_ms.empty()) return s;
  std::sort(samples_ms.begin(), samples_ms.end());
  const size_t n = samples_ms.size();
  s.mean_ms = std::accumulate(samples_ms.begin(), samples_ms.end(), 0.0) / static_cast<double>(n);
  s.median_ms = n % 2 == 1 ? samples_ms[n / 2] : 0.5 * (samples_ms[n / 2 - 1] + samples_ms[n / 2]);
  s.p95_ms = NearestRankPercentile(samples_ms, 95);
  s.p99_ms = NearestRankPercentile(samples_ms, 99);
  s.max_ms = samples_ms.back();
  return s;
}

RuntimeWindow::RuntimeWindow(size_t capacity) : capacity_(capacity) {
  MAV_CHECK(capacity > 0) << "a runtime window needs room for one sample";
  samples_.reserve(std::min<size_t>(capacity, 4096));
}

void RuntimeWindow::Add(double ms) {
  ++total_;
  if (samples_.size() < capacity_) {
    samples_.push_back(ms);
    return;
  }
  samples_[next_] = ms;
  next_ = (next_ + 1) % capacity_;
}

void RuntimeWindow::Clear() {
  samples_.clear();
  next_ = 0;
  total_ = 0;
}

RuntimeStats RuntimeWindow::Summary() const { return SummarizeRuntimes(samples_); }

RateMeter::RateMeter(int64_t window_ns, int64_t stale_ns)
    : window_ns_(window_ns), stale_ns_(stale_ns) {}

void RateMeter::Add(int64_t now_ns) {
  if (!any_) {
    // The first event opens the first window; a window counts the events after its start, so
    // that N events a second read N Hz.
    any_ = true;
    window_start_ns_ = last_ns_ = now_ns;
    return;
  }
  ++count_;
  last_ns_ = now_ns;
  if (now_ns - window_start_ns_ >= window_ns_) {
    rate_hz_ = static_cast<double>(count_) * 1e9 / static_cast<double>(now_ns - window_start_ns_);
    window_start_ns_ = now_ns;
    count_ = 0;
  }
}

double RateMeter::Rate(int64_t now_ns) const {
  if (!any_ || now_ns - last_ns_ > stale_ns_) return 0.0;
  if (rate_hz_ > 0) return rate_hz_;
  // No whole window yet (a short lock-stepped flight): the events so far.
  return count_ >= 1 && last_ns_ > window_start_ns_
             ? static_cast<double>(count_) * 1e9 / static_cast<double>(last_ns_ - window_start_ns_)
             : 0.0;
}

void RateMeter::Clear() { *this = RateMeter(window_ns_, stale_ns_); }

}  // namespace mav
