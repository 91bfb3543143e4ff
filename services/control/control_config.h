#pragma once
// What mav-control is configured with (ControlConfigureRequest as the service holds it), apart
// from the service: the configuration's checks and the configuration a contest flight task is
// flown with. mavctl builds its Configure requests from it through the control codec
// (mav::control_codec: this file and convert.h) without linking the service.

#include <string>
#include <vector>

#include "mav/control/autopilot.h"
#include "mav/dataset/flight_task.h"

namespace mav::control_service {

// A pose source that answers every camera frame of a lock-stepped simulation
// (ControlPoseSource.lockstep_latency_s).
struct LockstepPoseOptions {
  double latency_s = 0;  // 0: not lock-stepped (poses merged as they arrive); else [0.001, 1]
  double wait_s = 2.0;   // wall clock per IMU sample, (0, 60]
};

struct ControlConfig {
  control::AutopilotOptions autopilot;
  // The child_frame_id of each pose source's poses (parallel to autopilot.estimator.pose_sources):
  // non-empty and distinct; "pose_sensor<i>" for the simulator's flight mode.
  std::vector<std::string> pose_frames = {"pose_sensor0"};
  // Parallel to pose_frames; empty = none lock-stepped. Needs `lockstep`.
  std::vector<LockstepPoseOptions> lockstep_poses;
  // The IMU's clock is a lock-stepped simulator's: no wall-clock IMU watchdog.
  bool lockstep = false;

  // Names the field as control.proto spells it where the service's checks do (pose_frames).
  bool IsValid(std::string* why) const;
};

// What the contest told the teams about a flight task (eval::AutopilotOptionsForTask: the
// controllers' Firefly, the sensors' nominal rates, noise and mountings), with the simulator's
// pose frames "pose_sensor<i>": the configuration mav-eval flies the task with.
ControlConfig ConfigForFlightTask(const dataset::FlightTask& task,
                                  control::ControllerType controller, bool lockstep);

}  // namespace mav::control_service
