#include "clients/mavctl/mission_commands.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>

#include "clients/common/channel.h"
#include "clients/mavctl/connection.h"
#include "clients/mavctl/mission_driver.h"
#include "clients/plot/mission_flags.h"
#include "clients/plot/mission_plot.h"
#include "mav/common/file.h"
#include "mav/common/text.h"
#include "mav/dataset/mission_file.h"
#include "mav/mission/lockstep_driver.h"
#include "mav/mission/mission.h"
#include "mav/mission/report.h"
#include "mav/transport/flags.h"

namespace mav::mavctl {

namespace {

using transport::FlagParser;

int Usage(const std::string& message) {
  std::cerr << "mavctl mission: " << message << "\n";
  return 2;
}

int Fail(const std::string& message) {
  std::cerr << "mavctl mission run: " << message << "\n";
  return 1;
}

// host:port of a service (or a target naming several backends, clients/common/channel.h): the
// flag, else 127.0.0.1 and the port variable, else the default port.
Result<std::string> Address(const std::string& name, const std::string& flag,
                            const std::string& port_env, int64_t default_port) {
  if (!flag.empty()) {
    if (Result<client::ChannelTarget> t = client::ParseTarget(flag); !t.ok()) {
      return Status::InvalidArgument("--" + name + ": " + t.status().message());
    }
    return flag;
  }
  MAV_ASSIGN_OR_RETURN(const int64_t port, transport::PortFromEnv(port_env, default_port));
  return "127.0.0.1:" + std::to_string(port);
}

// The command line: the flags mav-eval mission shares, and this driver's own.
struct RunFlags {
  plot::MissionFlags mission;
  std::string simulator, localization, mapping, planning, control;
  double lockstep_wait_s = 2;
};

// The driver's options from the flags; InvalidArgument naming the flag.
Result<ServiceMissionOptions> OptionsFrom(const RunFlags& f) {
  MAV_ASSIGN_OR_RETURN(const plot::MissionFlagOptions shared,
                       plot::MissionOptionsFromFlags(f.mission));
  ServiceMissionOptions o;
  o.vehicle = shared.vehicle;
  o.vo_method = shared.vo_method;
  o.planning = shared.planning;
  o.online_map = shared.map == mission::MapSource::kOnline;
  o.lockstep_wait_s = f.lockstep_wait_s;
  return o;
}

// The command's flags, bound to *f.
FlagParser MakeRunFlags(RunFlags* f) {
  FlagParser flags(
      "mavctl mission run",
      "Flies a mission file through the running services (mav-simulator, mav-localization, "
      "mav-control, mav-planning), lock-stepped: the same mission logic, vehicle, map and "
      "roadmap as mav-eval mission in one process, the same seed giving the same flight. "
      "Exit status 0 only when the mission completed.");
  plot::AddMissionFlags(plot::MissionDriverKind::kServices, &flags, &f->mission);
  flags.AddDouble("lockstep-wait", &f->lockstep_wait_s,
                  "how long mav-control waits for a frame's pose before flying on without it, "
                  "wall s",
                  0.01, 60);
  flags.AddString("simulator", &f->simulator,
                  "mav-simulator's host:port (127.0.0.1 and MAV_SIMULATOR_PORT or 50051)");
  flags.AddString("localization", &f->localization,
                  "mav-localization's host:port (127.0.0.1 and MAV_LOCALIZATION_PORT or 50052)");
  flags.AddString(
      "mapping", &f->mapping,
      "mav-mapping's host:port, --map online (127.0.0.1 and MAV_MAPPING_PORT or 50053)");
  flags.AddString("planning", &f->planning,
                  "mav-planning's host:port (127.0.0.1 and MAV_PLANNING_PORT or 50054)");
  flags.AddString("control", &f->control,
                  "mav-control's host:port (127.0.0.1 and MAV_CONTROL_PORT or 50055)");
  return flags;
}

int Run(const std::vector<std::string>& args) {
  RunFlags flags_in;
  FlagParser flags = MakeRunFlags(&flags_in);
  ParseOrExit(&flags, nullptr, args);
  const plot::MissionFlags& f = flags_in.mission;
  if (f.mission_path.empty()) return Usage("run: --mission: required");
  flags_in.mission.camera_pitch_set = flags.WasSet("camera-pitch");
  Result<ServiceMissionOptions> options = OptionsFrom(flags_in);
  if (!options.ok()) return Usage("run: " + options.status().message());
  ServiceAddresses addresses;
  for (auto [name, flag, env, port, target] :
       {std::tuple{"simulator", &flags_in.simulator, "MAV_SIMULATOR_PORT", 50051,
                   &addresses.simulator},
        std::tuple{"localization", &flags_in.localization, "MAV_LOCALIZATION_PORT", 50052,
                   &addresses.localization},
        std::tuple{"mapping", &flags_in.mapping, "MAV_MAPPING_PORT", 50053, &addresses.mapping},
        std::tuple{"planning", &flags_in.planning, "MAV_PLANNING_PORT", 50054, &addresses.planning},
        std::tuple{"control", &flags_in.control, "MAV_CONTROL_PORT", 50055, &addresses.control}}) {
    Result<std::string> address = Address(name, *flag, env, port);
    if (!address.ok()) return Usage(address.status().message());
    *target = *address;
  }

  // A malformed file is refused here: nothing is loaded, nothing takes off.
  Result<std::string> text = ReadFileToString(f.mission_path);
  if (!text.ok()) return Usage(text.status().message() + " (no take-off)");
  Result<dataset::MissionSpec> spec = dataset::ParseMissionYaml(*text, f.mission_path);
  if (!spec.ok()) return Usage(spec.status().message() + " (no take-off)");
  plot::ApplyMissionFile(f, *spec, &options->vehicle);
  const mission::MissionOptions mission_options = plot::MissionLogicOptions(f, *spec);

  const auto wall_start = std::chrono::steady_clock::now();
  auto say = [&](const std::string& what) {
    if (!f.quiet) std::fprintf(stderr, "mavctl mission run: %s\n", what.c_str());
  };
  Result<std::unique_ptr<ServiceDriver>> driver =
      ServiceDriver::Create(*spec, *text, *options, addresses, say);
  if (!driver.ok()) return Fail(driver.status().ToString() + " (no take-off)");
  Result<mission::MissionReport> report =
      mission::RunMission(*spec, mission_options, **driver, mission::ProgressLinePrinter(f.quiet));
  (*driver)->Stop();
  if (!report.ok()) return Fail(report.status().ToString());

  const std::vector<mission::FlightSample>& record = (*driver)->record();
  mission::MissionFigures r = mission::FiguresOf(
      f.mission_path, spec->world, f.pose_source, f.controller, "services", f.seed,
      *std::move(report),
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count(), record);
  for (size_t i = 1; i < record.size(); ++i) {
    r.path_m += (record[i].p_true - record[i - 1].p_true).norm();
  }
  Result<ServiceFigures> services = (*driver)->Figures();
  if (!services.ok()) return Fail("the services' figures: " + services.status().ToString());
  r.setup_s = services->setup_s;
  r.collisions = services->collisions;
  r.collision_descriptions = services->collision_descriptions;
  r.frames = services->frames_published;
  r.vo_tracked = services->vo_frames - services->vo_lost;
  r.vo_lost = services->vo_lost;
  r.vo_skipped =
      services->frames_published - std::min(services->frames_published, services->vo_frames);
  r.vo_ms = services->vo_ms;
  r.render_ms = services->render_ms;
  r.poses_merged = services->poses_merged;
  r.poses_rejected = services->poses_gated;
  r.map_description = services->map_description;
  r.plan_ms = services->plan_ms;
  r.lockstep_frames_missed = services->lockstep_frames_missed;
  r.keyframes = services->keyframes;
  r.map_rebuilds = services->map_rebuilds;
  r.roadmap_builds = services->roadmap_builds;
  r.map_errors = services->map_errors;
  r.map_build_ms = services->map_build_ms;
  r.map_quality = services->map_quality;
  r.tick_ms = services->advance_ms;
  if (services->pose_latency.total.count > 0) r.pose_latency = services->pose_latency;
  std::fputs(mission::MissionTable(r).c_str(), stdout);

  if (!f.out_dir.empty()) {
    if (Status s =
            plot::WriteMissionFiles(f.out_dir, *spec, r.report, record, (*driver)->planning_map(),
                                    [&](const std::string& path) {
                                      return WriteStringToFileAtomic(path, (*driver)->map_bt());
                                    });
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

}  // namespace

int MissionCommand(const std::vector<std::string>& args) {
  if (args.empty() || args[0] != "run") {
    return Usage("expected `mavctl mission run --mission FILE ...` (mavctl mission run --help)");
  }
  return Run(std::vector<std::string>(args.begin() + 1, args.end()));
}

}  // namespace mav::mavctl
