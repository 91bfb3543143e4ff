// mav-eval planning: plans the same queries on one map with our roadmap planner and with the
// OMPL peers (a fresh PRM* or RRTConnect per query, the paper's 0.75 s budget, OMPL's
// simplifier), every method followed by the same speed plan and spline, and prints the figures
// of the paper's Section 3 (Holzmann et al. 2015) beside ours, with each path's length against
// a near-optimal reference (Lazy Theta* on the map's grid, pulled taut).

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "clients/plot/plot.h"
#include "commands.h"
#include "json.h"
#include "mav/common/file.h"
#include "mav/common/flags.h"
#include "mav/common/parse.h"
#include "mav/common/stats.h"
#include "mav/dataset/planning_queries.h"
#include "mav/planning/planner.h"
#include "mav/planning/planning_map.h"
#include "mav/planning/reference_path.h"
#include "paper.h"

namespace mav::eval_cli {
namespace {

using planning::PlanningMap;
using planning::PlanRequest;
using planning::PlanResult;
using planning::PlanStatus;

constexpr const char* kCommand = "mav-eval planning";

struct Query {
  std::string kind;                     // "t4_3", "blocked", "free" or "file:line"
  std::vector<Eigen::Vector3d> points;  // start, waypoints..., goal
  double reference_m = 0;               // 0: no reference (waypoints or not found)
};

// One method's outcome for one query.
struct Run {
  bool ok = false;
  std::string status;
  std::string message;
  double length_m = 0;             // shortened path
  double trajectory_length_m = 0;  // the spline's
  double planning_ms = 0;          // the whole query
  double duration_s = 0;
  double avg_speed_mps = 0;
  double peak_speed_mps = 0;
  double min_clearance_m = 0;  // re-checked here, exact, every <= 1 cm
  geometry::PolynomialTrajectory trajectory;
};

int Fail(const std::string& message, int code = 1) {
  std::cerr << kCommand << ": " << message << "\n";
  return code;
}

std::string Fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), format, v);
  return buf;
}

// The queries of a --queries file (format: mav/dataset/planning_queries.h).
Result<std::vector<Query>> ReadQueries(const std::string& path) {
  MAV_ASSIGN_OR_RETURN(const std::vector<dataset::PlanningQuery> read,
                       dataset::ReadPlanningQueries(path));
  std::vector<Query> out;
  out.reserve(read.size());
  for (const dataset::PlanningQuery& q : read) out.push_back({q.where, q.points, 0});
  return out;
}

// The exact clearance every <= 1 cm of the trajectory (the speed changes < 0.5 m/s per step).
double MinClearance(const PlanningMap& map, const geometry::PolynomialTrajectory& t) {
  double worst = 1e9;
  for (double s = 0; s <= t.duration_s();) {
    const Eigen::Vector3d p = t.EvaluateDerivative(s, 0);
    if (map.ClearanceLowerBound(p) < worst) worst = std::min(worst, map.ClearanceUpTo(p, worst));
    s += 0.01 / (t.EvaluateDerivative(s, 1).norm() + 0.5);
  }
  return std::min(worst, map.ClearanceUpTo(t.EvaluateDerivative(t.duration_s(), 0), worst));
}

Run ToRun(const PlanningMap& map, const Result<PlanResult>& r) {
  Run run;
  if (!r.ok()) {
    run.status = StatusCodeName(r.status().code());
    run.message = r.status().message();
    return run;
  }
  run.status = planning::PlanStatusName(r->status);
  run.message = r->message;
  run.planning_ms = r->timings.total_ms;
  run.length_m = r->shortened_cost.length_m;
  if (!r->ok()) return run;
  run.ok = true;
  run.trajectory = r->trajectory;
  run.trajectory_length_m = r->trajectory_length_m;
  run.duration_s = r->duration_s;
  run.avg_speed_mps = r->mean_speed_mps;
  run.peak_speed_mps = r->max_speed_mps;
  run.min_clearance_m = MinClearance(map, r->trajectory);
  return run;
}

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

struct Summary {
  int ok = 0, queries = 0, violations = 0;
  RuntimeStats planning;
  double mean_ratio = 0, max_ratio = 0;
  int ratios = 0;
  // The 35 m legs: queries whose reference is 32-38 m long.
  int legs35 = 0;
  double legs35_duration_s = 0, legs35_max_duration_s = 0, legs35_avg_speed = 0, legs35_peak = 0;
  double mean_duration_s = 0, mean_avg_speed = 0, peak_speed = 0, min_clearance = 1e9;
  double mean_length_m = 0;
};

Summary Summarize(const std::vector<Query>& queries, const std::vector<Run>& runs, double radius) {
  Summary s;
  s.queries = static_cast<int>(runs.size());
  std::vector<double> ms;
  for (size_t i = 0; i < runs.size(); ++i) {
    const Run& r = runs[i];
    ms.push_back(r.planning_ms);
    if (!r.ok) continue;
    ++s.ok;
    s.violations += r.min_clearance_m < radius;
    s.min_clearance = std::min(s.min_clearance, r.min_clearance_m);
    s.mean_duration_s += r.duration_s;
    s.mean_avg_speed += r.avg_speed_mps;
    s.mean_length_m += r.trajectory_length_m;
    s.peak_speed = std::max(s.peak_speed, r.peak_speed_mps);
    const double ref = queries[i].reference_m;
    if (ref > 0) {
      const double ratio = r.trajectory_length_m / ref;
      s.mean_ratio += ratio;
      s.max_ratio = std::max(s.max_ratio, ratio);
      ++s.ratios;
      if (ref >= 32 && ref <= 38) {
        ++s.legs35;
        s.legs35_duration_s += r.duration_s;
        s.legs35_max_duration_s = std::max(s.legs35_max_duration_s, r.duration_s);
        s.legs35_avg_speed += r.avg_speed_mps;
        s.legs35_peak = std::max(s.legs35_peak, r.peak_speed_mps);
      }
    }
  }
  s.planning = SummarizeRuntimes(ms);
  if (s.ok > 0) {
    s.mean_duration_s /= s.ok;
    s.mean_avg_speed /= s.ok;
    s.mean_length_m /= s.ok;
  }
  if (s.ratios > 0) s.mean_ratio /= s.ratios;
  if (s.legs35 > 0) {
    s.legs35_duration_s /= s.legs35;
    s.legs35_avg_speed /= s.legs35;
  }
  return s;
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
  std::vector<std::string> methods;
  for (std::string_view m : SplitFields(methods_text, ',')) {
    const std::string name(Trim(m));
    if (name != "roadmap" && name != "ompl-prmstar" && name != "ompl-rrtconnect") {
      return Fail("--methods: unknown method '" + name +
                      "' (known: roadmap, ompl-prmstar, ompl-rrtconnect)",
                  2);
    }
    methods.push_back(name);
  }

  std::vector<Query> queries;
  if (!queries_path.empty()) {
    auto read = ReadQueries(queries_path);
    if (!read.ok()) return Fail(read.status().message());
    queries = *read;
  }
  planning::MapOptions map_options;
  map_options.robot_radius_m = robot_radius;
  auto loaded_map = PlanningMap::LoadFile(map_path, map_options);
  if (!loaded_map.ok()) return Fail(loaded_map.status().message());
  const PlanningMap& map = **loaded_map;
  const planning::MapInfo& info = map.info();
  std::cout << "map " << map_path << ": " << info.resolution_m << " m, grid "
            << map.grid_size().transpose() << " (" << info.memory.bytes / 1000000 << " MB), load "
            << Fmt("%.0f", info.load_ms) << " ms + distance map "
            << Fmt("%.0f", info.distance_map_ms) << " ms\n";

  if (queries.empty()) {
    const std::vector<Eigen::Vector3d> t43 = {{2, -27, 15}, {20, -15, 15}, {25, 0, 5}, {0, 0, 1}};
    for (size_t i = 0; i + 1 < t43.size(); ++i)
      queries.push_back({"t4_3", {t43[i], t43[i + 1]}, 0});
    planning::RandomQueryOptions options;
    options.seed = static_cast<uint64_t>(seed);
    options.blocked = static_cast<int>(blocked);
    options.free = static_cast<int>(free);
    auto random = planning::RandomQueries(map, options);
    if (!random.ok()) return Fail(random.status().message());
    for (const planning::EvaluationQuery& q : *random) {
      queries.push_back(
          {q.straight_line_free ? "free" : "blocked", {q.start, q.goal}, q.reference_length_m});
    }
  }
  // The near-optimal reference of every start-goal query that does not have one yet.
  for (Query& q : queries) {
    if (q.reference_m > 0 || q.points.size() != 2) continue;
    auto reference = planning::ShortestReferencePath(map, q.points[0], q.points[1]);
    if (reference.ok() && reference->found) q.reference_m = reference->length_m;
  }
  std::cout << queries.size() << " queries\n";

  std::shared_ptr<const planning::Roadmap> roadmap;
  if (std::find(methods.begin(), methods.end(), "roadmap") != methods.end()) {
    if (!roadmap_path.empty() && PathExists(roadmap_path)) {
      auto r = planning::Roadmap::Load(roadmap_path, map);
      if (!r.ok()) return Fail(r.status().message());
      roadmap = *r;
      std::cout << "roadmap " << roadmap_path << ": loaded in "
                << Fmt("%.0f", roadmap->info().load_ms) << " ms";
    } else {
      planning::RoadmapOptions options;
      options.seed = static_cast<uint64_t>(seed);
      auto r = planning::Roadmap::Build(map, options);
      if (!r.ok()) return Fail(r.status().message());
      roadmap = *r;
      std::cout << "roadmap built in " << Fmt("%.1f", roadmap->info().build_s) << " s";
      if (!roadmap_path.empty()) {
        if (Status s = roadmap->Save(roadmap_path); !s.ok()) return Fail(s.message());
        std::cout << ", saved to " << roadmap_path;
      }
    }
    std::cout << ": " << roadmap->info().milestones << " milestones, " << roadmap->info().edges
              << " edges (" << roadmap->info().memory_bytes / 1000000 << " MB)\n";
  }

  std::map<std::string, std::vector<Run>> runs;
  for (const std::string& method : methods) {
    for (const Query& q : queries) {
      PlanRequest request;
      request.start = q.points.front();
      request.goal = q.points.back();
      request.waypoints.assign(q.points.begin() + 1, q.points.end() - 1);
      request.seed = static_cast<uint64_t>(seed);
      if (method == "roadmap") {
        runs[method].push_back(ToRun(map, planning::PlanPath(map, roadmap.get(), request)));
      } else {
        planning::OmplPeerOptions options;
        options.planner = method == "ompl-prmstar" ? planning::OmplPlanner::kPrmStar
                                                   : planning::OmplPlanner::kRrtConnect;
        options.time_budget_s = budget_s;
        options.seed = static_cast<uint64_t>(seed);
        runs[method].push_back(ToRun(map, planning::PlanWithOmpl(map, request, options)));
      }
    }
  }

  // Per query: the reference and every method's length ratio and flight time.
  std::printf("\n%-4s %-8s %7s", "#", "kind", "ref m");
  for (const std::string& m : methods)
    std::printf(" | %-16s %6s %7s %6s", m.c_str(), "ratio", "plan ms", "fly s");
  std::printf("\n");
  for (size_t i = 0; i < queries.size(); ++i) {
    const std::string kind = queries[i].kind.size() > 8 ? "file" : queries[i].kind;
    std::printf("%-4zu %-8s %7.2f", i, kind.c_str(), queries[i].reference_m);
    for (const std::string& m : methods) {
      const Run& r = runs[m][i];
      const double ratio =
          r.ok && queries[i].reference_m > 0 ? r.trajectory_length_m / queries[i].reference_m : NAN;
      std::printf(" | %-16s %6.3f %7.1f %6.2f", r.status.c_str(), ratio, r.planning_ms,
                  r.duration_s);
    }
    std::printf("\n");
  }

  const PaperControlFigures& paper = PaperControl();
  std::printf("\n%-16s %7s %9s %9s %8s %8s %7s | %-38s | %9s %5s\n", "method", "success",
              "plan med", "plan p99", "ratio", "max", "fly s",
              "35 m legs: n, fly s (max), avg, peak", "min clr m", "viol");
  std::printf(
      "%-16s %7s %7.0fms %9s %8s %8s %7s |  -, %.2f-%.2f s, %.1f, %.2f m/s %10s | %9s %5s\n",
      "paper (Sec. 3)", "-", 1000 * paper.plan_time_s, "-", "-", "-", "-",
      paper.leg_flight_time_min_s, paper.leg_flight_time_max_s, paper.leg_mean_speed_mps,
      paper.leg_peak_speed_mps, "", "-", "-");
  JsonReport json;
  for (const std::string& m : methods) {
    const Summary s = Summarize(queries, runs[m], robot_radius);
    std::printf(
        "%-16s %3d/%-3d %7.1fms %7.1fms %8.4f %8.4f %7.2f | %2d, %.2f s (%.2f), %.1f, %.2f m/s"
        "        | %9.3f %5d\n",
        m.c_str(), s.ok, s.queries, s.planning.median_ms, s.planning.p99_ms, s.mean_ratio,
        s.max_ratio, s.mean_duration_s, s.legs35, s.legs35_duration_s, s.legs35_max_duration_s,
        s.legs35_avg_speed, s.legs35_peak, s.ok > 0 ? s.min_clearance : NAN, s.violations);
    std::vector<JsonReport::Record> records;
    for (size_t i = 0; i < queries.size(); ++i) {
      const Run& r = runs[m][i];
      records.push_back({{"status", r.status},
                         {"length_m", r.length_m},
                         {"trajectory_length_m", r.trajectory_length_m},
                         {"planning_ms", r.planning_ms},
                         {"duration_s", r.duration_s},
                         {"avg_speed_mps", r.avg_speed_mps},
                         {"peak_speed_mps", r.peak_speed_mps},
                         {"min_clearance_m", r.min_clearance_m},
                         {"reference_length_m", queries[i].reference_m},
                         {"kind", queries[i].kind}});
    }
    json.Set(m, "queries", records);
    json.Set(m, "success", static_cast<double>(s.ok));
    json.Set(m, "count", static_cast<double>(s.queries));
    json.Set(m, "planning_median_ms", s.planning.median_ms);
    json.Set(m, "planning_p99_ms", s.planning.p99_ms);
    json.Set(m, "planning_max_ms", s.planning.max_ms);
    json.Set(m, "length_ratio_mean", s.mean_ratio);
    json.Set(m, "length_ratio_max", s.max_ratio);
    json.Set(m, "trajectory_length_mean_m", s.mean_length_m);
    json.Set(m, "duration_mean_s", s.mean_duration_s);
    json.Set(m, "avg_speed_mean_mps", s.mean_avg_speed);
    json.Set(m, "peak_speed_mps", s.peak_speed);
    json.Set(m, "legs35", static_cast<double>(s.legs35));
    json.Set(m, "legs35_duration_mean_s", s.legs35_duration_s);
    json.Set(m, "legs35_duration_max_s", s.legs35_max_duration_s);
    json.Set(m, "min_clearance_m", s.ok > 0 ? s.min_clearance : NAN);
    json.Set(m, "clearance_violations", static_cast<double>(s.violations));
  }
  json.Set("paper", "path_m", paper.leg_length_m);
  json.Set("paper", "planning_ms", 1000 * paper.plan_time_s);
  json.Set("paper", "flight_min_s", paper.leg_flight_time_min_s);
  json.Set("paper", "flight_max_s", paper.leg_flight_time_max_s);
  json.Set("paper", "avg_speed_mps", paper.leg_mean_speed_mps);
  json.Set("paper", "peak_speed_mps", paper.leg_peak_speed_mps);
  if (roadmap) {
    json.Set("roadmap_build", "milestones", static_cast<double>(roadmap->info().milestones));
    json.Set("roadmap_build", "edges", static_cast<double>(roadmap->info().edges));
    json.Set("roadmap_build", "build_s", roadmap->info().build_s);
    json.Set("roadmap_build", "load_ms", roadmap->info().load_ms);
  }

  if (!out_dir.empty()) {
    static const int kColours[3][3] = {{0, 0, 220}, {0, 150, 0}, {200, 100, 0}};
    std::vector<plot::PlotSeries> series;
    for (size_t k = 0; k < methods.size(); ++k) {
      const std::string dir = out_dir + "/" + methods[k];
      if (Status s = MakeDirectories(dir); !s.ok()) return Fail(s.message());
      bool labelled = false;
      for (size_t i = 0; i < queries.size(); ++i) {
        const Run& r = runs[methods[k]][i];
        if (!r.ok) continue;
        if (Status s = WriteCsv(dir + "/query_" + std::to_string(i) + ".csv", r.trajectory);
            !s.ok()) {
          return Fail(s.message());
        }
        plot::PlotSeries line;
        line.label = labelled ? "" : methods[k];
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
    const plot::TopViewHeightMap height = plot::HeightMapOf(map);
    if (Status s = plot::WriteTopViewPlot(out_dir + "/top_view.png",
                                          "planning on " + map_path + " (obstacles by height)",
                                          series, &height);
        !s.ok()) {
      return Fail(s.message());
    }
  }
  if (!json_path.empty()) {
    if (Status s = json.WriteFile(json_path); !s.ok()) return Fail(s.message());
  }
  return 0;
}

}  // namespace mav::eval_cli
