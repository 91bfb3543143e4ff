#include "mav/mapping/keyframes.h"

#include <cmath>

#include "mav/common/check.h"

namespace mav::mapping {

bool KeyframeOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!std::isfinite(min_translation_m) || !(min_translation_m > 0.0)) {
    return fail("min_translation_m must be finite and > 0 [m], got " +
                std::to_string(min_translation_m));
  }
  if (!std::isfinite(min_rotation_rad) || !(min_rotation_rad > 0.0)) {
    return fail("min_rotation_rad must be finite and > 0 [rad], got " +
                std::to_string(min_rotation_rad));
  }
  return true;
}

KeyframeSelector::KeyframeSelector(const KeyframeOptions& options) : options_(options) {
  std::string why;
  MAV_CHECK(options_.IsValid(&why)) << "KeyframeOptions: " << why;
}

bool KeyframeSelector::Consider(const geometry::SE3& T_world_cam) {
  bool is_keyframe = !has_reference_;
  if (!is_keyframe) {
    const double translation =
        (T_world_cam.Translation() - T_world_last_keyframe_.Translation()).norm();
    const double rotation =
        geometry::AngleBetween(T_world_last_keyframe_.Rotation(), T_world_cam.Rotation());
    is_keyframe =
        translation >= options_.min_translation_m || rotation >= options_.min_rotation_rad;
  }
  if (is_keyframe) {
    has_reference_ = true;
    T_world_last_keyframe_ = T_world_cam;
    ++num_keyframes_;
  }
  return is_keyframe;
}

void KeyframeSelector::Reset() {
  has_reference_ = false;
  num_keyframes_ = 0;
}

Result<std::vector<int64_t>> SelectKeyframes(const std::vector<StampedCameraPose>& poses,
                                             const KeyframeOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument("options." + why);
  for (size_t i = 0; i < poses.size(); ++i) {
    const geometry::SE3& T = poses[i].T_world_cam;
    if (!T.Translation().allFinite() || !T.Rotation().coeffs().allFinite()) {
      return Status::InvalidArgument("poses[" + std::to_string(i) +
                                     "].T_world_cam: non-finite pose");
    }
    if (i > 0 && poses[i].t_ns <= poses[i - 1].t_ns) {
      return Status::InvalidArgument(
          "poses[" + std::to_string(i) + "].t_ns: time stamps must strictly increase (" +
          std::to_string(poses[i - 1].t_ns) + " then " + std::to_string(poses[i].t_ns) + ")");
    }
  }
  KeyframeSelector selector(options);
  std::vector<int64_t> indices;
  for (size_t i = 0; i < poses.size(); ++i) {
    if (selector.Consider(poses[i].T_world_cam)) indices.push_back(static_cast<int64_t>(i));
  }
  return indices;
}

}  // namespace mav::mapping
