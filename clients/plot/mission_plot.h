#pragma once
// mission.png of mav-eval mission and mavctl mission run: the top view of the mission's world
// (obstacles by height), the true and estimated paths, the planned legs and the goals marked
// reached or missed.

#include <functional>
#include <string>
#include <vector>

#include "mav/common/status.h"
#include "mav/dataset/mission_file.h"
#include "mav/mission/mission.h"
#include "mav/mission/record.h"

namespace mav::planning {
class PlanningMap;
}

namespace mav::plot {

// DIR/trajectory.csv, DIR/mission.png and DIR/map.bt (written by `write_map`), DIR created.
Status WriteMissionFiles(const std::string& dir, const dataset::MissionSpec& spec,
                         const mission::MissionReport& report,
                         const std::vector<mission::FlightSample>& record,
                         const planning::PlanningMap& map,
                         const std::function<Status(const std::string& path)>& write_map);

Status WriteMissionPlot(const std::string& path, const dataset::MissionSpec& spec,
                        const mission::MissionReport& report,
                        const std::vector<mission::FlightSample>& record,
                        const planning::PlanningMap& map);

}  // namespace mav::plot
