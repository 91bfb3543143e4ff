#include "mav/eval/planning_eval.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <utility>

#include "mav/common/file.h"
#include "mav/dataset/planning_queries.h"
#include "mav/eval/paper_figures.h"
#include "mav/planning/planner.h"
#include "mav/planning/reference_path.h"

namespace mav::eval {
namespace {

using planning::PlanningMap;
using planning::PlanResult;

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

PlanningRun ToRun(const PlanningMap& map, const Result<PlanResult>& r) {
  PlanningRun run;
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

PlanningMethodStats Summarize(const std::vector<PlanningEvalQuery>& queries,
                              const std::vector<PlanningRun>& runs, double radius) {
  PlanningMethodStats s;
  s.queries = static_cast<int>(runs.size());
  std::vector<double> ms;
  for (size_t i = 0; i < runs.size(); ++i) {
    const PlanningRun& r = runs[i];
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
    if (ref <= 0) continue;
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

// The queries of the file, or the contest's t4_3 legs and random ones; then the near-optimal
// reference of every start-goal query that does not have one yet.
Result<std::vector<PlanningEvalQuery>> MakeQueries(const PlanningEvalOptions& options,
                                                   const PlanningMap& map) {
  std::vector<PlanningEvalQuery> queries;
  if (!options.queries_path.empty()) {
    MAV_ASSIGN_OR_RETURN(const std::vector<dataset::PlanningQuery> read,
                         dataset::ReadPlanningQueries(options.queries_path));
    for (const dataset::PlanningQuery& q : read) queries.push_back({q.where, q.points, 0});
  }
  if (queries.empty()) {
    const std::vector<Eigen::Vector3d> t43 = {{2, -27, 15}, {20, -15, 15}, {25, 0, 5}, {0, 0, 1}};
    for (size_t i = 0; i + 1 < t43.size(); ++i) {
      queries.push_back({"t4_3", {t43[i], t43[i + 1]}, 0});
    }
    planning::RandomQueryOptions random_options;
    random_options.seed = options.seed;
    random_options.blocked = options.blocked;
    random_options.free = options.free;
    MAV_ASSIGN_OR_RETURN(const std::vector<planning::EvaluationQuery> random,
                         planning::RandomQueries(map, random_options));
    for (const planning::EvaluationQuery& q : random) {
      queries.push_back(
          {q.straight_line_free ? "free" : "blocked", {q.start, q.goal}, q.reference_length_m});
    }
  }
  for (PlanningEvalQuery& q : queries) {
    if (q.reference_m > 0 || q.points.size() != 2) continue;
    auto reference = planning::ShortestReferencePath(map, q.points[0], q.points[1]);
    if (reference.ok() && reference->found) q.reference_m = reference->length_m;
  }
  return queries;
}

Status LoadOrBuildRoadmap(const PlanningEvalOptions& options, PlanningSummary* s) {
  std::ostringstream line;
  const std::string& path = options.roadmap_path;
  if (!path.empty() && PathExists(path)) {
    MAV_ASSIGN_OR_RETURN(s->roadmap, planning::Roadmap::Load(path, *s->map));
    line << "roadmap " << path << ": loaded in " << FormatLine("%.0f", s->roadmap->info().load_ms)
         << " ms";
  } else {
    planning::RoadmapOptions roadmap_options;
    roadmap_options.seed = options.seed;
    MAV_ASSIGN_OR_RETURN(s->roadmap, planning::Roadmap::Build(*s->map, roadmap_options));
    line << "roadmap built in " << FormatLine("%.1f", s->roadmap->info().build_s) << " s";
    if (!path.empty()) {
      MAV_RETURN_IF_ERROR(s->roadmap->Save(path));
      line << ", saved to " << path;
    }
  }
  const planning::RoadmapInfo& info = s->roadmap->info();
  line << ": " << info.milestones << " milestones, " << info.edges << " edges ("
       << info.memory_bytes / 1000000 << " MB)";
  s->setup_log.push_back(line.str());
  return Status::Ok();
}

PlanningRun PlanOne(const PlanningEvalOptions& options, const PlanningSummary& s,
                    const std::string& method, const PlanningEvalQuery& q) {
  planning::PlanRequest request;
  request.start = q.points.front();
  request.goal = q.points.back();
  request.waypoints.assign(q.points.begin() + 1, q.points.end() - 1);
  request.seed = options.seed;
  if (method == "roadmap")
    return ToRun(*s.map, planning::PlanPath(*s.map, s.roadmap.get(), request));
  planning::OmplPeerOptions peer;
  peer.planner = method == "ompl-prmstar" ? planning::OmplPlanner::kPrmStar
                                          : planning::OmplPlanner::kRrtConnect;
  peer.time_budget_s = options.budget_s;
  peer.seed = options.seed;
  return ToRun(*s.map, planning::PlanWithOmpl(*s.map, request, peer));
}

void AddQueryTable(const PlanningSummary& s, Report* report) {
  ReportTable& t = report->AddTable();
  std::string header = FormatLine("%-4s %-8s %7s", "#", "kind", "ref m");
  for (const PlanningMethodResult& m : s.methods) {
    header += FormatLine(" | %-16s %6s %7s %6s", m.method.c_str(), "ratio", "plan ms", "fly s");
  }
  t.header.push_back(header);
  for (size_t i = 0; i < s.queries.size(); ++i) {
    const PlanningEvalQuery& q = s.queries[i];
    const std::string kind = q.kind.size() > 8 ? "file" : q.kind;
    std::string row = FormatLine("%-4zu %-8s %7.2f", i, kind.c_str(), q.reference_m);
    for (const PlanningMethodResult& m : s.methods) {
      const PlanningRun& r = m.runs[i];
      const double ratio = r.ok && q.reference_m > 0 ? r.trajectory_length_m / q.reference_m : NAN;
      row += FormatLine(" | %-16s %6.3f %7.1f %6.2f", r.status.c_str(), ratio, r.planning_ms,
                        r.duration_s);
    }
    t.rows.push_back(row);
  }
}

void AddSummaryTable(const PlanningSummary& s, Report* report) {
  const PaperControlFigures& paper = PaperControl();
  ReportTable& t = report->AddTable();
  t.header.push_back(FormatLine("%-16s %7s %9s %9s %8s %8s %7s | %-38s | %9s %5s", "method",
                                "success", "plan med", "plan p99", "ratio", "max", "fly s",
                                "35 m legs: n, fly s (max), avg, peak", "min clr m", "viol"));
  t.rows.push_back(FormatLine(
      "%-16s %7s %7.0fms %9s %8s %8s %7s |  -, %.2f-%.2f s, %.1f, %.2f m/s %10s | %9s %5s",
      "paper (Sec. 3)", "-", 1000 * paper.plan_time_s, "-", "-", "-", "-",
      paper.leg_flight_time_min_s, paper.leg_flight_time_max_s, paper.leg_mean_speed_mps,
      paper.leg_peak_speed_mps, "", "-", "-"));
  for (const PlanningMethodResult& m : s.methods) {
    const PlanningMethodStats& st = m.stats;
    t.rows.push_back(FormatLine(
        "%-16s %3d/%-3d %7.1fms %7.1fms %8.4f %8.4f %7.2f | %2d, %.2f s (%.2f), %.1f, %.2f m/s"
        "        | %9.3f %5d",
        m.method.c_str(), st.ok, st.queries, st.planning.median_ms, st.planning.p99_ms,
        st.mean_ratio, st.max_ratio, st.mean_duration_s, st.legs35, st.legs35_duration_s,
        st.legs35_max_duration_s, st.legs35_avg_speed, st.legs35_peak,
        st.ok > 0 ? st.min_clearance : NAN, st.violations));
  }
}

void SetMethodJson(const PlanningSummary& s, const PlanningMethodResult& m, JsonReport* json) {
  std::vector<JsonReport::Record> records;
  for (size_t i = 0; i < s.queries.size(); ++i) {
    const PlanningRun& r = m.runs[i];
    records.push_back({{"status", r.status},
                       {"length_m", r.length_m},
                       {"trajectory_length_m", r.trajectory_length_m},
                       {"planning_ms", r.planning_ms},
                       {"duration_s", r.duration_s},
                       {"avg_speed_mps", r.avg_speed_mps},
                       {"peak_speed_mps", r.peak_speed_mps},
                       {"min_clearance_m", r.min_clearance_m},
                       {"reference_length_m", s.queries[i].reference_m},
                       {"kind", s.queries[i].kind}});
  }
  const PlanningMethodStats& st = m.stats;
  const std::string& g = m.method;
  json->Set(g, "queries", records);
  json->Set(g, "success", static_cast<double>(st.ok));
  json->Set(g, "count", static_cast<double>(st.queries));
  json->Set(g, "planning_median_ms", st.planning.median_ms);
  json->Set(g, "planning_p99_ms", st.planning.p99_ms);
  json->Set(g, "planning_max_ms", st.planning.max_ms);
  json->Set(g, "length_ratio_mean", st.mean_ratio);
  json->Set(g, "length_ratio_max", st.max_ratio);
  json->Set(g, "trajectory_length_mean_m", st.mean_length_m);
  json->Set(g, "duration_mean_s", st.mean_duration_s);
  json->Set(g, "avg_speed_mean_mps", st.mean_avg_speed);
  json->Set(g, "peak_speed_mps", st.peak_speed);
  json->Set(g, "legs35", static_cast<double>(st.legs35));
  json->Set(g, "legs35_duration_mean_s", st.legs35_duration_s);
  json->Set(g, "legs35_duration_max_s", st.legs35_max_duration_s);
  json->Set(g, "min_clearance_m", st.ok > 0 ? st.min_clearance : NAN);
  json->Set(g, "clearance_violations", static_cast<double>(st.violations));
}

void SetJson(const PlanningSummary& s, JsonReport* json) {
  for (const PlanningMethodResult& m : s.methods) SetMethodJson(s, m, json);
  const PaperControlFigures& paper = PaperControl();
  json->Set("paper", "path_m", paper.leg_length_m);
  json->Set("paper", "planning_ms", 1000 * paper.plan_time_s);
  json->Set("paper", "flight_min_s", paper.leg_flight_time_min_s);
  json->Set("paper", "flight_max_s", paper.leg_flight_time_max_s);
  json->Set("paper", "avg_speed_mps", paper.leg_mean_speed_mps);
  json->Set("paper", "peak_speed_mps", paper.leg_peak_speed_mps);
  if (s.roadmap) {
    const planning::RoadmapInfo& info = s.roadmap->info();
    json->Set("roadmap_build", "milestones", static_cast<double>(info.milestones));
    json->Set("roadmap_build", "edges", static_cast<double>(info.edges));
    json->Set("roadmap_build", "build_s", info.build_s);
    json->Set("roadmap_build", "load_ms", info.load_ms);
  }
}

}  // namespace

Result<PlanningSummary> EvaluatePlanning(const PlanningEvalOptions& options) {
  for (const std::string& m : options.methods) {
    if (m != "roadmap" && m != "ompl-prmstar" && m != "ompl-rrtconnect") {
      return Status::InvalidArgument("methods: unknown method '" + m +
                                     "' (known: roadmap, ompl-prmstar, ompl-rrtconnect)");
    }
  }
  PlanningSummary s;
  s.map_path = options.map_path;
  s.robot_radius_m = options.robot_radius_m;
  planning::MapOptions map_options;
  map_options.robot_radius_m = options.robot_radius_m;
  MAV_ASSIGN_OR_RETURN(s.map, PlanningMap::LoadFile(options.map_path, map_options));
  const planning::MapInfo& info = s.map->info();
  std::ostringstream map_line;
  map_line << "map " << options.map_path << ": " << info.resolution_m << " m, grid "
           << s.map->grid_size().transpose() << " (" << info.memory.bytes / 1000000 << " MB), load "
           << FormatLine("%.0f", info.load_ms) << " ms + distance map "
           << FormatLine("%.0f", info.distance_map_ms) << " ms";
  s.setup_log.push_back(map_line.str());
  MAV_ASSIGN_OR_RETURN(s.queries, MakeQueries(options, *s.map));
  s.setup_log.push_back(std::to_string(s.queries.size()) + " queries");
  if (std::find(options.methods.begin(), options.methods.end(), "roadmap") !=
      options.methods.end()) {
    MAV_RETURN_IF_ERROR(LoadOrBuildRoadmap(options, &s));
  }
  for (const std::string& method : options.methods) {
    PlanningMethodResult& m = s.methods.emplace_back();
    m.method = method;
    for (const PlanningEvalQuery& q : s.queries) m.runs.push_back(PlanOne(options, s, method, q));
    m.stats = Summarize(s.queries, m.runs, options.robot_radius_m);
  }
  return s;
}

Report PlanningReport(const PlanningSummary& s) {
  Report report;
  report.AddTable("", /*blank_line_before=*/false).notes = s.setup_log;
  AddQueryTable(s, &report);
  AddSummaryTable(s, &report);
  SetJson(s, &report.json);
  return report;
}

}  // namespace mav::eval
