#include "mav/common/parallel.h"

#include <algorithm>
#include <thread>
#include <vector>

#include "mav/common/check.h"

namespace mav {

void ParallelFor(int threads, int64_t count,
                 const std::function<void(int part, int64_t begin, int64_t end)>& body) {
  MAV_CHECK(threads >= 1) << "ParallelFor: " << threads << " threads";
  MAV_CHECK(count >= 0) << "ParallelFor: count " << count;
  const int parts = static_cast<int>(std::max<int64_t>(1, std::min<int64_t>(threads, count)));
  const auto run = [&](int p) { body(p, count * p / parts, count * (p + 1) / parts); };
  std::vector<std::thread> others;
  others.reserve(static_cast<size_t>(parts - 1));
  for (int p = 1; p < parts; ++p) others.emplace_back(run, p);
  run(0);
  for (std::thread& t : others) t.join();
}

}  // namespace mav
