#pragma once
// `mavctl plan ...`: the client side of mav.v1.Planning (docs/services.md, "mav-planning").
//
//   mavctl plan load (--file PATH | --mapping HOST:PORT [--method sparse-mesh|octomap] |
//                     --upload FILE.bt) [--robot-radius M] [--unknown-free] [--max-distance M]
//                    [--bounds x0,y0,z0,x1,y1,z1] [--distance-method exact|edt3d]
//   mavctl plan roadmap [--milestones N] [--budget S] [--seed S] [--margin M]
//                       [--validity-resolution M] [--save FILE.mavprm] | --load FILE.mavprm
//   mavctl plan path --start x,y,z --goal x,y,z [--via "x,y,z;x,y,z"] [--max-speed V]
//                    [--max-acceleration A] [--max-lateral A] [--max-jerk J]
//                    [--yaw constant|along-path] [--start-yaw RAD] [--no-roadmap]
//                    [--budget S] [--sample-dt S] [--out FILE.csv]
//   mavctl plan legs --points "x,y,z;x,y,z;..."   (each consecutive pair a plan; a table)
//   mavctl plan get PLAN_ID
//   mavctl plan sample PLAN_ID [--dt S] [--out FILE.csv]
//   mavctl plan status
//
// CSV files have the header t,x,y,z,vx,vy,vz,ax,ay,az,yaw (s, m, m/s, m/s^2, rad).
// Common flags: --address (127.0.0.1), --port (50054, env MAV_PLANNING_PORT), --timeout S (10 s;
// 120 s for load and roadmap). Exit status: 0 success (for path/legs: every plan SUCCESS), 1 the
// call or a plan failed (message names the address and the status), 2 usage error.

#include <string>
#include <vector>

namespace mav::mavctl {

// `args` are the words after "plan". Returns the process exit status.
int PlanCommand(const std::vector<std::string>& args);

}  // namespace mav::mavctl
