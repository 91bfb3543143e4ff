#include "mav/eval/control_eval.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include "mav/eval/paper_figures.h"

namespace mav::eval {
namespace {

// Gains with the three translational poles at -pole rad/s: (s + P)^3 = s^3 + 3P s^2 + 3P^2 s +
// P^3.
void PlacePositionPoles(double pole, control::PaperControllerGains* gains) {
  gains->position_omega_radps.setConstant(std::sqrt(3.0) * pole);
  gains->position_zeta.setConstant(std::sqrt(3.0) / 2.0);
  gains->integral_gain.setConstant(std::pow(pole, 3));
}

// One controller on one task; the legs it planned are taken from `legs`.
ControlRun FlyOne(const dataset::FlightTask& task, control::ControllerType controller,
                  const ControlEvalOptions& options, const RoadmapLegPlanner* planner) {
  FlightMissionOptions fly;
  fly.controller = controller;
  fly.seed = options.seed;
  if (planner != nullptr) {
    fly.planner = planner->planner;
    planner->legs->clear();
  }
  const ControllerTuning tuning = options.tuning;
  fly.tune = [tuning](control::AutopilotOptions* a) { tuning.Apply(a); };
  ControlRun run;
  run.controller = control::ControllerTypeName(controller);
  run.task = task.name;
  Result<FlightRecord> record = FlyTask(task, fly);
  if (planner != nullptr) run.legs = *planner->legs;
  if (!record.ok()) {
    run.status = record.status();
    return run;
  }
  run.score = ScoreFlight(task, *record);
  run.record = *std::move(record);
  return run;
}

void AddRunRows(const ControlRun& run, std::vector<std::string>* rows) {
  for (const PlannedLeg& l : run.legs) {
    rows->push_back(FormatLine(
        "        planned leg: %.1f m in %.1f ms, flight %.2f s, mean %.2f m/s, peak %.2f "
        "m/s, min clearance %.3f m",
        l.length_m, l.planning_ms, l.duration_s, l.mean_speed_mps, l.peak_speed_mps,
        l.min_clearance_m));
  }
  if (!run.status.ok()) return;
  const TaskScore& s = run.score;
  rows->push_back(FormatLine(
      "  %-5s %-5s points %5.1f / %4.1f  pos RMS %.4f m  rate RMS %.4f rad/s  settle %5.2f s"
      "  est RMS %.4f m  collisions %d  (%.0fx real time)",
      run.task.c_str(), run.controller.c_str(), s.points, s.max_points, s.position_rms_m,
      s.angular_rate_rms_radps, s.settling_time_s, s.estimator_rms_m, s.collisions,
      run.record.simulated_s / std::max(run.record.wall_s, 1e-9)));
  for (const GoalScore& g : s.goals) {
    std::string line = FormatLine(
        "        goal %d from %6.1f s: %s settle %5.2f s  pos %.4f m (%.1f)  rate %.4f (%.1f)"
        "  settle pts %.1f",
        g.goal, g.from_s, g.settled ? "  " : "NO", g.settling_time_s, g.rms.position_rms_m,
        g.position_points, g.rms.angular_rate_rms_radps, g.angular_rate_points, g.settling_points);
    if (g.flight_time_s > 0) {
      line += FormatLine("  leg %.1f m in %.2f s, mean %.2f m/s, peak %.2f m/s", g.path_length_m,
                         g.flight_time_s, g.mean_speed_mps, g.peak_speed_mps);
    }
    rows->push_back(line);
  }
  for (const sim::Collision& c : run.record.collisions) {
    rows->push_back(FormatLine("        COLLISION at %.2f s (%.2f, %.2f, %.2f): %s", c.t_ns * 1e-9,
                               c.p_world.x(), c.p_world.y(), c.p_world.z(), c.what.c_str()));
  }
}

// The planned legs' speeds: mean over the legs, or peak of all.
double LegSpeed(const TaskScore& score, bool peak) {
  double v = 0;
  for (const GoalScore& g : score.goals) {
    v = peak ? std::max(v, g.peak_speed_mps) : v + g.mean_speed_mps / score.goals.size();
  }
  return v;
}

void SetRunJson(const ControlRun& run, JsonReport* json) {
  const std::string group = run.controller + "/" + run.task;
  const TaskScore& s = run.score;
  json->Set(group, "points", s.points);
  json->Set(group, "max_points", s.max_points);
  json->Set(group, "position_rms_m", s.position_rms_m);
  json->Set(group, "angular_rate_rms_radps", s.angular_rate_rms_radps);
  json->Set(group, "settling_time_s", s.settling_time_s);
  json->Set(group, "all_settled", s.all_settled ? 1.0 : 0.0);
  json->Set(group, "estimator_position_rms_m", s.estimator_rms_m);
  json->Set(group, "collisions", static_cast<double>(s.collisions));
  json->Set(group, "min_clearance_m", run.record.min_clearance_m);
  json->Set(group, "realtime_factor", run.record.simulated_s / run.record.wall_s);
  json->Set(group, "step_mean_ms", run.record.step_ms.mean_ms);
  const double peak = LegSpeed(s, true);
  if (peak > 0) {
    json->Set(group, "leg_mean_speed_mps", LegSpeed(s, false));
    json->Set(group, "leg_peak_speed_mps", peak);
  }
}

void AddPaperTable(const ControlSummary& summary, Report* report) {
  auto find = [&](const std::string& c, const std::string& t) -> const ControlRun* {
    for (const ControlTaskResult& task : summary.tasks) {
      for (const ControlRun& r : task.runs) {
        if (r.status.ok() && r.controller == c && r.task == t) return &r;
      }
    }
    return nullptr;
  };
  auto cell = [&](const char* c, const char* t, double TaskScore::*field) {
    const ControlRun* r = find(c, t);
    return r ? FormatLine("%8.4f", r->score.*field) : std::string("       -");
  };
  auto speed = [&](const char* c, bool peak) {
    const ControlRun* r = find(c, "t4_3");
    if (r == nullptr || r->score.goals.empty()) return std::string("       -");
    return FormatLine("%8.2f", LegSpeed(r->score, peak));
  };
  const PaperControlFigures& paper = PaperControl();
  ReportTable& t = report->AddTable(
      "Holzmann et al. 2015 (Sec. 3) | ours (paper controller) | Lee (RotorS gains)");
  t.header.push_back(FormatLine("  %-34s %10s %10s %10s", "figure", "paper", "ours", "lee"));
  const auto score_row = [&](const char* figure, const char* format, double value, const char* task,
                             double TaskScore::*field) {
    t.rows.push_back(FormatLine(format, figure, value, cell("paper", task, field).c_str(),
                                cell("lee", task, field).c_str()));
  };
  score_row("t3_1 hover position RMS [m]", "  %-34s %10.3f %10s %10s", paper.hover_position_rms_m,
            "t3_1", &TaskScore::position_rms_m);
  score_row("t3_1 hover angular-rate RMS [rad/s]", "  %-34s %10.3f %10s %10s",
            paper.hover_angular_rate_rms_radps, "t3_1", &TaskScore::angular_rate_rms_radps);
  score_row("t3_2 constant wind settling [s]", "  %-34s %10.1f %10s %10s",
            paper.constant_wind_settling_s, "t3_2", &TaskScore::settling_time_s);
  t.rows.push_back(FormatLine("  %-34s %10s %10s %10s", "t3_3 gust settling [s]", "< 4",
                              cell("paper", "t3_3", &TaskScore::settling_time_s).c_str(),
                              cell("lee", "t3_3", &TaskScore::settling_time_s).c_str()));
  t.rows.push_back(FormatLine("  %-34s %10.2f %10s %10s", "t4_3 leg mean speed [m/s]",
                              paper.leg_mean_speed_mps, speed("paper", false).c_str(),
                              speed("lee", false).c_str()));
  t.rows.push_back(FormatLine("  %-34s %10.2f %10s %10s", "t4_3 leg peak speed [m/s]",
                              paper.leg_peak_speed_mps, speed("paper", true).c_str(),
                              speed("lee", true).c_str()));
}

}  // namespace

void ControllerTuning::Apply(control::AutopilotOptions* a) const {
  if (position_pole_radps > 0) PlacePositionPoles(position_pole_radps, &a->paper_gains);
  a->paper_gains.attitude_omega_radps = attitude_omega_radps;
  a->paper_gains.attitude_zeta = attitude_zeta;
  a->disturbance_observer_s = observer_s;
  a->correction_blend_s = blend_s;
  a->estimator.couple_tilt = !decoupled_estimator;
  a->tilt_braking_fraction = tilt_braking_fraction;
  if (model_mass_kg > 0) a->vehicle.mass_kg = model_mass_kg;
  a->allocation.roll_pitch_before_thrust_at_top = !strict_thrust_priority;
  a->gust_threshold_mps2 = gust_threshold_mps2;
  if (gust_pole_radps <= 0) {
    a->gust_gains.reset();
  } else {
    control::PaperControllerGains g = control::AutopilotOptions::GustGains();
    PlacePositionPoles(gust_pole_radps, &g);
    g.attitude_omega_radps = gust_attitude_omega_radps;
    a->gust_gains = g;
  }
}

Result<ControlSummary> EvaluateControl(const ControlEvalOptions& options) {
  ControlSummary summary;
  std::map<std::string, RoadmapLegPlanner> planners;  // by map path
  for (const dataset::FlightTask& task : options.tasks) {
    ControlTaskResult& result = summary.tasks.emplace_back();
    result.task = task;
    const RoadmapLegPlanner* planner = nullptr;
    if (task.kind == dataset::FlightTaskKind::kPlannedLegs) {
      if (!planners.count(task.map_path)) {
        Result<RoadmapLegPlanner> made =
            MakeRoadmapLegPlanner(task.map_path, options.roadmap_path, options.leg_limits);
        if (!made.ok()) {
          return Status(made.status().code(), task.name + ": " + made.status().message());
        }
        result.planner_log = made->log;
        planners[task.map_path] = *std::move(made);
      }
      planner = &planners.at(task.map_path);
    }
    for (control::ControllerType c : options.controllers) {
      result.runs.push_back(FlyOne(task, c, options, planner));
      if (!result.runs.back().status.ok()) ++summary.failures;
    }
  }
  return summary;
}

Report ControlReport(const ControlSummary& summary) {
  Report report;
  ReportTable& runs = report.AddTable("", /*blank_line_before=*/false);
  for (const ControlTaskResult& task : summary.tasks) {
    runs.rows.insert(runs.rows.end(), task.planner_log.begin(), task.planner_log.end());
    for (const ControlRun& run : task.runs) {
      AddRunRows(run, &runs.rows);
      if (run.status.ok()) SetRunJson(run, &report.json);
    }
  }
  AddPaperTable(summary, &report);
  return report;
}

}  // namespace mav::eval
