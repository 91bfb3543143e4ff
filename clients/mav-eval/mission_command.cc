// mav-eval mission: flies a mission file in one process, lock-stepped (mav/eval/mission_eval.h:
// the simulated vehicle, its rendered stereo camera and IMU, the VO, the estimator and
// controller, the planner, and the mission logic that mavctl mission run drives against the
// services). Writes the JSON report, DIR/trajectory.csv and DIR/mission.png; exits 0 only when
// the mission completed.

#include <unistd.h>

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
#include "mav/eval/mission_eval.h"
#include "mav/localization/odometry.h"
#include "mav/mission/lockstep_driver.h"
#include "mav/mission/mission.h"
#include "mav/mission/report.h"
#include "output.h"

namespace mav::eval_cli {
namespace {

constexpr const char* kCommand = "mav-eval mission";

int Fail(const std::string& message, int code = 1) {
  return eval_cli::Fail(kCommand, message, code);
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

  eval::MissionEvalOptions eval_options;
  eval_options.spec = *std::move(spec);
  eval_options.mission_path = f.mission_path;
  eval_options.driver = *std::move(options);
  eval_options.mission = mission_options;
  eval_options.pose_source = f.pose_source;
  eval_options.controller = f.controller;
  eval_options.seed = f.seed;
  std::fprintf(stderr, "%s: %s in %s, seed %llu, pose source %s: building the world and map\n",
               kCommand, f.mission_path.c_str(), eval_options.spec.world.c_str(),
               static_cast<unsigned long long>(f.seed), f.pose_source.c_str());
  Result<eval::MissionSummary> summary =
      eval::EvaluateMission(eval_options, mission::ProgressLinePrinter(f.quiet));
  if (!summary.ok()) return Fail(summary.status().ToString());
  const mission::MissionFigures& r = summary->figures;
  const mission::LockstepDriver& driver = *summary->driver;
  if (Status s = PrintReport(eval::MissionEvalReport(*summary), f.json_path); !s.ok()) {
    return Fail(s.message());
  }

  if (!f.out_dir.empty()) {
    if (Status s = plot::WriteMissionFiles(
            f.out_dir, eval_options.spec, r.report, driver.record(), driver.planning_map(),
            [&](const std::string& path) { return driver.WriteMap(path); });
        !s.ok()) {
      return Fail(s.message());
    }
    std::printf("  wrote              %s/trajectory.csv, mission.png, map.bt\n", f.out_dir.c_str());
  }
  return r.report.outcome == mission::MissionOutcome::kCompleted ? 0 : 1;
}

}  // namespace mav::eval_cli
