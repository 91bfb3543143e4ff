#pragma once
// Mission files: what a mission flies (the mission library's input, docs/mission.md):
// a simulator world, a start on the ground, a take-off height, goals visited in order with a
// hover at each, and whether to land at the end. YAML:
//
//   world: room-easy          # the simulator preset (required)
//   start: [0.0, 0.0, 0.0]    # on the ground, world frame, m (default: the origin)
//   altitude: 1.2             # take-off height above the start, m (default 1.0)
//   hover_s: 2                # hover at each goal, s (default 2)
//   goals:                    # visited in order (required, at least one)
//     - [2.0, 1.5, 1.2]       # a position, world frame, m
//     - {position: [-2.5, 2.0, 1.5], hover_s: 5, yaw_rad: 1.57}   # or with its own hover/yaw
//   land: true                # land below the last goal (default true)
//   camera_pitch_deg: 25      # the vehicle's stereo camera pitched down, degrees, [0, 60]
//                             # (default: the driver's, level unless told otherwise)
//
// Every error is an InvalidArgument that names the file, the line and the key path
// ("room.yaml:7: goals[1]: expected a list of 3 numbers"), so a bad file is refused before any
// take-off. A key the reader does not know is an error (a misspelt key is never ignored).
// Whether the world exists and a goal is free is for the caller that knows the world.

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mav/common/status.h"

namespace mav::dataset {

struct MissionGoal {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // world frame, m
  double hover_s = 2.0;                                // >= 0
  std::optional<double> yaw_rad;                       // none: the planner's choice
  int line = 0;                                        // in the file, 1-based (0: not from a file)
};

struct MissionSpec {
  std::string world;                                // simulator preset
  Eigen::Vector3d start = Eigen::Vector3d::Zero();  // on the ground
  double altitude_m = 1.0;                          // take-off height above the start, > 0
  std::vector<MissionGoal> goals;                   // in order, at least one
  bool land = true;                                 // land below the last goal
  std::optional<double> camera_pitch_deg;           // the camera's mounting, if the file says
  std::string source;                               // the file it came from (for messages)

  // The limits every mission keeps: a world named, finite coordinates, altitude in (0, 100] m,
  // camera pitch in [0, 60] degrees, hover in [0, 3600] s, 1..1000 goals. `why` names the field
  // ("goals[2].hover_s: ...").
  bool IsValid(std::string* why) const;
};

// Parses `text`; `source` names it in messages (a path, or "<mission>").
Result<MissionSpec> ParseMissionYaml(const std::string& text, const std::string& source);
// Reads and parses a mission file; NotFound / IoError when it cannot be read.
Result<MissionSpec> ReadMissionFile(const std::string& path);

}  // namespace mav::dataset
