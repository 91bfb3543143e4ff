#pragma once
// Summary statistics of per-frame runtimes.

#include <vector>

namespace mav::eval {

struct RuntimeStats {
  int count = 0;
  double mean_ms = 0;
  double median_ms = 0;
  double p95_ms = 0;  // nearest-rank 95th percentile
  double max_ms = 0;
};

RuntimeStats ComputeRuntimeStats(std::vector<double> samples_ms);

}  // namespace mav::eval
