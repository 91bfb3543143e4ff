#include "mav/mapping/pose_matcher.h"

namespace mav::mapping {

namespace {

bool Earlier(const std::pair<int64_t, geometry::SE3>& p, int64_t t) { return p.first < t; }

}  // namespace

void PoseHistory::Add(int64_t t_ns, const geometry::SE3& T_world_body) {
  if (poses_.empty() || poses_.back().first < t_ns) {
    poses_.emplace_back(t_ns, T_world_body);
  } else {
    const auto at = std::lower_bound(poses_.begin(), poses_.end(), t_ns, Earlier);
    if (at != poses_.end() && at->first == t_ns) {
      at->second = T_world_body;  // a repeated sample (e.g. a replay) replaces the old one
    } else {
      poses_.insert(at, {t_ns, T_world_body});
    }
  }
  while (poses_.size() > options_.max_history) poses_.pop_front();
}

PoseHistory::Decision PoseHistory::Lookup(int64_t t_ns, geometry::SE3* T_world_body) const {
  if (poses_.empty()) return Decision::kWait;
  const auto after = std::lower_bound(poses_.begin(), poses_.end(), t_ns, Earlier);
  if (options_.mode == PoseMatcherOptions::Mode::kExact) {
    if (after != poses_.end() && after->first == t_ns) {
      *T_world_body = after->second;
      return Decision::kPose;
    }
    return poses_.back().first > t_ns ? Decision::kNoPose : Decision::kWait;
  }
  if (after == poses_.end()) return Decision::kWait;  // nothing at or after t yet
  if (after->first == t_ns) {
    *T_world_body = after->second;
    return Decision::kPose;
  }
  if (after == poses_.begin()) return Decision::kNoPose;  // history starts after the frame
  const auto before = std::prev(after);
  if (t_ns - before->first > options_.max_gap_ns || after->first - t_ns > options_.max_gap_ns) {
    return Decision::kNoPose;
  }
  const double alpha =
      static_cast<double>(t_ns - before->first) / static_cast<double>(after->first - before->first);
  *T_world_body = geometry::InterpolatePose(before->second, after->second, alpha);
  return Decision::kPose;
}

}  // namespace mav::mapping
