#include "mav/mission/report.h"

#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <memory>
#include <sstream>

#include <unistd.h>

#include "mav/common/file.h"
#include "mav/common/text.h"

namespace mav::mission {

namespace {
// Hovers at least this long get their t3_1 figures in the table (5 s settling + the window).
constexpr double kHoverScoredS = 15;

std::string Format(const char* format, ...) __attribute__((format(printf, 1, 2)));
std::string Format(const char* format, ...) {
  char buf[1024];
  va_list args;
  va_start(args, format);
  std::vsnprintf(buf, sizeof(buf), format, args);
  va_end(args);
  return buf;
}
}  // namespace

MissionProgressCallback ProgressLinePrinter(bool quiet, std::function<std::string()> extra) {
  if (quiet) return {};
  const bool tty = isatty(STDERR_FILENO) != 0;
  auto next_line_s = std::make_shared<double>(0.0);
  return [tty, next_line_s, extra = std::move(extra)](const MissionProgress& p) {
    const bool last = p.phase == MissionPhase::kDone;
    if (p.t_s < *next_line_s && !last) return;
    *next_line_s = p.t_s + (tty ? 0.5 : 5.0);
    const VehicleView& v = *p.vehicle;
    char map[64] = "";
    if (v.map_keyframes > 0 || v.map_version > 0) {
      std::snprintf(map, sizeof(map), "  map %lld keyframes, v%llu",
                    static_cast<long long>(v.map_keyframes),
                    static_cast<unsigned long long>(v.map_version));
    }
    std::fprintf(
        stderr, "%st=%6.1f s  %-13s goal %d/%d  speed %.2f m/s  pose %s (age %.2f s)%s%s%s",
        tty ? "\r" : "", p.t_s, MissionPhaseName(p.phase), p.goal + 1, p.goals, v.v_est.norm(),
        v.localization_state.c_str(), std::isfinite(v.pose_age_s) ? v.pose_age_s : -1.0, map,
        extra ? ("  " + extra()).c_str() : "", tty && !last ? "   " : "\n");
  };
}

MissionFigures FiguresOf(const std::string& mission_path, const std::string& world,
                         const std::string& pose_source, const std::string& controller,
                         const std::string& driver, uint64_t seed, MissionReport report,
                         double wall_s, const std::vector<FlightSample>& record) {
  MissionFigures f;
  f.mission_path = mission_path;
  f.world = world;
  f.pose_source = pose_source;
  f.controller = controller;
  f.driver = driver;
  f.seed = seed;
  f.report = std::move(report);
  f.wall_s = wall_s;
  f.ate_m = EstimateRmsError(record);
  for (const GoalReport& g : f.report.goals) f.hover.push_back(ScoreHover(record, g));
  return f;
}

std::string MissionTable(const MissionFigures& r) {
  const MissionReport& report = r.report;
  std::string t;
  t += Format("mission %s (%s, seed %llu, pose source %s, %s, %s)\n", r.mission_path.c_str(),
              r.world.c_str(), static_cast<unsigned long long>(r.seed), r.pose_source.c_str(),
              r.controller.c_str(), r.driver.c_str());
  t += Format("  outcome            %s%s%s\n", MissionOutcomeName(report.outcome),
              report.error.empty() ? "" : ": ", report.error.c_str());
  int reached = 0;
  for (size_t i = 0; i < report.goals.size(); ++i) {
    const GoalReport& g = report.goals[i];
    reached += g.reached;
    t += Format("  goal %zu (line %d)    %s  error %.3f m (estimate %.3f m)\n", i + 1, g.line,
                g.reached ? "reached" : (g.visited ? "MISSED " : "not visited"), g.error_m,
                g.estimate_error_m);
    if (i < r.hover.size() && r.hover[i].samples > 0 &&
        g.reached_at_s - g.hover_start_s >= kHoverScoredS) {
      t += Format("    hover from +5 s:  position RMS %.4f m, angular-rate RMS %.4f rad/s\n",
                  r.hover[i].position_rms_m, r.hover[i].angular_rate_rms_radps);
    }
  }
  t += Format("  goals reached      %d of %zu\n", reached, report.goals.size());
  t += Format("  collisions         %lld\n", static_cast<long long>(r.collisions));
  for (const std::string& c : r.collision_descriptions) t += "    " + c + "\n";
  t += Format("  ATE (no alignment) %.4f m\n", r.ate_m);
  t += Format("  path flown         %.1f m in %.1f s simulated, %.1f s wall (x%.2f real time)\n",
              r.path_m, report.sim_time_s, r.wall_s, report.sim_time_s / r.wall_s);
  t += Format(
      "  localization       %llu frames: %llu tracked, %llu lost, %llu skipped; VO %.1f ms "
      "mean, render %.1f ms mean\n",
      static_cast<unsigned long long>(r.frames), static_cast<unsigned long long>(r.vo_tracked),
      static_cast<unsigned long long>(r.vo_lost), static_cast<unsigned long long>(r.vo_skipped),
      r.vo_ms.mean_ms, r.render_ms.mean_ms);
  t += Format("  estimator          %llu poses merged, %llu rejected by the gate\n",
              static_cast<unsigned long long>(r.poses_merged),
              static_cast<unsigned long long>(r.poses_rejected));
  t += Format("  planning           %d plans, %d replans (%.0f ms mean) on the %s\n", report.plans,
              report.replans, r.plan_ms.mean_ms, r.map_description.c_str());
  if (r.map_rebuilds > 0) {
    t += Format(
        "  online map         %lld keyframes, %llu rebuilds (%.0f ms mean), %llu errors; "
        "%llu roadmaps\n",
        static_cast<long long>(r.keyframes), static_cast<unsigned long long>(r.map_rebuilds),
        r.map_build_ms.mean_ms, static_cast<unsigned long long>(r.map_errors),
        static_cast<unsigned long long>(r.roadmap_builds));
  }
  if (r.map_quality) {
    t += Format("  final map          MCC %.3f, missed collisions %.2f %%, false %.2f %% (%s)\n",
                r.map_quality->mcc, r.map_quality->missed_percent, r.map_quality->false_percent,
                r.map_quality->observable_only ? "observable volume" : "whole world");
  }
  if (r.tick_ms) {
    t += Format(
        "  services           tick %.1f ms mean (p95 %.1f), %llu frames flown without "
        "their pose, set-up %.1f s\n",
        r.tick_ms->mean_ms, r.tick_ms->p95_ms,
        static_cast<unsigned long long>(r.lockstep_frames_missed.value_or(0)), r.setup_s);
  }
  if (r.pose_latency && r.pose_latency->total.count > 0) {
    const MissionFigures::PoseLatency& l = *r.pose_latency;
    t += Format(
        "  vision latency     capture -> estimator p50 %.1f / p99 %.1f / max %.1f ms (%llu poses); "
        "p50 by hop: frame over DDS %.2f, localization %.1f, pose over DDS %.2f, into the "
        "estimator %.3f ms\n",
        l.total.median_ms, l.total.p99_ms, l.total.max_ms,
        static_cast<unsigned long long>(l.total.count), l.frame_transport.median_ms,
        l.localization.median_ms, l.pose_transport.median_ms, l.merge.median_ms);
  }
  t += Format("  holds              %d\n", report.holds);
  return t;
}

std::string MissionJson(const MissionFigures& r) {
  const MissionReport& report = r.report;
  std::ostringstream j;
  j << "{\n  \"mission\": " << JsonQuote(r.mission_path) << ",\n  \"world\": " << JsonQuote(r.world)
    << ",\n  \"seed\": " << r.seed << ",\n  \"pose_source\": " << JsonQuote(r.pose_source)
    << ",\n  \"controller\": " << JsonQuote(r.controller)
    << ",\n  \"driver\": " << JsonQuote(r.driver)
    << ",\n  \"outcome\": " << JsonQuote(MissionOutcomeName(report.outcome))
    << ",\n  \"error\": " << JsonQuote(report.error) << ",\n  \"collisions\": " << r.collisions
    << ",\n  \"goals\": [";
  for (size_t i = 0; i < report.goals.size(); ++i) {
    const GoalReport& g = report.goals[i];
    j << (i ? ",\n" : "\n") << "    {\"reached\": " << (g.reached ? "true" : "false")
      << ", \"error_m\": " << JsonNumber(g.visited ? g.error_m : NAN)
      << ", \"estimate_error_m\": " << JsonNumber(g.visited ? g.estimate_error_m : NAN)
      << ", \"line\": " << g.line << ", \"t_s\": " << JsonNumber(g.reached_at_s);
    if (i < r.hover.size() && r.hover[i].samples > 0) {
      j << ", \"hover_position_rms_m\": " << JsonNumber(r.hover[i].position_rms_m)
        << ", \"hover_rate_rms_radps\": " << JsonNumber(r.hover[i].angular_rate_rms_radps);
    }
    j << "}";
  }
  j << "\n  ],\n  \"ate_m\": " << JsonNumber(r.ate_m) << ",\n  \"path_m\": " << JsonNumber(r.path_m)
    << ",\n  \"sim_time_s\": " << JsonNumber(report.sim_time_s)
    << ",\n  \"wall_time_s\": " << JsonNumber(r.wall_s)
    << ",\n  \"real_time_factor\": " << JsonNumber(report.sim_time_s / r.wall_s)
    << ",\n  \"holds\": " << report.holds << ",\n  \"localization\": {\"frames\": " << r.frames
    << ", \"tracked\": " << r.vo_tracked << ", \"lost\": " << r.vo_lost
    << ", \"skipped\": " << r.vo_skipped << ", \"vo_ms_mean\": " << JsonNumber(r.vo_ms.mean_ms)
    << ", \"vo_ms_p95\": " << JsonNumber(r.vo_ms.p95_ms)
    << ", \"render_ms_mean\": " << JsonNumber(r.render_ms.mean_ms)
    << "},\n  \"estimator\": {\"poses_merged\": " << r.poses_merged
    << ", \"poses_rejected\": " << r.poses_rejected;
  if (r.lockstep_frames_missed) j << ", \"frames_without_pose\": " << *r.lockstep_frames_missed;
  j << "},\n  \"mapping\": {\"map\": " << JsonQuote(r.map_description)
    << ", \"keyframes\": " << r.keyframes << ", \"rebuilds\": " << r.map_rebuilds
    << ", \"build_ms_mean\": " << JsonNumber(r.map_build_ms.mean_ms)
    << ", \"errors\": " << r.map_errors << ", \"roadmaps\": " << r.roadmap_builds;
  if (r.map_quality) {
    j << ", \"mcc\": " << JsonNumber(r.map_quality->mcc)
      << ", \"missed_percent\": " << JsonNumber(r.map_quality->missed_percent)
      << ", \"false_percent\": " << JsonNumber(r.map_quality->false_percent);
  }
  j << "},\n  \"planning\": {\"plans\": " << report.plans << ", \"replans\": " << report.replans
    << ", \"plan_ms_mean\": " << JsonNumber(r.plan_ms.mean_ms) << "}";
  if (r.tick_ms) {
    j << ",\n  \"services\": {\"tick_ms_mean\": " << JsonNumber(r.tick_ms->mean_ms)
      << ", \"tick_ms_p95\": " << JsonNumber(r.tick_ms->p95_ms);
    if (r.pose_latency) {
      const MissionFigures::PoseLatency& l = *r.pose_latency;
      j << ", \"pose_latency_ms\": {\"count\": " << l.total.count
        << ", \"p50\": " << JsonNumber(l.total.median_ms)
        << ", \"p99\": " << JsonNumber(l.total.p99_ms)
        << ", \"max\": " << JsonNumber(l.total.max_ms)
        << ", \"frame_transport_p50\": " << JsonNumber(l.frame_transport.median_ms)
        << ", \"localization_p50\": " << JsonNumber(l.localization.median_ms)
        << ", \"pose_transport_p50\": " << JsonNumber(l.pose_transport.median_ms)
        << ", \"merge_p50\": " << JsonNumber(l.merge.median_ms) << "}";
    }
    j << "}";
  }
  j << ",\n  \"setup_s\": " << JsonNumber(r.setup_s) << ",\n  \"events\": [";
  for (size_t i = 0; i < report.events.size(); ++i) {
    j << (i ? ",\n" : "\n") << "    {\"t_s\": " << JsonNumber(report.events[i].t_s)
      << ", \"what\": " << JsonQuote(report.events[i].what) << "}";
  }
  j << "\n  ]\n}\n";
  return j.str();
}

Status WriteTrajectoryCsv(const std::string& path, const std::vector<FlightSample>& record) {
  std::ostringstream out;
  out << "t,gt_x,gt_y,gt_z,est_x,est_y,est_z,gt_qw,gt_qx,gt_qy,gt_qz,est_qw,est_qx,est_qy,est_qz,"
         "armed\n";
  char line[400];
  for (const FlightSample& s : record) {
    std::snprintf(line, sizeof(line),
                  "%.3f,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%d\n",
                  s.t_s, s.p_true.x(), s.p_true.y(), s.p_true.z(), s.p_est.x(), s.p_est.y(),
                  s.p_est.z(), s.q_true.w(), s.q_true.x(), s.q_true.y(), s.q_true.z(), s.q_est.w(),
                  s.q_est.x(), s.q_est.y(), s.q_est.z(), s.armed ? 1 : 0);
    out << line;
  }
  return WriteStringToFileAtomic(path, out.str());
}

}  // namespace mav::mission
