#include "mav/common/parallel.h"

#include <algorithm>
#include <atomic>
#include <mutex>
#include <set>
#include <thread>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

namespace mav {
namespace {

// Every index runs once, the parts are the documented contiguous ranges, part 0 runs on the
// caller's thread and the others on threads of their own.
TEST(ParallelForTest, PartsCoverTheRangeOnceInContiguousPieces) {
  for (int threads : {1, 2, 3, 7}) {
    for (int64_t count : {0, 1, 2, 5, 100}) {
      SCOPED_TRACE(testing::Message() << threads << " threads, " << count);
      std::vector<std::atomic<int>> hits(static_cast<size_t>(count));
      std::mutex mutex;
      std::set<std::tuple<int, int64_t, int64_t>> parts;
      std::set<std::thread::id> ids;
      std::thread::id part0;
      ParallelFor(threads, count, [&](int part, int64_t begin, int64_t end) {
        for (int64_t i = begin; i < end; ++i) ++hits[static_cast<size_t>(i)];
        std::lock_guard<std::mutex> lock(mutex);
        parts.insert({part, begin, end});
        ids.insert(std::this_thread::get_id());
        if (part == 0) part0 = std::this_thread::get_id();
      });
      for (const std::atomic<int>& h : hits) EXPECT_EQ(h.load(), 1);
      const int expected_parts =
          static_cast<int>(std::max<int64_t>(1, std::min<int64_t>(threads, count)));
      ASSERT_EQ(static_cast<int>(parts.size()), expected_parts);
      int p = 0;
      for (const auto& [part, begin, end] : parts) {
        EXPECT_EQ(part, p);
        EXPECT_EQ(begin, count * p / expected_parts);
        EXPECT_EQ(end, count * (p + 1) / expected_parts);
        ++p;
      }
      EXPECT_EQ(part0, std::this_thread::get_id());
      EXPECT_EQ(static_cast<int>(ids.size()), expected_parts);
    }
  }
}

}  // namespace
}  // namespace mav
