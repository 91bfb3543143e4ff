// mav-eval control: flies the EuRoC 2014 Challenge 3 simulation tasks (t3_1 ... t4_3) in one
// process, lock-stepped and faster than real time, with the paper's controller and the Lee peer
// side by side, scores them as the contest's scripts did (mav/eval/contest_score.h) and prints
// the paper's figures beside ours.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "clients/plot/plot.h"
#include "commands.h"
#include "json.h"
#include "leg_planner.h"
#include "mav/common/file.h"
#include "mav/common/flags.h"
#include "mav/dataset/flight_task_io.h"
#include "mav/eval/contest_score.h"
#include "mav/eval/flight_mission.h"
#include "mav/sim/flight_task.h"
#include "paper.h"

namespace mav::eval_cli {
namespace {

constexpr const char* kCommand = "mav-eval control";

int Fail(const std::string& message, int code = 1) {
  std::cerr << kCommand << ": " << message << "\n";
  return code;
}

// DIR/<controller>/<task>.csv at 100 Hz (every step at the contest's IMU rate).
Status WriteCsv(const std::string& path, const eval::FlightRecord& r) {
  std::ostringstream out;
  out << "t,x,y,z,qw,qx,qy,qz,vx,vy,vz,wx,wy,wz,ref_x,ref_y,ref_z,est_x,est_y,est_z\n";
  char line[512];
  double next_t = -1;
  for (const eval::FlightRecordSample& s : r.samples) {
    if (s.t_s + 1e-9 < next_t) continue;
    next_t = std::floor(s.t_s * 100 + 0.5) / 100 + 0.01;
    const auto& x = s.truth;
    std::snprintf(line, sizeof(line),
                  "%.3f,%.5f,%.5f,%.5f,%.6f,%.6f,%.6f,%.6f,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,"
                  "%.5f,%.5f,%.5f,%.5f,%.5f\n",
                  s.t_s, x.p_world.x(), x.p_world.y(), x.p_world.z(), x.q_world_body.w(),
                  x.q_world_body.x(), x.q_world_body.y(), x.q_world_body.z(), x.v_world.x(),
                  x.v_world.y(), x.v_world.z(), x.omega_body.x(), x.omega_body.y(),
                  x.omega_body.z(), s.reference.position.x(), s.reference.position.y(),
                  s.reference.position.z(), s.estimate.p_world.x(), s.estimate.p_world.y(),
                  s.estimate.p_world.z());
    out << line;
  }
  return WriteStringToFileAtomic(path, out.str());
}

// Position error |p - goal| against time for each controller, the force windows shaded and the
// scoring windows marked.
Status WriteErrorPlot(const std::string& path, const dataset::FlightTask& task,
                      const std::vector<const eval::FlightRecord*>& records,
                      const std::vector<eval::TaskScore>& scores) {
  const int w = 1100, h = 420, left = 70, right = 20, top = 40, bottom = 50;
  cv::Mat img(h, w, CV_8UC3, cv::Scalar(255, 255, 255));
  // Time span: from the first scored goal's reference time minus 2 s to its window's end.
  double t0 = 0, t1 = task.duration_s;
  if (task.kind == dataset::FlightTaskKind::kDisturbance) {
    t0 = task.forces.front().start_s - 3;
    t1 = std::min(task.duration_s, t0 + 28);
  } else if (task.kind == dataset::FlightTaskKind::kHover) {
    t0 = task.goals.back().publish_s;
    t1 = std::min(task.duration_s, t0 + task.scoring.hover_delay_s + task.scoring.window_s + 2);
  }
  double e_max = 0.05;
  auto goal_at = [&](int g) { return task.goals[std::max(0, g)].position; };
  for (const auto* r : records) {
    for (const auto& s : r->samples) {
      if (s.t_s < t0 || s.t_s > t1 || s.goal_index < 0) continue;
      e_max = std::max(e_max, (s.truth.p_world - goal_at(s.goal_index)).norm());
    }
  }
  e_max = std::min(e_max * 1.1, task.kind == dataset::FlightTaskKind::kHover ? 0.2 : 0.6);
  auto px = [&](double t, double e) {
    return cv::Point(
        left + static_cast<int>((t - t0) / (t1 - t0) * (w - left - right)),
        h - bottom - static_cast<int>(std::min(e, e_max) / e_max * (h - top - bottom)));
  };
  for (const dataset::ForceWindow& f : task.forces) {
    const double a = std::max(f.start_s, t0), b = std::min(f.end_s, t1);
    if (b > a) cv::rectangle(img, px(a, e_max), px(b, 0), cv::Scalar(215, 235, 255), cv::FILLED);
  }
  for (size_t k = 0; k < scores.size(); ++k) {
    for (const eval::GoalScore& g : scores[k].goals) {
      const double a = std::max(g.window_start_s, t0);
      const double b = std::min(g.window_start_s + task.scoring.window_s, t1);
      if (b > a) {
        const cv::Scalar c = k == 0 ? cv::Scalar(40, 160, 40) : cv::Scalar(40, 40, 200);
        const cv::Point lift(0, -5 * static_cast<int>(k));  // one bar above the other
        cv::line(img, px(a, 0) + lift, px(b, 0) + lift, c, 4);
      }
    }
  }
  // 0.1 m settling ball and the full-score band (0.02 m).
  for (double e : {task.scoring.settle_radius_m, 0.1 * task.scoring.position_limit_m}) {
    if (e < e_max) cv::line(img, px(t0, e), px(t1, e), cv::Scalar(160, 160, 160), 1);
  }
  cv::rectangle(img, px(t0, e_max), px(t1, 0), cv::Scalar(0, 0, 0), 1);
  const cv::Scalar colours[2] = {cv::Scalar(40, 160, 40), cv::Scalar(40, 40, 200)};
  for (size_t k = 0; k < records.size(); ++k) {
    std::vector<cv::Point> pts;
    for (const auto& s : records[k]->samples) {
      if (s.t_s < t0 || s.t_s > t1 || s.goal_index < 0) continue;
      pts.push_back(px(s.t_s, (s.truth.p_world - goal_at(s.goal_index)).norm()));
    }
    if (pts.size() > 1) cv::polylines(img, pts, false, colours[k % 2], 1, cv::LINE_AA);
    cv::putText(img, records[k]->controller,
                cv::Point(w - 160, top + 20 + 20 * static_cast<int>(k)), cv::FONT_HERSHEY_SIMPLEX,
                0.55, colours[k % 2], 2, cv::LINE_AA);
  }
  for (int i = 0; i <= 5; ++i) {
    const double e = e_max * i / 5;
    cv::putText(img, cv::format("%.3f", e), cv::Point(5, px(t0, e).y + 4), cv::FONT_HERSHEY_SIMPLEX,
                0.4, cv::Scalar(60, 60, 60), 1, cv::LINE_AA);
    const double t = t0 + (t1 - t0) * i / 5;
    cv::putText(img, cv::format("%.0f s", t), cv::Point(px(t, 0).x - 12, h - bottom + 18),
                cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(60, 60, 60), 1, cv::LINE_AA);
  }
  cv::putText(img,
              task.name +
                  ": position error |p - goal| [m] (shaded: external force; bars: "
                  "scoring windows; lines: 0.1 m ball, 0.02 m full band)",
              cv::Point(left, 25), cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 0), 1,
              cv::LINE_AA);
  if (!cv::imwrite(path, img)) return Status::IoError(path + ": cannot write PNG");
  return Status::Ok();
}

struct Run {
  std::string controller;
  std::string task;
  eval::FlightRecord record;
  eval::TaskScore score;
};

void PrintScore(const Run& run) {
  const eval::TaskScore& s = run.score;
  std::printf(
      "  %-5s %-5s points %5.1f / %4.1f  pos RMS %.4f m  rate RMS %.4f rad/s  settle %5.2f s"
      "  est RMS %.4f m  collisions %d  (%.0fx real time)\n",
      run.task.c_str(), run.controller.c_str(), s.points, s.max_points, s.position_rms_m,
      s.angular_rate_rms_radps, s.settling_time_s, s.estimator_rms_m, s.collisions,
      run.record.simulated_s / std::max(run.record.wall_s, 1e-9));
  for (const eval::GoalScore& g : s.goals) {
    std::printf(
        "        goal %d from %6.1f s: %s settle %5.2f s  pos %.4f m (%.1f)  rate %.4f (%.1f)"
        "  settle pts %.1f",
        g.goal, g.from_s, g.settled ? "  " : "NO", g.settling_time_s, g.rms.position_rms_m,
        g.position_points, g.rms.angular_rate_rms_radps, g.angular_rate_points, g.settling_points);
    if (g.flight_time_s > 0) {
      std::printf("  leg %.1f m in %.2f s, mean %.2f m/s, peak %.2f m/s", g.path_length_m,
                  g.flight_time_s, g.mean_speed_mps, g.peak_speed_mps);
    }
    std::printf("\n");
  }
  for (const sim::Collision& c : run.record.collisions) {
    std::printf("        COLLISION at %.2f s (%.2f, %.2f, %.2f): %s\n", c.t_ns * 1e-9,
                c.p_world.x(), c.p_world.y(), c.p_world.z(), c.what.c_str());
  }
}

}  // namespace

int RunControl(const std::vector<std::string>& args) {
  std::string task_name = "all", controller_name = "all", task_file, out_dir, json_path;
  std::string map_path = sim::DefaultPlantMapPath();
  uint64_t seed = 1;
  FlagParser flags(
      "mav-eval control --task t3_1|t3_2|t3_3|t4_1|t4_2|t4_3|all [--controller paper|lee|all] "
      "[--task-file F.yaml] [--seed S] [--out DIR] [--json FILE]");
  flags.AddString("task", &task_name, "contest task, or all");
  flags.AddString("controller", &controller_name, "paper (Holzmann et al.), lee (RotorS), all");
  flags.AddString("task-file", &task_file,
                  "YAML overriding figures of --task (or of its 'base:'); see flight_task_io.h");
  flags.AddUint64("seed", &seed, "sensor-noise seed");
  flags.AddString("out", &out_dir, "write DIR/<controller>/<task>.csv and PNG plots");
  flags.AddString("json", &json_path, "write {\"<controller>/<task>\": {metric: value}}");
  flags.AddString("map", &map_path, "t4_3's OctoMap (the contest's power_plant.bt)");
  std::string leg_limits;
  flags.AddString("leg-limits", &leg_limits,
                  "t4_3: the legs' speed, acceleration, lateral acceleration and jerk limits "
                  "V,A,L,J [m/s, m/s^2, m/s^2, m/s^3] (default: the Firefly's 10,6,7,15)");
  // The paper controller's design, for the trade-off measurements of docs/control.md.
  const control::PaperControllerGains defaults;
  double position_pole = 0, attitude_omega = defaults.attitude_omega_radps;
  double attitude_zeta = defaults.attitude_zeta;
  const control::AutopilotOptions ap_defaults;
  double observer_s = ap_defaults.disturbance_observer_s, blend_s = ap_defaults.correction_blend_s;
  bool decoupled = false;
  double tilt_braking = ap_defaults.tilt_braking_fraction;
  bool strict_thrust = false;
  double model_mass = 0;
  const control::PaperControllerGains gust_defaults = control::AutopilotOptions::GustGains();
  double gust_pole = 0;
  double gust_attitude_omega = gust_defaults.attitude_omega_radps;
  double gust_threshold = ap_defaults.gust_threshold_mps2;
  flags.AddDouble("gust-pole", &gust_pole,
                  "paper: translational poles at -P rad/s while a gust is rejected (0 = no gain "
                  "scheduling; 4 = AutopilotOptions::GustGains())");
  flags.AddDouble("gust-attitude-omega", &gust_attitude_omega,
                  "paper: planar loop natural frequency while a gust is rejected [rad/s]");
  flags.AddDouble("gust-threshold", &gust_threshold,
                  "observed disturbance step that switches the gust gains in [m/s^2]");
  flags.AddDouble("position-pole", &position_pole,
                  "paper: put the three translational poles at -P rad/s (0 = the default design)");
  flags.AddDouble("attitude-omega", &attitude_omega,
                  "paper: planar loop natural frequency [rad/s]");
  flags.AddDouble("attitude-zeta", &attitude_zeta, "paper: planar loop damping");
  flags.AddDouble("observer-s", &observer_s, "disturbance observer time constant [s] (0 = off)");
  flags.AddDouble("blend-s", &blend_s, "correction blending time constant [s] (0 = off)");
  flags.AddDouble("tilt-braking", &tilt_braking,
                  "paper: fraction of the rotors' angular acceleration the bounded planar loop "
                  "keeps for stopping a tilt (0 = the paper's unbounded linear loop)");
  flags.AddBool("strict-thrust-priority", &strict_thrust,
                "paper: the allocation keeps the thrust even at the top, where roll/pitch then "
                "get no torque (the old allocation; with --tilt-braking 0: the paper's loop)");
  flags.AddDouble("model-mass", &model_mass,
                  "the vehicle mass the controllers are told [kg] (0 = the contest's 1.568 kg; "
                  "the simulated Firefly weighs 1.5 kg)");
  flags.AddBool("decoupled-estimator", &decoupled,
                "the paper's decoupled estimator weights (no tilt coupling)");
  bool help = false;
  if (Status s = flags.Parse(args, nullptr, &help); !s.ok()) return Fail(s.message(), 2);
  if (help) {
    std::cout << flags.Help();
    return 0;
  }
  if (!(model_mass >= 0)) return Fail("--model-mass: must be >= 0 (0 = the contest's)", 2);
  std::vector<control::ControllerType> controllers;
  if (controller_name == "paper" || controller_name == "all") {
    controllers.push_back(control::ControllerType::kPaper);
  }
  if (controller_name == "lee" || controller_name == "all") {
    controllers.push_back(control::ControllerType::kLee);
  }
  if (controllers.empty()) {
    return Fail("--controller: unknown controller '" + controller_name + "' (paper, lee, all)", 2);
  }
  const dataset::FlightTaskResolver resolve = [&](const std::string& name) {
    return sim::BuiltinFlightTask(name, map_path);
  };
  std::vector<dataset::FlightTask> tasks;
  if (!task_file.empty()) {
    Result<dataset::FlightTask> t = dataset::ReadFlightTaskFile(
        task_file, resolve, task_name == "all" ? std::string() : task_name);
    if (!t.ok()) return Fail(t.status().message(), 2);
    tasks.push_back(*t);
  } else if (task_name == "all") {
    for (const std::string& n : sim::FlightTaskNames()) tasks.push_back(*resolve(n));
  } else {
    Result<dataset::FlightTask> t = resolve(task_name);
    if (!t.ok()) return Fail("--" + t.status().message(), 2);
    tasks.push_back(*t);
  }

  planning::SpeedLimits limits;
  if (!leg_limits.empty()) {
    double v[4];
    if (std::sscanf(leg_limits.c_str(), "%lf,%lf,%lf,%lf", &v[0], &v[1], &v[2], &v[3]) != 4) {
      return Fail("--leg-limits: expected V,A,L,J, got '" + leg_limits + "'", 2);
    }
    limits = {v[0], v[1], v[2], v[3]};
  }

  JsonReport json;
  std::vector<Run> runs;
  int failures = 0;
  std::map<std::string, eval::LegPlanner> leg_planners;  // by map path (leg_planner.h)
  for (const dataset::FlightTask& task : tasks) {
    if (task.kind == dataset::FlightTaskKind::kPlannedLegs && !leg_planners.count(task.map_path)) {
      Result<eval::LegPlanner> p = MakeRoadmapLegPlanner(
          task.map_path, out_dir.empty() ? "" : out_dir + "/roadmap.mavprm", limits, std::cout);
      if (!p.ok()) return Fail(task.name + ": " + p.status().message());
      leg_planners[task.map_path] = *p;
    }
    std::vector<size_t> task_runs;
    for (control::ControllerType c : controllers) {
      eval::FlightMissionOptions options;
      options.controller = c;
      options.seed = seed;
      if (task.kind == dataset::FlightTaskKind::kPlannedLegs) {
        options.planner = leg_planners.at(task.map_path);
      }
      options.tune = [&](control::AutopilotOptions* a) {
        if (position_pole > 0) {
          // (s + P)^3 = s^3 + 3P s^2 + 3P^2 s + P^3.
          a->paper_gains.position_omega_radps.setConstant(std::sqrt(3.0) * position_pole);
          a->paper_gains.position_zeta.setConstant(std::sqrt(3.0) / 2.0);
          a->paper_gains.integral_gain.setConstant(std::pow(position_pole, 3));
        }
        a->paper_gains.attitude_omega_radps = attitude_omega;
        a->paper_gains.attitude_zeta = attitude_zeta;
        a->disturbance_observer_s = observer_s;
        a->correction_blend_s = blend_s;
        a->estimator.couple_tilt = !decoupled;
        a->tilt_braking_fraction = tilt_braking;
        if (model_mass > 0) a->vehicle.mass_kg = model_mass;
        a->allocation.roll_pitch_before_thrust_at_top = !strict_thrust;
        a->gust_threshold_mps2 = gust_threshold;
        if (gust_pole <= 0) {
          a->gust_gains.reset();
        } else {
          control::PaperControllerGains g = gust_defaults;
          g.position_omega_radps.setConstant(std::sqrt(3.0) * gust_pole);
          g.position_zeta.setConstant(std::sqrt(3.0) / 2.0);
          g.integral_gain.setConstant(std::pow(gust_pole, 3));
          g.attitude_omega_radps = gust_attitude_omega;
          a->gust_gains = g;
        }
      };
      Result<eval::FlightRecord> record = eval::FlyTask(task, options);
      if (!record.ok()) {
        std::cerr << kCommand << ": " << record.status().ToString() << "\n";
        ++failures;
        continue;
      }
      Run run;
      run.controller = control::ControllerTypeName(c);
      run.task = task.name;
      run.score = eval::ScoreFlight(task, *record);
      run.record = std::move(record).value();
      PrintScore(run);
      const std::string group = run.controller + "/" + task.name;
      const eval::TaskScore& s = run.score;
      json.Set(group, "points", s.points);
      json.Set(group, "max_points", s.max_points);
      json.Set(group, "position_rms_m", s.position_rms_m);
      json.Set(group, "angular_rate_rms_radps", s.angular_rate_rms_radps);
      json.Set(group, "settling_time_s", s.settling_time_s);
      json.Set(group, "all_settled", s.all_settled ? 1.0 : 0.0);
      json.Set(group, "estimator_position_rms_m", s.estimator_rms_m);
      json.Set(group, "collisions", static_cast<double>(s.collisions));
      json.Set(group, "min_clearance_m", run.record.min_clearance_m);
      json.Set(group, "realtime_factor", run.record.simulated_s / run.record.wall_s);
      json.Set(group, "step_mean_ms", run.record.step_ms.mean_ms);
      double peak = 0, mean_speed = 0;
      for (const eval::GoalScore& g : s.goals) {
        peak = std::max(peak, g.peak_speed_mps);
        mean_speed += g.mean_speed_mps / s.goals.size();
      }
      if (peak > 0) {
        json.Set(group, "leg_mean_speed_mps", mean_speed);
        json.Set(group, "leg_peak_speed_mps", peak);
      }
      if (!out_dir.empty()) {
        const std::string dir = out_dir + "/" + run.controller;
        if (Status st = MakeDirectories(dir); !st.ok()) return Fail(st.message());
        if (Status st = WriteCsv(dir + "/" + task.name + ".csv", run.record); !st.ok()) {
          return Fail(st.message());
        }
      }
      task_runs.push_back(runs.size());
      runs.push_back(std::move(run));
    }
    if (!out_dir.empty() && !task_runs.empty()) {
      std::vector<const eval::FlightRecord*> recs;
      std::vector<eval::TaskScore> scores;
      for (size_t i : task_runs) {
        recs.push_back(&runs[i].record);
        scores.push_back(runs[i].score);
      }
      if (Status st = WriteErrorPlot(out_dir + "/" + task.name + "_error.png", task, recs, scores);
          !st.ok()) {
        return Fail(st.message());
      }
      if (task.kind == dataset::FlightTaskKind::kWaypoints ||
          task.kind == dataset::FlightTaskKind::kPlannedLegs) {
        std::vector<plot::PlotSeries> series;
        const int colours[2][3] = {{40, 160, 40}, {40, 40, 200}};
        for (size_t k = 0; k < recs.size(); ++k) {
          plot::PlotSeries s;
          s.label = recs[k]->controller;
          for (const auto& x : recs[k]->samples) s.positions.push_back(x.truth.p_world);
          s.b = colours[k % 2][0];
          s.g = colours[k % 2][1];
          s.r = colours[k % 2][2];
          series.push_back(std::move(s));
        }
        plot::PlotSeries goals;
        goals.label = "goals";
        for (const auto& g : task.goals) goals.positions.push_back(g.position);
        series.push_back(goals);
        if (Status st = plot::WriteTopViewPlot(out_dir + "/" + task.name + "_top.png",
                                               task.name + " top view", series);
            !st.ok()) {
          return Fail(st.message());
        }
      }
    }
  }

  // The paper's figures beside ours.
  const PaperControlFigures& paper = PaperControl();
  std::printf("\nHolzmann et al. 2015 (Sec. 3) | ours (paper controller) | Lee (RotorS gains)\n");
  auto find = [&](const std::string& c, const std::string& t) -> const Run* {
    for (const Run& r : runs) {
      if (r.controller == c && r.task == t) return &r;
    }
    return nullptr;
  };
  auto cell = [&](const Run* r, double eval::TaskScore::*field) {
    return r ? cv::format("%8.4f", r->score.*field) : std::string("       -");
  };
  std::printf("  %-34s %10s %10s %10s\n", "figure", "paper", "ours", "lee");
  std::printf("  %-34s %10.3f %10s %10s\n", "t3_1 hover position RMS [m]",
              paper.hover_position_rms_m,
              cell(find("paper", "t3_1"), &eval::TaskScore::position_rms_m).c_str(),
              cell(find("lee", "t3_1"), &eval::TaskScore::position_rms_m).c_str());
  std::printf("  %-34s %10.3f %10s %10s\n", "t3_1 hover angular-rate RMS [rad/s]",
              paper.hover_angular_rate_rms_radps,
              cell(find("paper", "t3_1"), &eval::TaskScore::angular_rate_rms_radps).c_str(),
              cell(find("lee", "t3_1"), &eval::TaskScore::angular_rate_rms_radps).c_str());
  std::printf("  %-34s %10.1f %10s %10s\n", "t3_2 constant wind settling [s]",
              paper.constant_wind_settling_s,
              cell(find("paper", "t3_2"), &eval::TaskScore::settling_time_s).c_str(),
              cell(find("lee", "t3_2"), &eval::TaskScore::settling_time_s).c_str());
  std::printf("  %-34s %10s %10s %10s\n", "t3_3 gust settling [s]", "< 4",
              cell(find("paper", "t3_3"), &eval::TaskScore::settling_time_s).c_str(),
              cell(find("lee", "t3_3"), &eval::TaskScore::settling_time_s).c_str());
  // The planned legs' speeds: mean over the legs, peak of all.
  auto leg_speed = [&](const Run* r, bool peak) {
    if (r == nullptr || r->score.goals.empty()) return std::string("       -");
    double v = 0;
    for (const eval::GoalScore& g : r->score.goals) {
      v = peak ? std::max(v, g.peak_speed_mps) : v + g.mean_speed_mps / r->score.goals.size();
    }
    return cv::format("%8.2f", v);
  };
  std::printf("  %-34s %10.2f %10s %10s\n", "t4_3 leg mean speed [m/s]", paper.leg_mean_speed_mps,
              leg_speed(find("paper", "t4_3"), false).c_str(),
              leg_speed(find("lee", "t4_3"), false).c_str());
  std::printf("  %-34s %10.2f %10s %10s\n", "t4_3 leg peak speed [m/s]", paper.leg_peak_speed_mps,
              leg_speed(find("paper", "t4_3"), true).c_str(),
              leg_speed(find("lee", "t4_3"), true).c_str());
  if (!json_path.empty()) {
    if (Status st = json.WriteFile(json_path); !st.ok()) return Fail(st.message());
  }
  return failures > 0 ? 1 : 0;
}

}  // namespace mav::eval_cli
