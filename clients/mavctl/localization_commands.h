#pragma once
// `mavctl loc ...`: the client side of mav.v1.Localization (docs/services.md, "mav-localization").
//
//   mavctl loc configure --method sparse-pixel|sparse-subpixel|dense
//                        (--euroc DIR | --simulator HOST:PORT) [--queue N] [--output-frame F]
//                        [--no-dds] [--ransac-iterations N] [--inlier-threshold PX]
//   mavctl loc reset [--x X --y Y --z Z]
//   mavctl loc status
//   mavctl loc trajectory --out FILE.tum [--start-t-ns T] [--end-t-ns T]
//
// Common flags: --address (127.0.0.1), --port (50052, env MAV_LOCALIZATION_PORT), --timeout S.
// Exit status: 0 success, 1 the call failed (message names the address and the status),
// 2 usage error.

#include <string>
#include <vector>

namespace mav::mavctl {

// `args` are the words after "loc". Returns the process exit status.
int LocalizationCommand(const std::vector<std::string>& args);

}  // namespace mav::mavctl
