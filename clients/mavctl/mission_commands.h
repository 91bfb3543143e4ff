#pragma once
// `mavctl mission run`: a mission file flown through the running services (mission_driver.h),
// with the mission logic mav-eval mission runs in process (mav/mission/mission.h).
//
//   mavctl mission run --mission FILE [--seed S] [--pose-source vo|contest|truth]
//                      [--camera-pitch DEG] [--vo-latency S] [--controller paper|lee]
//                      [--vo-method sparse-subpixel|sparse-pixel|dense]
//                      [--max-speed V] [--timeout S] [--face-goals] [--map truth|online]
//                      [--out DIR] [--json FILE] [--quiet] [--simulator A] [--localization A]
//                      [--mapping A] [--planning A] [--control A]
//
// Writes the same table, JSON report, DIR/trajectory.csv, DIR/mission.png and DIR/map.bt as
// mav-eval mission. Exit status: 0 when the mission completed, 1 when it did not (or a service
// failed: the message names it, its address and the RPC), 2 usage error or a malformed mission
// file (nothing is loaded, nothing takes off).

#include <string>
#include <vector>

namespace mav::mavctl {

// `args` are the words after "mission". Returns the process exit status.
int MissionCommand(const std::vector<std::string>& args);

}  // namespace mav::mavctl
