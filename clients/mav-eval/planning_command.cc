// mav-eval planning: plans the same queries on one map with our roadmap planner and with the
// OMPL peers (a fresh PRM* or RRTConnect per query, the paper's 0.75 s budget, OMPL's
// simplifier), every method followed by the same speed plan and spline, and prints the figures
// of the paper's Section 3 (Holzmann et al. 2015) beside ours, with each path's length against
// a near-optimal reference (mav/eval/planning_eval.h).

#include <cstdio>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "clients/plot/plot.h"
#include "commands.h"
#include "mav/common/file.h"
#include "mav/common/flags.h"
#include "mav/common/parse.h"
#include "mav/eval/planning_eval.h"
#include "output.h"

namespace mav::eval_cli {
namespace {

constexpr const char* kCommand = "mav-eval planning";

int Fail(const std::string& message, int code = 1) {
  return eval_cli::Fail(kCommand, message, code);
}

std::string Fmt(const char* format, double v) { return eval::FormatLine(format, v); }

Status WriteCsv(const std::string& path, const geometry::PolynomialTrajectory& t) {
  std::ostringstream out;
  out << "t,x,y,z,vx,vy,vz,ax,ay,az,yaw\n";
  char buf[256];
  for (const geometry::TrajectoryPoint& p : t.Sample(0.01)) {
    std::snprintf(buf, sizeof(buf), "%.3f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f\n",
                  p.t_s, p.position.x(), p.position.y(), p.position.z(), p.velocity.x(),
                  p.velocity.y(), p.velocity.z(), p.acceleration.x(), p.acceleration.y(),
                  p.acceleration.z(), p.yaw_rad);
    out << buf;
  }
  return WriteStringToFileAtomic(path, out.str());
}

// DIR/<method>/query_<i>.csv of every planned query and DIR/top_view.png.
Status WriteFiles(const std::string& out_dir, const eval::PlanningSummary& s) {
  static const int kColours[3][3] = {{0, 0, 220}, {0, 150, 0}, {200, 100, 0}};
  std::vector<plot::PlotSeries> series;
  for (size_t k = 0; k < s.methods.size(); ++k) {
    const eval::PlanningMethodResult& m = s.methods[k];
    const std::string dir = out_dir + "/" + m.method;
    MAV_RETURN_IF_ERROR(MakeDirectories(dir));
    bool labelled = false;
    for (size_t i = 0; i < m.runs.size(); ++i) {
      const eval::PlanningRun& r = m.runs[i];
      if (!r.ok) continue;
      MAV_RETURN_IF_ERROR(WriteCsv(dir + "/query_" + std::to_string(i) + ".csv", r.trajectory));
      plot::PlotSeries line;
      line.label = labelled ? "" : m.method;
      labelled = true;
      for (const geometry::TrajectoryPoint& p : r.trajectory.Sample(0.05)) {
        line.positions.push_back(p.position);
      }
      line.b = kColours[k % 3][0];
      line.g = kColours[k % 3][1];
      line.r = kColours[k % 3][2];
      series.push_back(std::move(line));
    }
  }
  const plot::TopViewHeightMap height = plot::HeightMapOf(*s.map);
  return plot::WriteTopViewPlot(out_dir + "/top_view.png",
                                "planning on " + s.map_path + " (obstacles by height)", series,
                                &height);
}

}  // namespace

int RunPlanning(const std::vector<std::string>& args) {
  std::string map_path, queries_path, out_dir, json_path, roadmap_path;
  std::string methods_text = "roadmap,ompl-prmstar,ompl-rrtconnect";
  double robot_radius = 0.5, budget_s = 0.75;
  int64_t seed = 1, blocked = 15, free = 15;
  FlagParser flags(
      "mav-eval planning --map FILE.bt [--queries FILE] [--robot-radius M] [--seed S] "
      "[--out DIR] [--json FILE]");
  flags.AddString("map", &map_path, "OctoMap binary (.bt) to plan in");
  flags.AddString("queries", &queries_path,
                  "one query a line: sx sy sz gx gy gz (more triples: waypoints between), "
                  "# comments; default: the contest's t4_3 legs plus random 20-40 m queries");
  flags.AddDouble("robot-radius", &robot_radius, "robot radius, m");
  flags.AddInt64("seed", &seed, "seed of the roadmap, the peers and the random queries");
  flags.AddString("out", &out_dir,
                  "write DIR/<method>/query_<i>.csv (every 0.01 s) and DIR/top_view.png");
  flags.AddString("json", &json_path, "write {method: {queries: [...], summary figures}}");
  flags.AddString("roadmap", &roadmap_path,
                  "roadmap file: loaded when it exists (and belongs to the map), else built "
                  "and saved there");
  flags.AddString("methods", &methods_text,
                  "comma-separated: roadmap, ompl-prmstar, ompl-rrtconnect");
  flags.AddDouble("budget-s", &budget_s, "time per query of the OMPL peers, s (the paper's 0.75)");
  flags.AddInt64("blocked", &blocked, "random queries whose straight line is blocked");
  flags.AddInt64("free", &free, "random queries whose straight line is free");
  std::vector<std::string> positional;
  bool help = false;
  if (Status s = flags.Parse(args, &positional, &help); !s.ok()) return Fail(s.message(), 2);
  if (help) {
    std::cout << flags.Help();
    return 0;
  }
  if (map_path.empty() || !positional.empty()) {
    std::cerr << kCommand << ": --map FILE.bt is required\n" << flags.Help();
    return 2;
  }
  if (!(robot_radius > 0 && robot_radius <= 10)) {
    return Fail("--robot-radius: must be in (0, 10] m, got " + Fmt("%g", robot_radius), 2);
  }
  if (!(budget_s > 0 && budget_s <= 600)) {
    return Fail("--budget-s: must be in (0, 600] s, got " + Fmt("%g", budget_s), 2);
  }
  if (seed < 0) return Fail("--seed: must be >= 0", 2);
  if (blocked < 0 || free < 0) return Fail("--blocked and --free: must be >= 0", 2);
  eval::PlanningEvalOptions options;
  options.methods.clear();
  for (std::string_view m : SplitFields(methods_text, ',')) {
    const std::string name(Trim(m));
    if (name != "roadmap" && name != "ompl-prmstar" && name != "ompl-rrtconnect") {
      return Fail("--methods: unknown method '" + name +
                      "' (known: roadmap, ompl-prmstar, ompl-rrtconnect)",
                  2);
    }
    options.methods.push_back(name);
  }

  options.map_path = map_path;
  options.queries_path = queries_path;
  options.robot_radius_m = robot_radius;
  options.budget_s = budget_s;
  options.seed = static_cast<uint64_t>(seed);
  options.blocked = static_cast<int>(blocked);
  options.free = static_cast<int>(free);
  options.roadmap_path = roadmap_path;

  Result<eval::PlanningSummary> summary = eval::EvaluatePlanning(options);
  if (!summary.ok()) return Fail(summary.status().message());
  if (Status s = PrintReport(eval::PlanningReport(*summary), json_path); !s.ok()) {
    return Fail(s.message());
  }
  if (!out_dir.empty()) {
    if (Status s = WriteFiles(out_dir, *summary); !s.ok()) return Fail(s.message());
  }
  return 0;
}

}  // namespace mav::eval_cli
