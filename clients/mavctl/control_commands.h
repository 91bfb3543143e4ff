#pragma once
// `mavctl ctl ...`: the client side of mav.v1.Control, and `mavctl sim flight ...`: the
// simulator's flight mode (docs/services.md, "mav-control" and "Flight mode").
//
//   mavctl ctl configure [--task t3_1|FILE.yaml] [--controller paper|lee] [--lockstep]
//                        [--pose-frame NAME] [--no-dds]
//   mavctl ctl arm | ctl disarm
//   mavctl ctl hover --position X,Y,Z [--yaw RAD] [--immediate] [--max-speed V] [--max-accel A]
//   mavctl ctl trajectory (--to X,Y,Z --duration S | --plan ID --planning HOST:PORT)
//                         [--start-t-ns T] [--offset X,Y,Z] [--allow-jump]
//   mavctl ctl gains [--position-omega W] [--position-zeta Z] [--integral K] [--attitude-omega W]
//                    [--attitude-zeta Z] [--yaw-omega W] [--yaw-zeta Z]
//                  | --lee [--lee-position K] [--lee-velocity K] [--lee-attitude K] [--lee-rate K]
//   mavctl ctl state | ctl status
//   mavctl sim flight load (--task NAME | --file SERVER_PATH | --yaml LOCAL_FILE) [--seed S]
//                          [--lockstep] [--rate F] [--step-timeout S] [--map PATH]
//   mavctl sim flight run [--until S] [--pause-on-goal] [--wait] [--wait-timeout S]
//   mavctl sim flight pause | sim flight status
//
// ctl: --address (127.0.0.1), --port (50055, env MAV_CONTROL_PORT), --timeout S; sim flight:
// the simulator's (50051, env MAV_SIMULATOR_PORT). Exit status: 0 success, 1 the call failed
// (message names the address and the status), 2 usage error.

#include <string>
#include <vector>

namespace mav::mavctl {

// `args` are the words after "ctl". Returns the process exit status.
int ControlCommand(const std::vector<std::string>& args);
// `args` are the words after "sim flight".
int FlightCommand(const std::vector<std::string>& args);

}  // namespace mav::mavctl
