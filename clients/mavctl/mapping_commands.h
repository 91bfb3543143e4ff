#pragma once
// `mavctl map ...`: the client side of mav.v1.Mapping (docs/services.md, "mav-mapping").
//
//   mavctl map start (--simulator HOST:PORT | --euroc DIR)
//                    [--pose-source ground-truth|localization|none] [--min-translation M]
//                    [--min-rotation DEG] [--max-keyframes N] [--features N] [--no-dds]
//   mavctl map reset
//   mavctl map insert --left L.png --right R.png --t-ns T --pose x,y,z,qw,qx,qy,qz
//                     [--rectified] [--force]
//   mavctl map build --method sparse-mesh|octomap [--resolution M]
//                    [--bounds x0,y0,z0,x1,y1,z1] [--unknown keep|occupied|free]
//   mavctl map occupancy --out FILE.bt [--method sparse-mesh|octomap] [--format bt|mavocc]
//   mavctl map query --box x0,y0,z0,x1,y1,z1 [--method M] [--unknown-is-collision]
//   mavctl map mesh --out FILE.ply [--ascii]
//   mavctl map status
//
// Common flags: --address (127.0.0.1), --port (50053, env MAV_MAPPING_PORT), --timeout S
// (10 s; `map build` 120 s). Exit status: 0 success, 1 the call failed (message names the
// address and the status), 2 usage error.

#include <string>
#include <vector>

namespace mav::mavctl {

// `args` are the words after "map". Returns the process exit status.
int MappingCommand(const std::vector<std::string>& args);

}  // namespace mav::mavctl
