#pragma once
// The one way the libraries split a loop over threads: [0, count) in `threads` contiguous parts,
// part 0 on the calling thread, the others on threads started for the call and joined before it
// returns. A library with a split that must not depend on the thread count (a result OR-ed from
// per-part masks, a sum in a fixed order) gives each part its own output, indexed by `part`.
//
//   ParallelFor(options.threads, edges.size(), [&](int part, int64_t begin, int64_t end) {
//     for (int64_t i = begin; i < end; ++i) Cost(edges[i]);
//   });
//
// No pool: the loops split here run for milliseconds to seconds, against ~20 us to start a
// thread, and the services already own their threads (WorkQueue); a pool would be one more
// set of threads to size and shut down.

#include <cstdint>
#include <functional>

namespace mav {

// Runs body(part, begin, end) for each part p of [0, count) cut into `threads` (>= 1; at most
// `count` parts, so no part is empty unless count is 0, when body runs once with 0, 0), part p
// being [count * p / parts, count * (p + 1) / parts). Returns when every part has.
void ParallelFor(int threads, int64_t count,
                 const std::function<void(int part, int64_t begin, int64_t end)>& body);

}  // namespace mav
