#include "mav/eval/runtime_stats.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace mav::eval {

RuntimeStats ComputeRuntimeStats(std::vector<double> samples_ms) {
  RuntimeStats s;
  s.count = static_cast<int>(samples_ms.size());
  if (samples_ms.empty()) return s;
  std::sort(samples_ms.begin(), samples_ms.end());
  const size_t n = samples_ms.size();
  s.mean_ms = std::accumulate(samples_ms.begin(), samples_ms.end(), 0.0) / static_cast<double>(n);
  s.median_ms = n % 2 == 1 ? samples_ms[n / 2] : 0.5 * (samples_ms[n / 2 - 1] + samples_ms[n / 2]);
  // Nearest rank: the smallest sample with at least 95 % of samples at or below it.
  const size_t rank = static_cast<size_t>(std::ceil(0.95 * static_cast<double>(n)));
  s.p95_ms = samples_ms[std::max<size_t>(rank, 1) - 1];
  s.max_ms = samples_ms.back();
  return s;
}

}  // namespace mav::eval
