#include "mav/eval/mission_eval.h"

#include <sstream>
#include <utility>

#include "mav/common/time.h"

namespace mav::eval {
namespace {

// The driver's counters into the figures.
void AddDriverFigures(const mission::LockstepDriver& driver, mission::MissionFigures* r) {
  const mission::LockstepStats stats = driver.stats();
  r->path_m = stats.path_m;
  r->setup_s = stats.setup_s;
  r->collisions = stats.collisions;
  r->collision_descriptions = stats.collision_descriptions;
  r->frames = stats.frames;
  r->vo_tracked = stats.vo_tracked;
  r->vo_lost = stats.vo_lost;
  r->vo_skipped = stats.vo_skipped;
  r->vo_ms = stats.vo_ms;
  r->render_ms = stats.render_ms;
  r->poses_merged = driver.autopilot().status().poses;
  r->poses_rejected = stats.poses_rejected;
  r->map_description = stats.map_description;
  r->keyframes = stats.keyframes;
  r->map_rebuilds = stats.map_rebuilds;
  r->roadmap_builds = stats.roadmap_builds;
  r->map_errors = stats.map_errors;
  r->map_build_ms = stats.map_build_ms;
  r->plan_ms = stats.plan_ms;
}

}  // namespace

Result<MissionSummary> EvaluateMission(const MissionEvalOptions& options,
                                       const mission::MissionProgressCallback& progress) {
  const int64_t wall_start = MonotonicNowNs();
  MissionSummary out;
  Result<std::unique_ptr<mission::LockstepDriver>> driver =
      mission::LockstepDriver::Create(options.spec, options.driver);
  if (!driver.ok()) {
    return Status(driver.status().code(), driver.status().message() + " (no take-off)");
  }
  out.driver = *std::move(driver);
  MAV_ASSIGN_OR_RETURN(mission::MissionReport report,
                       mission::RunMission(options.spec, options.mission, *out.driver, progress));
  out.figures =
      mission::FiguresOf(options.mission_path, options.spec.world, options.pose_source,
                         options.controller, "in-process", options.seed, std::move(report),
                         SecondsSince(wall_start), out.driver->record());
  AddDriverFigures(*out.driver, &out.figures);
  if (options.driver.map_source == mission::MapSource::kOnline) {
    Result<mission::MapQuality> quality = out.driver->EvaluateMap();
    if (!quality.ok()) {
      return Status(quality.status().code(),
                    "evaluating the final map: " + quality.status().message());
    }
    out.figures.map_quality = *quality;
  }
  return out;
}

Report MissionEvalReport(const MissionSummary& summary) {
  Report report;
  ReportTable& table = report.AddTable("", /*blank_line_before=*/false);
  std::istringstream lines(mission::MissionTable(summary.figures));
  for (std::string line; std::getline(lines, line);) table.rows.push_back(line);
  report.json_document = mission::MissionJson(summary.figures);
  return report;
}

}  // namespace mav::eval
