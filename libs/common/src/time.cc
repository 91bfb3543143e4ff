#include "mav/common/time.h"

#include <chrono>

namespace mav {

int64_t MonotonicNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

int64_t WallNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

double MsSince(int64_t start_ns) { return NsToSeconds(MonotonicNowNs() - start_ns) * 1e3; }

double SecondsSince(int64_t start_ns) { return NsToSeconds(MonotonicNowNs() - start_ns); }

}  // namespace mav
