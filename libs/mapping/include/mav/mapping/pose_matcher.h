#pragma once
// Pairs live stereo frames with the poses of a separate stream (the mapping service's input:
// frames from mav/sensors/stereo, poses from mav/sim/ground_truth or mav/localization/pose).
//
//  * Ground truth (kInterpolate, e.g. 200 Hz): the pose at the frame's t_ns is interpolated (SE3
//    geodesic, geometry::InterpolatePose) between the last sample <= t and the first sample >= t;
//    each must be within max_gap_ns (25 ms) of t, else the frame has no pose.
//  * Localization (kExact, one pose per processed frame): the pose with exactly the frame's t_ns.
//    One writer, reliable and in order: a newer pose means this frame's pose will not come.
// A frame waits (pending, at most max_pending) until its pose can be decided; it is dropped as
// "without pose" when the pose stream has moved past it without a match, when the history no
// longer reaches back to it, or after wait_ns of wall time (Expire).
//
// Memory: the pose history keeps the newest max_history samples (20 s of 200 Hz ground truth by
// default), the pending buffer the newest max_pending frames.
// Not thread-safe (the service guards it).

#include <algorithm>
#include <cstdint>
#include <deque>
#include <utility>
#include <vector>

#include "mav/geometry/se3.h"

namespace mav::mapping {

struct PoseMatcherOptions {
  enum class Mode { kInterpolate, kExact };
  Mode mode = Mode::kInterpolate;
  int64_t max_gap_ns = 25'000'000;
  int64_t wait_ns = 2'000'000'000;
  size_t max_history = 4000;
  size_t max_pending = 32;
};

// The time-ordered pose samples and the decision for one time stamp.
class PoseHistory {
 public:
  explicit PoseHistory(const PoseMatcherOptions& options) : options_(options) {}

  // Adds T_world_body at t_ns (a repeated stamp replaces the old sample; out-of-order samples
  // are inserted in place). Keeps the newest max_history samples.
  void Add(int64_t t_ns, const geometry::SE3& T_world_body);

  // kPose (written to *T_world_body), kWait (it may come later) or kNoPose (never).
  enum class Decision { kPose, kWait, kNoPose };
  Decision Lookup(int64_t t_ns, geometry::SE3* T_world_body) const;

  size_t size() const { return poses_.size(); }
  void Clear() { poses_.clear(); }

 private:
  PoseMatcherOptions options_;
  std::deque<std::pair<int64_t, geometry::SE3>> poses_;  // ascending t_ns
};

// Frame: any type with a `int64_t t_ns` member (the service's stereo frame with its images).
template <typename Frame>
class PoseMatcher {
 public:
  struct Matched {
    Frame frame;
    geometry::SE3 T_world_body;
  };

  explicit PoseMatcher(const PoseMatcherOptions& options) : options_(options), history_(options) {}

  // Adds a pose sample; returns the pending frames it resolves, in time order. *dropped counts
  // the frames decided to have no pose.
  std::vector<Matched> AddPose(int64_t t_ns, const geometry::SE3& T_world_body, uint64_t* dropped) {
    history_.Add(t_ns, T_world_body);
    if (pending_.empty()) return {};
    return Resolve(dropped);
  }

  // Adds a frame (arrived at monotonic time now_ns); returns it (and any other resolved frames)
  // when its pose is known now. The oldest pending frame is dropped (counted) beyond max_pending.
  std::vector<Matched> AddFrame(Frame frame, int64_t now_ns, uint64_t* dropped) {
    pending_.push_back({std::move(frame), now_ns});
    while (pending_.size() > options_.max_pending) {
      pending_.pop_front();
      if (dropped != nullptr) ++*dropped;
    }
    return Resolve(dropped);
  }

  // Drops frames that waited longer than wait_ns. Returns how many.
  uint64_t Expire(int64_t now_ns) {
    uint64_t n = 0;
    while (!pending_.empty() && now_ns - pending_.front().arrived_ns > options_.wait_ns) {
      pending_.pop_front();
      ++n;
    }
    return n;
  }

  const PoseHistory& history() const { return history_; }
  size_t pending() const { return pending_.size(); }
  void Clear() {
    history_.Clear();
    pending_.clear();
  }

 private:
  struct Pending {
    Frame frame;
    int64_t arrived_ns = 0;
  };

  std::vector<Matched> Resolve(uint64_t* dropped) {
    std::vector<Matched> out;
    for (auto it = pending_.begin(); it != pending_.end();) {
      geometry::SE3 pose;
      const PoseHistory::Decision decision = history_.Lookup(it->frame.t_ns, &pose);
      if (decision == PoseHistory::Decision::kWait) {
        ++it;
        continue;
      }
      if (decision == PoseHistory::Decision::kPose) {
        out.push_back({std::move(it->frame), pose});
      } else if (dropped != nullptr) {
        ++*dropped;
      }
      it = pending_.erase(it);
    }
    std::sort(out.begin(), out.end(),
              [](const Matched& a, const Matched& b) { return a.frame.t_ns < b.frame.t_ns; });
    return out;
  }

  PoseMatcherOptions options_;
  PoseHistory history_;
  std::deque<Pending> pending_;  // ascending arrival
};

}  // namespace mav::mapping
