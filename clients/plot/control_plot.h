#pragma once
// The control evaluation's plot (mav-eval control --out): each controller's position error
// against time on one contest task.

#include <string>
#include <vector>

#include "mav/common/status.h"
#include "mav/dataset/flight_task.h"
#include "mav/eval/contest_score.h"
#include "mav/eval/flight_mission.h"

namespace mav::plot {

// Position error |p - goal| against time for each controller (green, then red), the force
// windows shaded and the scoring windows of `scores` (one per record) marked; a 1100 x 420 PNG.
// IoError naming `path`.
Status WriteControlErrorPlot(const std::string& path, const dataset::FlightTask& task,
                             const std::vector<const eval::FlightRecord*>& records,
                             const std::vector<eval::TaskScore>& scores);

}  // namespace mav::plot
