// mav-planning: the Planning gRPC service (control plane only, no DDS): maps (OctoMap .bt from a
// file, an upload or the mapping service), the PRM* roadmap and plans of libs/planning.
// docs/services.md lists flags and environment.
//
// Start-up: with --map the map is loaded before the port opens; with --roadmap FILE too, the
// roadmap is loaded from FILE when FILE holds one of this map, else built (--roadmap-milestones,
// --roadmap-seed) and saved to FILE, so a restarted or second server does not rebuild.

#include <thread>

#include "mav/common/file.h"
#include "mav/common/log.h"
#include "mav/common/time.h"
#include "mav/transport/service_main.h"
#include "services/planning/planner_core.h"
#include "services/planning/planning_service.h"

namespace {

struct StartupOptions {
  std::string map_path;
  std::string roadmap_path;
  double robot_radius_m = 0.5;
  uint64_t roadmap_milestones = 100000;
  uint64_t roadmap_seed = 1;
};

int LoadAtStartup(const mav::transport::ServiceRunner& runner, const StartupOptions& startup,
                  mav::planning_service::PlannerCore* core) {
  if (startup.map_path.empty()) {
    if (!startup.roadmap_path.empty()) return runner.Usage("--roadmap: needs --map");
    return 0;
  }
  mav::planning::MapOptions map_options;
  map_options.robot_radius_m = startup.robot_radius_m;
  std::string why;
  if (!map_options.IsValid(&why)) return runner.Usage("--robot-radius: " + why);
  auto map = core->LoadMapFile(startup.map_path, map_options, {});
  if (!map.ok()) return runner.Fail(map.status().WithContext("--map"));
  if (startup.roadmap_path.empty()) return 0;
  if (mav::PathExists(startup.roadmap_path)) {
    auto loaded = core->LoadRoadmap(startup.roadmap_path, {});
    if (loaded.ok()) return 0;
    MAV_LOG(kWarning) << "--roadmap: " << loaded.status().ToString() << "; building a new one";
  }
  mav::planning::RoadmapOptions roadmap_options;
  roadmap_options.max_milestones = startup.roadmap_milestones;
  roadmap_options.seed = startup.roadmap_seed;
  MAV_LOG(kInfo) << "building a roadmap of " << startup.roadmap_milestones << " milestones for "
                 << startup.roadmap_path;
  auto built = core->BuildRoadmap(roadmap_options, {});
  if (!built.ok()) return runner.Fail(built.status().WithContext("--roadmap"));
  auto saved = core->SaveRoadmap(startup.roadmap_path, {});
  if (!saved.ok()) return runner.Fail(saved.status().WithContext("--roadmap"));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  mav::transport::ServiceRunner runner({"mav-planning",
                                        "Serves mav.v1.Planning over gRPC: OctoMap maps, the PRM* "
                                        "roadmap and plans (libs/planning).",
                                        50054, "MAV_PLANNING_PORT"});
  mav::planning_service::PlannerCoreOptions core_options;
  mav::planning_service::PlanningServiceOptions service_options;
  StartupOptions startup;
  int64_t max_plans = core_options.max_plans_in_flight;
  int64_t max_map_memory_mb = static_cast<int64_t>(core_options.max_map_memory_bytes >> 20);
  int64_t max_upload_mb = static_cast<int64_t>(service_options.max_upload_bytes >> 20);
  int64_t threads = core_options.threads;
  mav::FlagParser& flags = runner.flags();
  flags.AddString("map", &startup.map_path, "load this OctoMap .bt at start-up");
  flags.AddString("roadmap", &startup.roadmap_path,
                  "with --map: load the roadmap from this .mavprm when it holds one of the map, "
                  "else build one and save it there");
  flags.AddDouble("robot-radius", &startup.robot_radius_m, "robot radius of the --map, m");
  flags.AddUint64("roadmap-milestones", &startup.roadmap_milestones,
                  "milestones of a roadmap built at start-up");
  flags.AddUint64("roadmap-seed", &startup.roadmap_seed, "seed of a roadmap built at start-up");
  flags.AddInt("max-plans-in-flight", &max_plans,
               "PlanPath calls computed at once, beyond which RESOURCE_EXHAUSTED (0 = 2 x cores)");
  flags.AddInt("max-map-memory-mb", &max_map_memory_mb,
               "largest map grids accepted, MiB (RESOURCE_EXHAUSTED above, before allocating)");
  flags.AddUint64("max-milestones", &core_options.max_milestones,
                  "largest roadmap BuildRoadmap builds (RESOURCE_EXHAUSTED above)");
  flags.AddInt("max-upload-mb", &max_upload_mb, "largest UploadMap / mapping-service map, MiB");
  flags.AddInt("threads", &threads, "threads of the distance transform and the roadmap costs");
  runner.ParseFlagsOrExit(argc, argv);
  if (max_plans < 0 || max_plans > 1024)
    return runner.Usage("--max-plans-in-flight: must be in [0, 1024]");
  if (max_map_memory_mb < 1) return runner.Usage("--max-map-memory-mb: must be >= 1");
  if (max_upload_mb < 1) return runner.Usage("--max-upload-mb: must be >= 1");
  if (threads < 1 || threads > 64) return runner.Usage("--threads: must be in [1, 64]");
  core_options.max_plans_in_flight = static_cast<int>(max_plans);
  core_options.max_map_memory_bytes = static_cast<uint64_t>(max_map_memory_mb) << 20;
  core_options.threads = static_cast<int>(threads);
  service_options.max_upload_bytes = static_cast<uint64_t>(max_upload_mb) << 20;
  std::string why;
  if (!core_options.IsValid(&why)) return runner.Usage(why);
  if (!service_options.IsValid(&why)) return runner.Usage(why);

  mav::planning_service::PlannerCore core(core_options);
  if (int rc = LoadAtStartup(runner, startup, &core); rc != 0) return rc;
  mav::planning_service::PlanningService service(&core, service_options);
  MAV_LOG(kInfo) << "at most " << core_options.PlansInFlightLimit() << " plans in flight";
  return runner.Serve({&service}, {mav::v1::Planning::service_full_name()},
                      [&] { core.Shutdown(); });
}
