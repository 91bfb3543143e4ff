#include "services/control/control_config.h"

#include "mav/common/text.h"
#include "mav/eval/flight_mission.h"

namespace mav::control_service {

bool ControlConfig::IsValid(std::string* why) const {
  auto fail = [&](const std::string& message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (pose_frames.size() != autopilot.estimator.pose_sources.size()) {
    return fail("estimator.pose_sources: " + std::to_string(pose_frames.size()) +
                " frame names for " + std::to_string(autopilot.estimator.pose_sources.size()) +
                " sources");
  }
  for (size_t i = 0; i < pose_frames.size(); ++i) {
    const std::string field = "estimator.pose_sources[" + std::to_string(i) + "].frame_id";
    if (pose_frames[i].empty()) return fail(field + ": empty");
    if (pose_frames[i].size() > 32) return fail(field + ": longer than 32 characters (the IDL's)");
    for (size_t j = 0; j < i; ++j) {
      if (pose_frames[j] == pose_frames[i]) {
        return fail(field + ": " + QuoteForError(pose_frames[i]) + " is pose_sources[" +
                    std::to_string(j) + "]'s too");
      }
    }
  }
  if (!lockstep_poses.empty() && lockstep_poses.size() != pose_frames.size()) {
    return fail("estimator.pose_sources: " + std::to_string(lockstep_poses.size()) +
                " lock-step settings for " + std::to_string(pose_frames.size()) + " sources");
  }
  for (size_t i = 0; i < lockstep_poses.size(); ++i) {
    const std::string field = "estimator.pose_sources[" + std::to_string(i) + "].lockstep_";
    const LockstepPoseOptions& l = lockstep_poses[i];
    if (l.latency_s == 0) continue;
    if (!(l.latency_s >= 0.001 && l.latency_s <= 1)) {
      return fail(field + "latency_s: must be 0 (off) or in [0.001, 1] s, got " +
                  std::to_string(l.latency_s));
    }
    if (!(l.wait_s > 0 && l.wait_s <= 60)) {
      return fail(field + "wait_s: must be in (0, 60] s, got " + std::to_string(l.wait_s));
    }
    if (!lockstep) return fail(field + "latency_s: needs lockstep (a lock-stepped simulator)");
  }
  return autopilot.IsValid(why);
}

ControlConfig ConfigForFlightTask(const dataset::FlightTask& task,
                                  control::ControllerType controller, bool lockstep) {
  ControlConfig config;
  config.autopilot = eval::AutopilotOptionsForTask(task, controller);
  config.pose_frames.clear();
  for (size_t i = 0; i < config.autopilot.estimator.pose_sources.size(); ++i) {
    config.pose_frames.push_back("pose_sensor" + std::to_string(i));
  }
  config.lockstep = lockstep;
  config.autopilot.rest_z_m = task.spawn_position.z();  // resting on its legs
  return config;
}

}  // namespace mav::control_service
