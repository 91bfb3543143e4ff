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

#include "clients/plot/mission_flags.h"
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

// The command line: the flags mavctl mission run shares, and this driver's own.
struct Flags {
  plot::MissionFlags mission;
  std::string outage, world;
};

// The driver's options from the flags; InvalidArgument naming the flag.
Result<mission::LockstepOptions> DriverOptions(const Flags& f) {
  MAV_ASSIGN_OR_RETURN(const plot::MissionFlagOptions shared,
                       plot::MissionOptionsFromFlags(f.mission));
  mission::LockstepOptions options;
  options.vehicle = shared.vehicle;
  options.vo_method = shared.vo_method;
  options.map_source = shared.map;
  options.planning = shared.planning;
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
  plot::AddMissionFlags(plot::MissionDriverKind::kInProcess, &flags, &f->mission);
  flags.AddString("world", &f->world,
                  "fly in this preset instead of the file's world (room-easy, room-medium and "
                  "room-hard share one layout)");
  flags.AddString("localization-outage", &f->outage,
                  "START,DURATION: the localization is down for DURATION s from START s and comes "
                  "back restarted (fault injection)");
  return flags;
}

}  // namespace

int RunMission(const std::vector<std::string>& args) {
  Flags flags_in;
  FlagParser flags = MakeFlags(&flags_in);
  const plot::MissionFlags& f = flags_in.mission;
  bool help = false;
  if (Status s = flags.Parse(args, nullptr, &help); !s.ok()) {
    return Fail(s.message() + "\n" + flags.Help(), 2);
  }
  if (help) {
    std::cout << flags.Help();
    return 0;
  }
  if (f.mission_path.empty()) return Fail("--mission: required\n" + flags.Help(), 2);
  flags_in.mission.camera_pitch_set = flags.WasSet("camera-pitch");
  Result<mission::LockstepOptions> options = DriverOptions(flags_in);
  if (!options.ok()) return Fail(options.status().message(), 2);

  Result<dataset::MissionSpec> spec = dataset::ReadMissionFile(f.mission_path);
  if (!spec.ok()) return Fail(spec.status().message() + " (no take-off)");
  if (!flags_in.world.empty()) spec->world = flags_in.world;
  plot::ApplyMissionFile(f, *spec, &options->vehicle);
  const mission::MissionOptions mission_options = plot::MissionLogicOptions(f, *spec);

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
