// mav-eval mission: flies a mission file in one process, lock-stepped (mav/mission/
// lockstep_driver.h): the simulated vehicle, its rendered stereo camera and IMU, the VO, the
// estimator and controller, the planner, and the mission logic (mav/mission/mission.h) that
// mavctl mission run drives against the services. Writes the JSON report, DIR/trajectory.csv
// and DIR/mission.png; exits 0 only when the mission completed.

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "clients/plot/mission_plot.h"
#include "commands.h"
#include "mav/common/file.h"
#include "mav/common/flags.h"
#include "mav/common/parse.h"
#include "mav/common/text.h"
#include "mav/common/time.h"
#include "mav/dataset/mission_file.h"
#include "mav/localization/odometry.h"
#include "mav/mission/lockstep_driver.h"
#include "mav/mission/mission.h"
#include "mav/mission/report.h"

namespace mav::eval_cli {
namespace {

constexpr const char* kCommand = "mav-eval mission";

int Fail(const std::string& message, int code = 1) {
  std::cerr << kCommand << ": " << message << "\n";
  return code;
}

// The command line.
struct Flags {
  std::string mission_path, out_dir, json_path, pose_source = "vo";
  std::string vo_method = "sparse-subpixel", controller = "paper", outage, world, map = "truth";
  uint64_t seed = 1;
  double vo_latency_s = 0.05, max_speed = 0, timeout_s = 900, camera_pitch_deg = 0;
  bool quiet = false;
  bool face_goals = false;
};

// The driver's options from the flags; InvalidArgument naming the flag.
Result<mission::LockstepOptions> DriverOptions(const Flags& f) {
  mission::LockstepOptions options;
  options.vehicle.seed = f.seed;
  options.vehicle.vo_latency_s = f.vo_latency_s;
  options.vehicle.camera_pitch_rad = f.camera_pitch_deg * M_PI / 180;
  const std::optional<mission::PoseSource> source = mission::ParsePoseSource(f.pose_source);
  if (!source) {
    return Status::InvalidArgument("--pose-source: " + QuoteForError(f.pose_source) +
                                   " is not one of vo, contest, truth");
  }
  options.vehicle.pose_source = *source;
  const std::optional<mission::MapSource> map = mission::ParseMapSource(f.map);
  if (!map) {
    return Status::InvalidArgument("--map: " + QuoteForError(f.map) +
                                   " is not one of truth, online");
  }
  options.map_source = *map;
  const std::optional<localization::Method> method = localization::ParseMethod(f.vo_method);
  if (!method) {
    return Status::InvalidArgument("--vo-method: " + QuoteForError(f.vo_method) +
                                   " is not one of sparse-pixel, sparse-subpixel, dense");
  }
  options.vo_method = *method;
  const std::optional<control::ControllerType> controller = mission::ParseController(f.controller);
  if (!controller) {
    return Status::InvalidArgument("--controller: " + QuoteForError(f.controller) +
                                   " is not one of paper, lee");
  }
  options.vehicle.controller = *controller;
  if (!f.outage.empty()) {
    const std::vector<std::string_view> parts = SplitFields(f.outage, ',');
    mission::LocalizationOutage outage;
    Result<double> start = parts.size() == 2 ? ParseDouble(parts[0], "start")
                                             : Result<double>(Status::InvalidArgument("fields"));
    Result<double> duration = parts.size() == 2 ? ParseDouble(parts[1], "duration")
                                                : Result<double>(Status::InvalidArgument("fields"));
    if (start.ok()) outage.start_s = *start;
    if (duration.ok()) outage.duration_s = *duration;
    if (!start.ok() || !duration.ok() || outage.start_s < 0 || outage.duration_s <= 0) {
      return Status::InvalidArgument(
          "--localization-outage: expected START,DURATION in seconds (START >= 0, DURATION > 0), "
          "got " +
          QuoteForError(f.outage));
    }
    options.outages.push_back(outage);
  }
  if (f.max_speed > 0) options.planning.limits = mission::SpeedLimitsForMaxSpeed(f.max_speed);
  return options;
}

// The command's flags, bound to *f.
FlagParser MakeFlags(Flags* f) {
  FlagParser flags(
      "mav-eval mission --mission FILE [--seed S] [--pose-source vo|contest|truth] [--out DIR] "
      "[--json FILE]\n\n"
      "Flies a mission file in one process, lock-stepped and deterministic for a seed: the "
      "simulated vehicle\nin the mission's world, its rendered stereo camera and IMU, the VO, the "
      "estimator and controller,\nthe planner and the mission logic. Exit status 0 only when the "
      "mission completed.");
  flags.AddString("mission", &f->mission_path, "mission file (YAML, docs/formats.md)");
  flags.AddUint64("seed", &f->seed, "seed of the simulation (textures, noise, roadmap)");
  flags.AddString("pose-source", &f->pose_source,
                  "the estimator's pose: vo (stereo VO on the rendered images), contest (the "
                  "contest's 10 Hz sensor), truth (debugging)");
  flags.AddString("map", &f->map,
                  "the planner's map: truth (the world's exact occupancy) or online (built during "
                  "the flight from the VO's keyframes; needs --pose-source vo)");
  flags.AddString("world", &f->world,
                  "fly in this preset instead of the file's world (room-easy, room-medium and "
                  "room-hard share one layout)");
  flags.AddString("vo-method", &f->vo_method, "sparse-subpixel, sparse-pixel or dense");
  flags.AddString("controller", &f->controller, "paper or lee");
  flags.AddDouble("vo-latency", &f->vo_latency_s, "modelled VO latency, s (capture to estimator)",
                  0, 0.5);
  flags.AddDouble("camera-pitch", &f->camera_pitch_deg,
                  "the stereo camera's downward pitch on the vehicle, degrees", 0, 60);
  flags.AddDouble("max-speed", &f->max_speed, "planned speed limit, m/s (0 = the world's default)",
                  0, 20);
  flags.AddString("localization-outage", &f->outage,
                  "START,DURATION: the localization is down for DURATION s from START s and comes "
                  "back restarted (fault injection)");
  flags.AddDouble("timeout", &f->timeout_s,
                  "abort the mission after this long in simulated time, s (outcome aborted)", 1,
                  7000);
  flags.AddString("out", &f->out_dir, "write trajectory.csv and mission.png here");
  flags.AddString("json", &f->json_path, "write the report here");
  flags.AddBool("quiet", &f->quiet, "no progress line");
  flags.AddBool("face-goals", &f->face_goals,
                "turn to face each goal before its leg (always with --map online)");
  return flags;
}

}  // namespace

int RunMission(const std::vector<std::string>& args) {
  Flags f;
  FlagParser flags = MakeFlags(&f);
  bool help = false;
  if (Status s = flags.Parse(args, nullptr, &help); !s.ok()) {
    return Fail(s.message() + "\n" + flags.Help(), 2);
  }
  if (help) {
    std::cout << flags.Help();
    return 0;
  }
  if (f.mission_path.empty()) return Fail("--mission: required\n" + flags.Help(), 2);
  Result<mission::LockstepOptions> options = DriverOptions(f);
  if (!options.ok()) return Fail(options.status().message(), 2);

  Result<dataset::MissionSpec> spec = dataset::ReadMissionFile(f.mission_path);
  if (!spec.ok()) return Fail(spec.status().message() + " (no take-off)");
  if (!f.world.empty()) spec->world = f.world;
  mission::MissionOptions mission_options;
  mission_options.timeout_s = f.timeout_s;
  mission_options.face_goals = f.face_goals || f.map == "online";
  if (spec->world == "plant") mission_options.goal_tolerance_m = 0.5;

  const auto wall_start = std::chrono::steady_clock::now();
  std::fprintf(stderr, "%s: %s in %s, seed %llu, pose source %s: building the world and map\n",
               kCommand, f.mission_path.c_str(), spec->world.c_str(),
               static_cast<unsigned long long>(f.seed), f.pose_source.c_str());
  Result<std::unique_ptr<mission::LockstepDriver>> driver =
      mission::LockstepDriver::Create(*spec, *options);
  if (!driver.ok()) return Fail(driver.status().ToString() + " (no take-off)");
  Result<mission::MissionReport> report =
      mission::RunMission(*spec, mission_options, **driver, mission::ProgressLinePrinter(f.quiet));
  if (!report.ok()) return Fail(report.status().ToString());

  const std::vector<mission::FlightSample>& record = (*driver)->record();
  mission::MissionFigures r = mission::FiguresOf(
      f.mission_path, spec->world, f.pose_source, f.controller, "in-process", f.seed,
      *std::move(report),
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count(), record);
  const mission::LockstepStats stats = (*driver)->stats();
  r.path_m = stats.path_m;
  r.setup_s = stats.setup_s;
  r.collisions = stats.collisions;
  r.collision_descriptions = stats.collision_descriptions;
  r.frames = stats.frames;
  r.vo_tracked = stats.vo_tracked;
  r.vo_lost = stats.vo_lost;
  r.vo_skipped = stats.vo_skipped;
  r.vo_ms = stats.vo_ms;
  r.render_ms = stats.render_ms;
  r.poses_merged = (*driver)->autopilot().status().poses;
  r.poses_rejected = stats.poses_rejected;
  r.map_description = stats.map_description;
  r.keyframes = stats.keyframes;
  r.map_rebuilds = stats.map_rebuilds;
  r.map_errors = stats.map_errors;
  r.map_build_ms = stats.map_build_ms;
  r.plan_ms = stats.plan_ms;
  if (options->map_source == mission::MapSource::kOnline) {
    Result<mission::MapQuality> quality = (*driver)->EvaluateMap();
    if (!quality.ok()) return Fail("evaluating the final map: " + quality.status().ToString());
    r.map_quality = *quality;
  }
  std::fputs(mission::MissionTable(r).c_str(), stdout);

  if (!f.out_dir.empty()) {
    if (Status s = plot::WriteMissionFiles(
            f.out_dir, *spec, r.report, record, (*driver)->planning_map(),
            [&](const std::string& path) { return (*driver)->WriteMap(path); });
        !s.ok()) {
      return Fail(s.message());
    }
    std::printf("  wrote              %s/trajectory.csv, mission.png, map.bt\n", f.out_dir.c_str());
  }
  if (!f.json_path.empty()) {
    if (Status s = WriteStringToFileAtomic(f.json_path, mission::MissionJson(r)); !s.ok()) {
      return Fail(s.message());
    }
  }
  return r.report.outcome == mission::MissionOutcome::kCompleted ? 0 : 1;
}

}  // namespace mav::eval_cli
