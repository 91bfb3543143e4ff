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

#include "commands.h"
#include "json.h"
#include "mav/common/file.h"
#include "mav/common/flags.h"
#include "mav/common/parse.h"
#include "mav/common/text.h"
#include "mav/common/time.h"
#include "mav/dataset/mission_file.h"
#include "mav/localization/odometry.h"
#include "mav/mission/lockstep_driver.h"
#include "mav/mission/mission.h"
#include "plot.h"

namespace mav::eval_cli {
namespace {

constexpr const char* kCommand = "mav-eval mission";
// Hovers at least this long get their t3_1 figures in the table (5 s settling + the window).
constexpr double kHoverScoredS = 15;

int Fail(const std::string& message, int code = 1) {
  std::cerr << kCommand << ": " << message << "\n";
  return code;
}

Status WriteTrajectoryCsv(const std::string& path,
                          const std::vector<mission::FlightSample>& record) {
  std::ostringstream out;
  out << "t,gt_x,gt_y,gt_z,est_x,est_y,est_z,gt_qw,gt_qx,gt_qy,gt_qz,est_qw,est_qx,est_qy,est_qz,"
         "armed\n";
  char line[400];
  for (const mission::FlightSample& s : record) {
    std::snprintf(line, sizeof(line),
                  "%.3f,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%d\n",
                  s.t_s, s.p_true.x(), s.p_true.y(), s.p_true.z(), s.p_est.x(), s.p_est.y(),
                  s.p_est.z(), s.q_true.w(), s.q_true.x(), s.q_true.y(), s.q_true.z(), s.q_est.w(),
                  s.q_est.x(), s.q_est.y(), s.q_est.z(), s.armed ? 1 : 0);
    out << line;
  }
  return WriteStringToFileAtomic(path, out.str());
}

Status WritePlot(const std::string& path, const dataset::MissionSpec& spec,
                 const mission::MissionReport& report, const mission::LockstepDriver& driver) {
  std::vector<PlotSeries> series;
  PlotSeries truth{"flown (ground truth)", {}, 40, 40, 40};
  PlotSeries estimate{"estimate", {}, 200, 120, 0};
  for (const mission::FlightSample& s : driver.record()) {
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
  const TopViewHeightMap height =
      HeightMapOf(driver.planning_map(), spec.start.z() + 0.01, z_top + 0.5);
  return WriteTopViewPlot(path, spec.world + " mission (obstacles by height)", series, &height);
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
  options.seed = f.seed;
  options.vo_latency_s = f.vo_latency_s;
  options.camera_pitch_rad = f.camera_pitch_deg * M_PI / 180;
  const std::optional<mission::PoseSource> source = mission::ParsePoseSource(f.pose_source);
  if (!source) {
    return Status::InvalidArgument("--pose-source: " + QuoteForError(f.pose_source) +
                                   " is not one of vo, contest, truth");
  }
  options.pose_source = *source;
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
  if (f.controller == "paper") {
    options.controller = control::ControllerType::kPaper;
  } else if (f.controller == "lee") {
    options.controller = control::ControllerType::kLee;
  } else {
    return Status::InvalidArgument("--controller: " + QuoteForError(f.controller) +
                                   " is not one of paper, lee");
  }
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
  if (f.max_speed > 0) {
    planning::SpeedLimits limits;
    limits.max_speed_mps = f.max_speed;
    limits.max_acceleration_mps2 = std::min(2.0, f.max_speed);
    limits.max_lateral_acceleration_mps2 = std::min(2.0, f.max_speed);
    limits.max_jerk_mps3 = 5.0;
    options.limits = limits;
  }
  return options;
}

// One flown mission and its figures.
struct Flown {
  dataset::MissionSpec spec;
  mission::MissionReport report;
  mission::LockstepStats stats;
  control::AutopilotStatus autopilot;
  std::vector<eval::WindowRms> hover;              // per goal: the t3_1 figures of its hover
  std::optional<mission::MapQuality> map_quality;  // the final map against the exact world
  double ate_m = 0;
  double wall_s = 0;
};

void PrintTable(const Flags& f, const Flown& r) {
  const mission::MissionReport& report = r.report;
  const mission::LockstepStats& stats = r.stats;
  std::printf("mission %s (%s, seed %llu, pose source %s, %s)\n", f.mission_path.c_str(),
              r.spec.world.c_str(), static_cast<unsigned long long>(f.seed), f.pose_source.c_str(),
              f.controller.c_str());
  std::printf("  outcome            %s%s%s\n", mission::MissionOutcomeName(report.outcome),
              report.error.empty() ? "" : ": ", report.error.c_str());
  int reached = 0;
  for (size_t i = 0; i < report.goals.size(); ++i) {
    const mission::GoalReport& g = report.goals[i];
    reached += g.reached;
    std::printf("  goal %zu (line %d)    %s  error %.3f m (estimate %.3f m)\n", i + 1, g.line,
                g.reached ? "reached" : (g.visited ? "MISSED " : "not visited"), g.error_m,
                g.estimate_error_m);
    if (r.hover[i].samples > 0 && g.reached_at_s - g.hover_start_s >= kHoverScoredS) {
      std::printf("    hover from +5 s:  position RMS %.4f m, angular-rate RMS %.4f rad/s\n",
                  r.hover[i].position_rms_m, r.hover[i].angular_rate_rms_radps);
    }
  }
  std::printf("  goals reached      %d of %zu\n", reached, report.goals.size());
  std::printf("  collisions         %lld\n", static_cast<long long>(stats.collisions));
  for (const std::string& c : stats.collision_descriptions) std::printf("    %s\n", c.c_str());
  std::printf("  ATE (no alignment) %.4f m\n", r.ate_m);
  std::printf("  path flown         %.1f m in %.1f s simulated, %.1f s wall (x%.2f real time)\n",
              stats.path_m, report.sim_time_s, r.wall_s, report.sim_time_s / r.wall_s);
  std::printf(
      "  localization       %llu frames: %llu tracked, %llu lost, %llu skipped; VO %.1f ms "
      "mean, render %.1f ms mean\n",
      static_cast<unsigned long long>(stats.frames),
      static_cast<unsigned long long>(stats.vo_tracked),
      static_cast<unsigned long long>(stats.vo_lost),
      static_cast<unsigned long long>(stats.vo_skipped), stats.vo_ms.mean_ms,
      stats.render_ms.mean_ms);
  std::printf("  estimator          %llu poses merged, %llu rejected by the gate\n",
              static_cast<unsigned long long>(r.autopilot.poses),
              static_cast<unsigned long long>(stats.poses_rejected));
  std::printf("  planning           %d plans, %d replans (%.0f ms mean) on the %s\n", report.plans,
              report.replans, stats.plan_ms.mean_ms, stats.map_description.c_str());
  if (stats.map_rebuilds > 0) {
    std::printf("  online map         %lld keyframes, %llu rebuilds (%.0f ms mean), %llu errors\n",
                static_cast<long long>(stats.keyframes),
                static_cast<unsigned long long>(stats.map_rebuilds), stats.map_build_ms.mean_ms,
                static_cast<unsigned long long>(stats.map_errors));
  }
  if (r.map_quality) {
    std::printf("  final map          MCC %.3f, missed collisions %.2f %%, false %.2f %% (%s)\n",
                r.map_quality->mcc, r.map_quality->missed_percent, r.map_quality->false_percent,
                r.map_quality->observable_only ? "observable volume" : "whole world");
  }
  std::printf("  holds              %d\n", report.holds);
}

std::string ReportJson(const Flags& f, const Flown& r) {
  const mission::MissionReport& report = r.report;
  const mission::LockstepStats& stats = r.stats;
  std::ostringstream j;
  j << "{\n  \"mission\": " << JsonQuote(f.mission_path)
    << ",\n  \"world\": " << JsonQuote(r.spec.world) << ",\n  \"seed\": " << f.seed
    << ",\n  \"pose_source\": " << JsonQuote(f.pose_source)
    << ",\n  \"controller\": " << JsonQuote(f.controller)
    << ",\n  \"outcome\": " << JsonQuote(mission::MissionOutcomeName(report.outcome))
    << ",\n  \"error\": " << JsonQuote(report.error) << ",\n  \"collisions\": " << stats.collisions
    << ",\n  \"goals\": [";
  for (size_t i = 0; i < report.goals.size(); ++i) {
    const mission::GoalReport& g = report.goals[i];
    j << (i ? ",\n" : "\n") << "    {\"reached\": " << (g.reached ? "true" : "false")
      << ", \"error_m\": " << JsonNumber(g.visited ? g.error_m : NAN)
      << ", \"estimate_error_m\": " << JsonNumber(g.visited ? g.estimate_error_m : NAN)
      << ", \"line\": " << g.line << ", \"t_s\": " << JsonNumber(g.reached_at_s);
    if (r.hover[i].samples > 0) {
      j << ", \"hover_position_rms_m\": " << JsonNumber(r.hover[i].position_rms_m)
        << ", \"hover_rate_rms_radps\": " << JsonNumber(r.hover[i].angular_rate_rms_radps);
    }
    j << "}";
  }
  j << "\n  ],\n  \"ate_m\": " << JsonNumber(r.ate_m)
    << ",\n  \"path_m\": " << JsonNumber(stats.path_m)
    << ",\n  \"sim_time_s\": " << JsonNumber(report.sim_time_s)
    << ",\n  \"wall_time_s\": " << JsonNumber(r.wall_s)
    << ",\n  \"real_time_factor\": " << JsonNumber(report.sim_time_s / r.wall_s)
    << ",\n  \"holds\": " << report.holds << ",\n  \"localization\": {\"frames\": " << stats.frames
    << ", \"tracked\": " << stats.vo_tracked << ", \"lost\": " << stats.vo_lost
    << ", \"skipped\": " << stats.vo_skipped
    << ", \"vo_ms_mean\": " << JsonNumber(stats.vo_ms.mean_ms)
    << ", \"vo_ms_p95\": " << JsonNumber(stats.vo_ms.p95_ms)
    << ", \"render_ms_mean\": " << JsonNumber(stats.render_ms.mean_ms)
    << "},\n  \"estimator\": {\"poses_merged\": " << r.autopilot.poses
    << ", \"poses_rejected\": " << stats.poses_rejected
    << "},\n  \"mapping\": {\"map\": " << JsonQuote(stats.map_description)
    << ", \"keyframes\": " << stats.keyframes << ", \"rebuilds\": " << stats.map_rebuilds
    << ", \"build_ms_mean\": " << JsonNumber(stats.map_build_ms.mean_ms)
    << ", \"errors\": " << stats.map_errors;
  if (r.map_quality) {
    j << ", \"mcc\": " << JsonNumber(r.map_quality->mcc)
      << ", \"missed_percent\": " << JsonNumber(r.map_quality->missed_percent)
      << ", \"false_percent\": " << JsonNumber(r.map_quality->false_percent);
  }
  j << "},\n  \"planning\": {\"plans\": " << report.plans << ", \"replans\": " << report.replans
    << ", \"plan_ms_mean\": " << JsonNumber(stats.plan_ms.mean_ms)
    << "},\n  \"setup_s\": " << JsonNumber(stats.setup_s) << ",\n  \"events\": [";
  for (size_t i = 0; i < report.events.size(); ++i) {
    j << (i ? ",\n" : "\n") << "    {\"t_s\": " << JsonNumber(report.events[i].t_s)
      << ", \"what\": " << JsonQuote(report.events[i].what) << "}";
  }
  j << "\n  ]\n}\n";
  return j.str();
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

  Flown r;
  Result<dataset::MissionSpec> spec = dataset::ReadMissionFile(f.mission_path);
  if (!spec.ok()) return Fail(spec.status().message() + " (no take-off)");
  r.spec = *std::move(spec);
  if (!f.world.empty()) r.spec.world = f.world;
  mission::MissionOptions mission_options;
  mission_options.timeout_s = f.timeout_s;
  mission_options.face_goals = f.face_goals || f.map == "online";
  if (r.spec.world == "plant") mission_options.goal_tolerance_m = 0.5;

  const auto wall_start = std::chrono::steady_clock::now();
  std::fprintf(stderr, "%s: %s in %s, seed %llu, pose source %s: building the world and map\n",
               kCommand, f.mission_path.c_str(), r.spec.world.c_str(),
               static_cast<unsigned long long>(f.seed), f.pose_source.c_str());
  Result<std::unique_ptr<mission::LockstepDriver>> driver =
      mission::LockstepDriver::Create(r.spec, *options);
  if (!driver.ok()) return Fail(driver.status().ToString() + " (no take-off)");
  const bool tty = isatty(STDERR_FILENO) != 0;
  double next_line_s = 0;
  auto progress = [&](const mission::MissionProgress& p) {
    if (f.quiet || p.t_s < next_line_s) return;
    next_line_s = p.t_s + (tty ? 0.5 : 5.0);
    const mission::VehicleView& v = *p.vehicle;
    std::fprintf(stderr, "%st=%6.1f s  %-13s goal %d/%d  speed %.2f m/s  pose %s (age %.2f s)%s",
                 tty ? "\r" : "", p.t_s, mission::MissionPhaseName(p.phase), p.goal + 1, p.goals,
                 v.v_est.norm(), v.localization_state.c_str(),
                 std::isfinite(v.pose_age_s) ? v.pose_age_s : -1.0, tty ? "   " : "\n");
  };
  Result<mission::MissionReport> report =
      mission::RunMission(r.spec, mission_options, **driver, progress);
  if (tty && !f.quiet) std::fprintf(stderr, "\n");
  if (!report.ok()) return Fail(report.status().ToString());
  r.report = *std::move(report);
  r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  r.stats = (*driver)->stats();
  r.autopilot = (*driver)->autopilot().status();
  r.ate_m = mission::EstimateRmsError((*driver)->record());
  for (const mission::GoalReport& g : r.report.goals) {
    r.hover.push_back(mission::ScoreHover((*driver)->record(), g));
  }
  if (options->map_source == mission::MapSource::kOnline) {
    Result<mission::MapQuality> quality = (*driver)->EvaluateMap();
    if (!quality.ok()) return Fail("evaluating the final map: " + quality.status().ToString());
    r.map_quality = *quality;
  }
  PrintTable(f, r);

  if (!f.out_dir.empty()) {
    if (Status s = MakeDirectories(f.out_dir); !s.ok()) return Fail(s.message());
    if (Status s = WriteTrajectoryCsv(f.out_dir + "/trajectory.csv", (*driver)->record());
        !s.ok()) {
      return Fail(s.message());
    }
    if (Status s = WritePlot(f.out_dir + "/mission.png", r.spec, r.report, **driver); !s.ok()) {
      return Fail(s.message());
    }
    if (Status s = (*driver)->WriteMap(f.out_dir + "/map.bt"); !s.ok()) return Fail(s.message());
    std::printf("  wrote              %s/trajectory.csv, mission.png, map.bt\n", f.out_dir.c_str());
  }
  if (!f.json_path.empty()) {
    if (Status s = WriteStringToFileAtomic(f.json_path, ReportJson(f, r)); !s.ok()) {
      return Fail(s.message());
    }
  }
  return r.report.outcome == mission::MissionOutcome::kCompleted ? 0 : 1;
}

}  // namespace mav::eval_cli
