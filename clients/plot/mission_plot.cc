#include "clients/plot/mission_plot.h"

#include <algorithm>

#include "clients/plot/plot.h"
#include "mav/common/file.h"
#include "mav/mission/report.h"

namespace mav::plot {

Status WriteMissionPlot(const std::string& path, const dataset::MissionSpec& spec,
                        const mission::MissionReport& report,
                        const std::vector<mission::FlightSample>& record,
                        const planning::PlanningMap& map) {
  std::vector<PlotSeries> series;
  PlotSeries truth{"flown (ground truth)", {}, 40, 40, 40};
  PlotSeries estimate{"estimate", {}, 200, 120, 0};
  for (const mission::FlightSample& s : record) {
    truth.positions.push_back(s.p_true);
    estimate.positions.push_back(s.p_est);
  }
  for (size_t i = 0; i < report.legs.size(); ++i) {
    PlotSeries leg{i == 0 ? "plans" : "", report.legs[i].path, 0, 170, 240};
    series.push_back(std::move(leg));
  }
  series.push_back(std::move(truth));
  series.push_back(std::move(estimate));
  PlotSeries reached{"goals reached", {}, 40, 170, 40, true};
  PlotSeries missed{"goals missed", {}, 30, 30, 220, true};
  for (const mission::GoalReport& g : report.goals) {
    (g.reached ? reached : missed).positions.push_back(g.goal);
  }
  if (!reached.positions.empty()) series.push_back(std::move(reached));
  if (!missed.positions.empty()) series.push_back(std::move(missed));
  // Obstacles up to the highest point flown over (a room's ceiling would hide the rest).
  double z_top = spec.start.z() + spec.altitude_m;
  for (const dataset::MissionGoal& g : spec.goals) z_top = std::max(z_top, g.position.z());
  const TopViewHeightMap height = HeightMapOf(map, spec.start.z() + 0.01, z_top + 0.5);
  return WriteTopViewPlot(path, spec.world + " mission (obstacles by height)", series, &height);
}

Status WriteMissionFiles(const std::string& dir, const dataset::MissionSpec& spec,
                         const mission::MissionReport& report,
                         const std::vector<mission::FlightSample>& record,
                         const planning::PlanningMap& map,
                         const std::function<Status(const std::string& path)>& write_map) {
  MAV_RETURN_IF_ERROR(MakeDirectories(dir));
  MAV_RETURN_IF_ERROR(mission::WriteTrajectoryCsv(dir + "/trajectory.csv", record));
  MAV_RETURN_IF_ERROR(WriteMissionPlot(dir + "/mission.png", spec, report, record, map));
  return write_map(dir + "/map.bt");
}

}  // namespace mav::plot
