// mav-eval control: flies the EuRoC 2014 Challenge 3 simulation tasks (t3_1 ... t4_3) in one
// process, lock-stepped and faster than real time, with the paper's controller and the Lee peer
// side by side, scores them as the contest's scripts did and prints the paper's figures beside
// ours (mav/eval/control_eval.h).

#include <cmath>
#include <cstdio>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "clients/plot/control_plot.h"
#include "clients/plot/plot.h"
#include "commands.h"
#include "mav/common/file.h"
#include "mav/common/flags.h"
#include "mav/dataset/flight_task_io.h"
#include "mav/eval/control_eval.h"
#include "mav/sim/flight_task.h"
#include "output.h"

namespace mav::eval_cli {
namespace {

constexpr const char* kCommand = "mav-eval control";

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

// DIR/<controller>/<task>.csv of every run, DIR/<task>_error.png and, for the tasks with legs,
// DIR/<task>_top.png.
Status WriteTaskFiles(const std::string& out_dir, const eval::ControlTaskResult& result) {
  const dataset::FlightTask& task = result.task;
  std::vector<const eval::FlightRecord*> recs;
  std::vector<eval::TaskScore> scores;
  for (const eval::ControlRun& run : result.runs) {
    if (!run.status.ok()) continue;
    const std::string dir = out_dir + "/" + run.controller;
    MAV_RETURN_IF_ERROR(MakeDirectories(dir));
    MAV_RETURN_IF_ERROR(WriteCsv(dir + "/" + task.name + ".csv", run.record));
    recs.push_back(&run.record);
    scores.push_back(run.score);
  }
  if (recs.empty()) return Status::Ok();
  MAV_RETURN_IF_ERROR(
      plot::WriteControlErrorPlot(out_dir + "/" + task.name + "_error.png", task, recs, scores));
  if (task.kind != dataset::FlightTaskKind::kWaypoints &&
      task.kind != dataset::FlightTaskKind::kPlannedLegs) {
    return Status::Ok();
  }
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
  return plot::WriteTopViewPlot(out_dir + "/" + task.name + "_top.png", task.name + " top view",
                                series);
}

// The command line.
struct ControlFlags {
  std::string task = "all", controller = "all", task_file, out_dir, json_path, leg_limits;
  std::string map_path = sim::DefaultPlantMapPath();
  eval::ControlEvalOptions options;
};

FlagParser MakeFlags(ControlFlags* f) {
  FlagParser flags(
      "mav-eval control --task t3_1|t3_2|t3_3|t4_1|t4_2|t4_3|all [--controller paper|lee|all] "
      "[--task-file F.yaml] [--seed S] [--out DIR] [--json FILE]");
  flags.AddString("task", &f->task, "contest task, or all");
  flags.AddString("controller", &f->controller, "paper (Holzmann et al.), lee (RotorS), all");
  flags.AddString("task-file", &f->task_file,
                  "YAML overriding figures of --task (or of its 'base:'); see flight_task_io.h");
  flags.AddUint64("seed", &f->options.seed, "sensor-noise seed");
  flags.AddString("out", &f->out_dir, "write DIR/<controller>/<task>.csv and PNG plots");
  flags.AddString("json", &f->json_path, "write {\"<controller>/<task>\": {metric: value}}");
  flags.AddString("map", &f->map_path, "t4_3's OctoMap (the contest's power_plant.bt)");
  flags.AddString("leg-limits", &f->leg_limits,
                  "t4_3: the legs' speed, acceleration, lateral acceleration and jerk limits "
                  "V,A,L,J [m/s, m/s^2, m/s^2, m/s^3] (default: the Firefly's 10,6,7,15)");
  eval::ControllerTuning& t = f->options.tuning;
  flags.AddDouble("gust-pole", &t.gust_pole_radps,
                  "paper: translational poles at -P rad/s while a gust is rejected (0 = no gain "
                  "scheduling; 4 = AutopilotOptions::GustGains())");
  flags.AddDouble("gust-attitude-omega", &t.gust_attitude_omega_radps,
                  "paper: planar loop natural frequency while a gust is rejected [rad/s]");
  flags.AddDouble("gust-threshold", &t.gust_threshold_mps2,
                  "observed disturbance step that switches the gust gains in [m/s^2]");
  flags.AddDouble("position-pole", &t.position_pole_radps,
                  "paper: put the three translational poles at -P rad/s (0 = the default design)");
  flags.AddDouble("attitude-omega", &t.attitude_omega_radps,
                  "paper: planar loop natural frequency [rad/s]");
  flags.AddDouble("attitude-zeta", &t.attitude_zeta, "paper: planar loop damping");
  flags.AddDouble("observer-s", &t.observer_s, "disturbance observer time constant [s] (0 = off)");
  flags.AddDouble("blend-s", &t.blend_s, "correction blending time constant [s] (0 = off)");
  flags.AddDouble("tilt-braking", &t.tilt_braking_fraction,
                  "paper: fraction of the rotors' angular acceleration the bounded planar loop "
                  "keeps for stopping a tilt (0 = the paper's unbounded linear loop)");
  flags.AddBool("strict-thrust-priority", &t.strict_thrust_priority,
                "paper: the allocation keeps the thrust even at the top, where roll/pitch then "
                "get no torque (the old allocation; with --tilt-braking 0: the paper's loop)");
  flags.AddDouble("model-mass", &t.model_mass_kg,
                  "the vehicle mass the controllers are told [kg] (0 = the contest's 1.568 kg; "
                  "the simulated Firefly weighs 1.5 kg)");
  flags.AddBool("decoupled-estimator", &t.decoupled_estimator,
                "the paper's decoupled estimator weights (no tilt coupling)");
  return flags;
}

// The controllers, tasks (built in, or from the task file) and leg limits of the flags;
// InvalidArgument naming the flag.
Status CompleteOptions(ControlFlags* f) {
  eval::ControlEvalOptions& o = f->options;
  if (!(o.tuning.model_mass_kg >= 0)) {
    return Status::InvalidArgument("--model-mass: must be >= 0 (0 = the contest's)");
  }
  o.controllers.clear();
  if (f->controller == "paper" || f->controller == "all") {
    o.controllers.push_back(control::ControllerType::kPaper);
  }
  if (f->controller == "lee" || f->controller == "all") {
    o.controllers.push_back(control::ControllerType::kLee);
  }
  if (o.controllers.empty()) {
    return Status::InvalidArgument("--controller: unknown controller '" + f->controller +
                                   "' (paper, lee, all)");
  }
  const std::string map_path = f->map_path;
  const dataset::FlightTaskResolver resolve = [map_path](const std::string& name) {
    return sim::BuiltinFlightTask(name, map_path);
  };
  if (!f->task_file.empty()) {
    MAV_ASSIGN_OR_RETURN(dataset::FlightTask t,
                         dataset::ReadFlightTaskFile(f->task_file, resolve,
                                                     f->task == "all" ? std::string() : f->task));
    o.tasks.push_back(std::move(t));
  } else if (f->task == "all") {
    for (const std::string& n : sim::FlightTaskNames()) o.tasks.push_back(*resolve(n));
  } else {
    Result<dataset::FlightTask> t = resolve(f->task);
    if (!t.ok()) return Status(t.status().code(), "--" + t.status().message());
    o.tasks.push_back(*t);
  }
  if (!f->leg_limits.empty()) {
    double v[4];
    if (std::sscanf(f->leg_limits.c_str(), "%lf,%lf,%lf,%lf", &v[0], &v[1], &v[2], &v[3]) != 4) {
      return Status::InvalidArgument("--leg-limits: expected V,A,L,J, got '" + f->leg_limits + "'");
    }
    o.leg_limits = {v[0], v[1], v[2], v[3]};
  }
  if (!f->out_dir.empty()) o.roadmap_path = f->out_dir + "/roadmap.mavprm";
  return Status::Ok();
}

}  // namespace

int RunControl(const std::vector<std::string>& args) {
  ControlFlags f;
  FlagParser flags = MakeFlags(&f);
  bool help = false;
  if (Status s = flags.Parse(args, nullptr, &help); !s.ok()) return Fail(kCommand, s.message(), 2);
  if (help) {
    std::cout << flags.Help();
    return 0;
  }
  if (Status s = CompleteOptions(&f); !s.ok()) return Fail(kCommand, s.message(), 2);
  // Made first so that the leg planner can save its roadmap there.
  if (!f.out_dir.empty()) {
    if (Status s = MakeDirectories(f.out_dir); !s.ok()) return Fail(kCommand, s.message());
  }

  Result<eval::ControlSummary> summary = eval::EvaluateControl(f.options);
  if (!summary.ok()) return Fail(kCommand, summary.status().message());
  for (const eval::ControlTaskResult& task : summary->tasks) {
    for (const eval::ControlRun& run : task.runs) {
      if (!run.status.ok()) std::cerr << kCommand << ": " << run.status.ToString() << "\n";
    }
    if (f.out_dir.empty()) continue;
    if (Status s = WriteTaskFiles(f.out_dir, task); !s.ok()) return Fail(kCommand, s.message());
  }
  if (Status s = PrintReport(eval::ControlReport(*summary), f.json_path); !s.ok()) {
    return Fail(kCommand, s.message());
  }
  return summary->failures > 0 ? 1 : 0;
}

}  // namespace mav::eval_cli
