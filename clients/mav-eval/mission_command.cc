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

int Fail(const std::string& message, int code = 1) {
  std::cerr << kCommand << ": " << message << "\n";
  return code;
}

// RMS of |estimate - truth| over the samples while armed (no alignment).
double Ate(const std::vector<mission::FlightSample>& record) {
  double sum = 0;
  size_t n = 0;
  for (const mission::FlightSample& s : record) {
    if (!s.armed) continue;
    sum += (s.p_est - s.p_true).squaredNorm();
    ++n;
  }
  return n ? std::sqrt(sum / n) : 0.0;
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

}  // namespace

int RunMission(const std::vector<std::string>& args) {
  std::string mission_path, out_dir, json_path, pose_source_name = "vo";
  std::string vo_method_name = "sparse-subpixel", controller_name = "paper", outage_text;
  std::string world_override;
  uint64_t seed = 1;
  double vo_latency_s = 0.05, max_speed = 0;
  bool quiet = false;
  FlagParser flags(
      "mav-eval mission --mission FILE [--seed S] [--pose-source vo|contest|truth] [--out DIR] "
      "[--json FILE]\n\n"
      "Flies a mission file in one process, lock-stepped and deterministic for a seed: the "
      "simulated vehicle\nin the mission's world, its rendered stereo camera and IMU, the VO, the "
      "estimator and controller,\nthe planner and the mission logic. Exit status 0 only when the "
      "mission completed.");
  flags.AddString("mission", &mission_path, "mission file (YAML, docs/formats.md)");
  flags.AddUint64("seed", &seed, "seed of the simulation (textures, noise, roadmap)");
  flags.AddString("pose-source", &pose_source_name,
                  "the estimator's pose: vo (stereo VO on the rendered images), contest (the "
                  "contest's 10 Hz sensor), truth (debugging)");
  flags.AddString("world", &world_override,
                  "fly in this preset instead of the file's world (room-easy, room-medium and "
                  "room-hard share one layout)");
  flags.AddString("vo-method", &vo_method_name, "sparse-subpixel, sparse-pixel or dense");
  flags.AddString("controller", &controller_name, "paper or lee");
  flags.AddDouble("vo-latency", &vo_latency_s, "modelled VO latency, s (capture to estimator)", 0,
                  0.5);
  flags.AddDouble("max-speed", &max_speed, "planned speed limit, m/s (0 = the world's default)", 0,
                  20);
  flags.AddString("localization-outage", &outage_text,
                  "START,DURATION: the localization is down for DURATION s from START s and comes "
                  "back restarted (fault injection)");
  flags.AddString("out", &out_dir, "write trajectory.csv and mission.png here");
  flags.AddString("json", &json_path, "write the report here");
  flags.AddBool("quiet", &quiet, "no progress line");
  bool help = false;
  if (Status s = flags.Parse(args, nullptr, &help); !s.ok()) {
    return Fail(s.message() + "\n" + flags.Help(), 2);
  }
  if (help) {
    std::cout << flags.Help();
    return 0;
  }
  if (mission_path.empty()) return Fail("--mission: required\n" + flags.Help(), 2);
  mission::LockstepOptions options;
  options.seed = seed;
  options.vo_latency_s = vo_latency_s;
  const std::optional<mission::PoseSource> source = mission::ParsePoseSource(pose_source_name);
  if (!source) {
    return Fail(
        "--pose-source: " + QuoteForError(pose_source_name) + " is not one of vo, contest, truth",
        2);
  }
  options.pose_source = *source;
  const std::optional<localization::Method> method = localization::ParseMethod(vo_method_name);
  if (!method) {
    return Fail("--vo-method: " + QuoteForError(vo_method_name) +
                    " is not one of sparse-pixel, sparse-subpixel, dense",
                2);
  }
  options.vo_method = *method;
  if (controller_name == "paper") {
    options.controller = control::ControllerType::kPaper;
  } else if (controller_name == "lee") {
    options.controller = control::ControllerType::kLee;
  } else {
    return Fail("--controller: " + QuoteForError(controller_name) + " is not one of paper, lee", 2);
  }
  if (!outage_text.empty()) {
    const std::vector<std::string_view> parts = SplitFields(outage_text, ',');
    mission::LocalizationOutage outage;
    Result<double> start = parts.size() == 2 ? ParseDouble(parts[0], "start")
                                             : Result<double>(Status::InvalidArgument("fields"));
    Result<double> duration = parts.size() == 2 ? ParseDouble(parts[1], "duration")
                                                : Result<double>(Status::InvalidArgument("fields"));
    if (start.ok()) outage.start_s = *start;
    if (duration.ok()) outage.duration_s = *duration;
    if (!start.ok() || !duration.ok() || outage.start_s < 0 || outage.duration_s <= 0) {
      return Fail(
          "--localization-outage: expected START,DURATION in seconds (START >= 0, "
          "DURATION > 0), got " +
              QuoteForError(outage_text),
          2);
    }
    options.outages.push_back(outage);
  }

  Result<dataset::MissionSpec> spec = dataset::ReadMissionFile(mission_path);
  if (!spec.ok()) return Fail(spec.status().message() + " (no take-off)");
  if (!world_override.empty()) spec->world = world_override;
  mission::MissionOptions mission_options;
  if (spec->world == "plant") mission_options.goal_tolerance_m = 0.5;
  if (max_speed > 0) {
    planning::SpeedLimits limits;
    limits.max_speed_mps = max_speed;
    limits.max_acceleration_mps2 = std::min(2.0, max_speed);
    limits.max_lateral_acceleration_mps2 = std::min(2.0, max_speed);
    limits.max_jerk_mps3 = 5.0;
    options.limits = limits;
  }

  const auto wall_start = std::chrono::steady_clock::now();
  std::fprintf(stderr, "%s: %s in %s, seed %llu, pose source %s: building the world and map\n",
               kCommand, mission_path.c_str(), spec->world.c_str(),
               static_cast<unsigned long long>(seed), pose_source_name.c_str());
  Result<std::unique_ptr<mission::LockstepDriver>> driver =
      mission::LockstepDriver::Create(*spec, options);
  if (!driver.ok()) return Fail(driver.status().ToString() + " (no take-off)");
  const bool tty = isatty(STDERR_FILENO) != 0;
  double next_line_s = 0;
  auto progress = [&](const mission::MissionProgress& p) {
    if (quiet || (!tty && p.t_s < next_line_s)) return;
    if (tty && p.t_s < next_line_s) return;
    next_line_s = p.t_s + (tty ? 0.5 : 5.0);
    const mission::VehicleView& v = *p.vehicle;
    std::fprintf(stderr, "%st=%6.1f s  %-13s goal %d/%d  speed %.2f m/s  pose %s (age %.2f s)%s",
                 tty ? "\r" : "", p.t_s, mission::MissionPhaseName(p.phase), p.goal + 1, p.goals,
                 v.v_est.norm(), v.localization_state.c_str(),
                 std::isfinite(v.pose_age_s) ? v.pose_age_s : -1.0, tty ? "   " : "\n");
  };
  Result<mission::MissionReport> report =
      mission::RunMission(*spec, mission_options, **driver, progress);
  if (tty && !quiet) std::fprintf(stderr, "\n");
  if (!report.ok()) return Fail(report.status().ToString());
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  const mission::LockstepStats stats = (*driver)->stats();
  const std::vector<mission::FlightSample>& record = (*driver)->record();
  const double ate = Ate(record);
  const control::AutopilotStatus ap = (*driver)->autopilot().status();

  // The table.
  std::printf("mission %s (%s, seed %llu, pose source %s, %s)\n", mission_path.c_str(),
              spec->world.c_str(), static_cast<unsigned long long>(seed), pose_source_name.c_str(),
              controller_name.c_str());
  std::printf("  outcome            %s%s%s\n", mission::MissionOutcomeName(report->outcome),
              report->error.empty() ? "" : ": ", report->error.c_str());
  int reached = 0;
  for (size_t i = 0; i < report->goals.size(); ++i) {
    const mission::GoalReport& g = report->goals[i];
    reached += g.reached;
    std::printf("  goal %zu (line %d)    %s  error %.3f m (estimate %.3f m)\n", i + 1, g.line,
                g.reached ? "reached" : (g.visited ? "MISSED " : "not visited"), g.error_m,
                g.estimate_error_m);
  }
  std::printf("  goals reached      %d of %zu\n", reached, report->goals.size());
  std::printf("  collisions         %lld\n", static_cast<long long>(stats.collisions));
  for (const std::string& c : stats.collision_descriptions) std::printf("    %s\n", c.c_str());
  std::printf("  ATE (no alignment) %.4f m\n", ate);
  std::printf("  path flown         %.1f m in %.1f s simulated, %.1f s wall (x%.2f real time)\n",
              stats.path_m, report->sim_time_s, wall_s, report->sim_time_s / wall_s);
  std::printf(
      "  localization       %llu frames: %llu tracked, %llu lost, %llu skipped; VO %.1f ms "
      "mean, render %.1f ms mean\n",
      static_cast<unsigned long long>(stats.frames),
      static_cast<unsigned long long>(stats.vo_tracked),
      static_cast<unsigned long long>(stats.vo_lost),
      static_cast<unsigned long long>(stats.vo_skipped), stats.vo_ms.mean_ms,
      stats.render_ms.mean_ms);
  std::printf("  estimator          %llu poses merged, %llu rejected by the gate\n",
              static_cast<unsigned long long>(ap.poses),
              static_cast<unsigned long long>(stats.poses_rejected));
  std::printf("  planning           %d plans, %d replans (%.0f ms mean) on the %s\n", report->plans,
              report->replans, stats.plan_ms.mean_ms, stats.map_description.c_str());
  std::printf("  holds              %d\n", report->holds);

  if (!out_dir.empty()) {
    if (Status s = MakeDirectories(out_dir); !s.ok()) return Fail(s.message());
    if (Status s = WriteTrajectoryCsv(out_dir + "/trajectory.csv", record); !s.ok()) {
      return Fail(s.message());
    }
    if (Status s = WritePlot(out_dir + "/mission.png", *spec, *report, **driver); !s.ok()) {
      return Fail(s.message());
    }
    std::printf("  wrote              %s/trajectory.csv, %s/mission.png\n", out_dir.c_str(),
                out_dir.c_str());
  }
  if (!json_path.empty()) {
    std::ostringstream j;
    j << "{\n  \"mission\": " << JsonQuote(mission_path)
      << ",\n  \"world\": " << JsonQuote(spec->world) << ",\n  \"seed\": " << seed
      << ",\n  \"pose_source\": " << JsonQuote(pose_source_name)
      << ",\n  \"controller\": " << JsonQuote(controller_name)
      << ",\n  \"outcome\": " << JsonQuote(mission::MissionOutcomeName(report->outcome))
      << ",\n  \"error\": " << JsonQuote(report->error)
      << ",\n  \"collisions\": " << stats.collisions << ",\n  \"goals\": [";
    for (size_t i = 0; i < report->goals.size(); ++i) {
      const mission::GoalReport& g = report->goals[i];
      j << (i ? ",\n" : "\n") << "    {\"reached\": " << (g.reached ? "true" : "false")
        << ", \"error_m\": " << JsonNumber(g.visited ? g.error_m : NAN)
        << ", \"estimate_error_m\": " << JsonNumber(g.visited ? g.estimate_error_m : NAN)
        << ", \"line\": " << g.line << ", \"t_s\": " << JsonNumber(g.reached_at_s) << "}";
    }
    j << "\n  ],\n  \"ate_m\": " << JsonNumber(ate)
      << ",\n  \"path_m\": " << JsonNumber(stats.path_m)
      << ",\n  \"sim_time_s\": " << JsonNumber(report->sim_time_s)
      << ",\n  \"wall_time_s\": " << JsonNumber(wall_s)
      << ",\n  \"real_time_factor\": " << JsonNumber(report->sim_time_s / wall_s)
      << ",\n  \"holds\": " << report->holds
      << ",\n  \"localization\": {\"frames\": " << stats.frames
      << ", \"tracked\": " << stats.vo_tracked << ", \"lost\": " << stats.vo_lost
      << ", \"skipped\": " << stats.vo_skipped
      << ", \"vo_ms_mean\": " << JsonNumber(stats.vo_ms.mean_ms)
      << ", \"vo_ms_p95\": " << JsonNumber(stats.vo_ms.p95_ms)
      << ", \"render_ms_mean\": " << JsonNumber(stats.render_ms.mean_ms)
      << "},\n  \"estimator\": {\"poses_merged\": " << ap.poses
      << ", \"poses_rejected\": " << stats.poses_rejected
      << "},\n  \"mapping\": {\"map\": " << JsonQuote(stats.map_description)
      << ", \"keyframes\": 0, \"rebuilds\": 0},\n  \"planning\": {\"plans\": " << report->plans
      << ", \"replans\": " << report->replans
      << ", \"plan_ms_mean\": " << JsonNumber(stats.plan_ms.mean_ms)
      << "},\n  \"setup_s\": " << JsonNumber(stats.setup_s) << ",\n  \"events\": [";
    for (size_t i = 0; i < report->events.size(); ++i) {
      j << (i ? ",\n" : "\n") << "    {\"t_s\": " << JsonNumber(report->events[i].t_s)
        << ", \"what\": " << JsonQuote(report->events[i].what) << "}";
    }
    j << "\n  ]\n}\n";
    if (Status s = WriteStringToFileAtomic(json_path, j.str()); !s.ok()) return Fail(s.message());
  }
  return report->outcome == mission::MissionOutcome::kCompleted ? 0 : 1;
}

}  // namespace mav::eval_cli
