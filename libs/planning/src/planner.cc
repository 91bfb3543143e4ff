#include "mav/planning/planner.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>
#include <sstream>

#include "mav/common/time.h"
#include "pipeline.h"

namespace mav::planning {
namespace {

std::string Point(const Eigen::Vector3d& p) {
  std::ostringstream s;
  s << "(" << p.x() << ", " << p.y() << ", " << p.z() << ")";
  return s.str();
}

// Why p is not a valid state, or "" when it is.
std::string WhyInvalid(const ClearanceMap& map, const Eigen::Vector3d& p) {
  std::ostringstream s;
  const Box& b = map.bounds();
  if (!b.Contains(p)) {
    s << Point(p) << " is outside the planning volume " << Point(b.min) << " .. " << Point(b.max);
  } else if (!map.HasClearance(p, map.robot_radius())) {
    s << Point(p) << " is " << map.Clearance(p)
      << " m from the nearest obstacle, closer than the robot radius " << map.robot_radius()
      << " m";
  }
  return s.str();
}

struct Connection {
  uint32_t milestone;
  double cost;
};

// A* over the roadmap plus the leg's two ends (nodes M and M + 1).
Result<internal::LegOutcome> RoadmapLeg(const ClearanceMap& map, const Roadmap& roadmap,
                                        const PlanRequest& request, const Eigen::Vector3d& a,
                                        const Eigen::Vector3d& b, const Termination& stop) {
  internal::LegOutcome out;
  int64_t t0 = MonotonicNowNs();
  const CostWeights& w = request.weights;
  const double preferred = map.robot_radius() + roadmap.info().clearance_margin_m;
  const double tolerance = roadmap.info().validity_resolution_m;
  const double clear_a = internal::ConnectionClearance(map, a, preferred);
  const double clear_b = internal::ConnectionClearance(map, b, preferred);

  // Connections, widening the candidate set when none is found.
  std::vector<Connection> from_a, to_b;
  size_t tried_a = 0, tried_b = 0;
  for (size_t k = request.connection_candidates; k <= roadmap.num_milestones() * 2 + 1; k *= 8) {
    if (from_a.empty()) {
      const std::vector<uint32_t> near = roadmap.Nearest(a, k);
      for (size_t i = tried_a; i < near.size(); ++i) {
        const Eigen::Vector3d& m = roadmap.milestone(near[i]);
        if (map.IsSegmentValid(a, m, clear_a, tolerance)) {
          from_a.push_back({near[i], SegmentCost(map, w, a, m)});
        }
      }
      tried_a = near.size();
    }
    if (to_b.empty()) {
      const std::vector<uint32_t> near = roadmap.Nearest(b, k);
      for (size_t i = tried_b; i < near.size(); ++i) {
        const Eigen::Vector3d& m = roadmap.milestone(near[i]);
        if (map.IsSegmentValid(m, b, clear_b, tolerance)) {
          to_b.push_back({near[i], SegmentCost(map, w, m, b)});
        }
      }
      tried_b = near.size();
    }
    if ((!from_a.empty() && !to_b.empty()) || k >= roadmap.num_milestones()) break;
    if (stop.ShouldStop()) break;
  }
  MAV_RETURN_IF_ERROR(stop.Check("plan"));
  double direct = std::numeric_limits<double>::infinity();
  if (map.IsSegmentValid(a, b, std::min(clear_a, clear_b), tolerance)) {
    direct = SegmentCost(map, w, a, b);
  }
  std::sort(to_b.begin(), to_b.end(),
            [](const Connection& x, const Connection& y) { return x.milestone < y.milestone; });
  out.connect_ms = MsSince(t0);
  // Ends in different components and no direct segment: no search needed.
  bool joined = std::isfinite(direct);
  {
    std::vector<uint32_t> labels;
    labels.reserve(from_a.size());
    for (const Connection& c : from_a) labels.push_back(roadmap.component(c.milestone));
    std::sort(labels.begin(), labels.end());
    for (const Connection& c : to_b) {
      joined = joined ||
               std::binary_search(labels.begin(), labels.end(), roadmap.component(c.milestone));
    }
  }
  if (!joined) {
    std::ostringstream msg;
    if (from_a.empty()) {
      msg << "no roadmap milestone is visible from " << Point(a);
    } else if (to_b.empty()) {
      msg << "no roadmap milestone is visible from " << Point(b);
    } else {
      msg << "the roadmap does not connect " << Point(a) << " (" << from_a.size()
          << " connections) to " << Point(b) << " (" << to_b.size()
          << " connections): they are in different components";
    }
    out.status = PlanStatus::kNoPath;
    out.message = msg.str();
    return out;
  }

  t0 = MonotonicNowNs();
  const uint32_t n = static_cast<uint32_t>(roadmap.num_milestones());
  const uint32_t start = n, goal = n + 1;
  constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();
  constexpr double kInf = std::numeric_limits<double>::infinity();
  std::vector<double> g(n + 2, kInf);
  std::vector<uint32_t> parent(n + 2, kNone);
  std::vector<bool> closed(n + 2, false);
  const auto position = [&](uint32_t v) -> const Eigen::Vector3d& {
    return v == start ? a : v == goal ? b : roadmap.milestone(v);
  };
  const auto heuristic = [&](uint32_t v) {
    const Eigen::Vector3d& p = position(v);
    return w.length * (p - b).norm() + w.altitude * std::abs(p.z() - b.z());
  };
  using Entry = std::pair<double, uint32_t>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> open;
  const auto relax = [&](uint32_t from, uint32_t to, double cost) {
    const double candidate = g[from] + cost;
    if (candidate < g[to]) {
      g[to] = candidate;
      parent[to] = from;
      open.emplace(candidate + heuristic(to), to);
    }
  };
  g[start] = 0;
  open.emplace(heuristic(start), start);
  uint64_t pops = 0;
  while (!open.empty()) {
    const uint32_t u = open.top().second;
    open.pop();
    if (closed[u]) continue;
    closed[u] = true;
    if (u == goal) break;
    if ((++pops & 1023) == 0) MAV_RETURN_IF_ERROR(stop.Check("plan"));
    if (u == start) {
      for (const Connection& c : from_a) relax(start, c.milestone, c.cost);
      if (std::isfinite(direct)) relax(start, goal, direct);
      continue;
    }
    const auto [begin, end] = roadmap.neighbours(u);
    const std::vector<RoadmapEdge>& edges = roadmap.edges();
    for (auto it = begin; it != end; ++it) {
      if (closed[it->first]) continue;
      const RoadmapEdge& e = edges[it->second];
      relax(u, it->first,
            w.length * e.length_m + w.clearance * e.proximity + w.altitude * e.climb_m);
    }
    const auto link =
        std::lower_bound(to_b.begin(), to_b.end(), u,
                         [](const Connection& c, uint32_t id) { return c.milestone < id; });
    if (link != to_b.end() && link->milestone == u) relax(u, goal, link->cost);
  }
  out.search_ms = MsSince(t0);
  MAV_CHECK(std::isfinite(g[goal])) << "A* missed a goal in the start's component";
  for (uint32_t v = goal; v != kNone; v = parent[v]) out.raw.push_back(position(v));
  std::reverse(out.raw.begin(), out.raw.end());
  out.status = PlanStatus::kSuccess;
  return out;
}

}  // namespace

namespace internal {

double ConnectionClearance(const ClearanceMap& map, const Eigen::Vector3d& p, double preferred) {
  return map.HasClearance(p, preferred) ? preferred : map.robot_radius();
}

Result<PlanResult> RunPipeline(const ClearanceMap& map, const PlanRequest& request,
                               const LegPlanner& plan_leg, double path_clearance_m,
                               const Termination& stop) {
  const int64_t start_ns = MonotonicNowNs();
  std::string why;
  if (!request.IsValid(&why)) return Status::InvalidArgument(why);
  MAV_RETURN_IF_ERROR(stop.Check("plan"));
  PlanResult result;
  std::vector<Eigen::Vector3d> points = {request.start};
  points.insert(points.end(), request.waypoints.begin(), request.waypoints.end());
  points.push_back(request.goal);

  // 1. The points.
  const int64_t check_ns = MonotonicNowNs();
  for (size_t i = 0; i < points.size(); ++i) {
    const std::string bad = WhyInvalid(map, points[i]);
    if (bad.empty()) continue;
    if (i == 0) {
      result.status = PlanStatus::kStartInvalid;
      result.message = "start: " + bad;
    } else if (i + 1 == points.size()) {
      result.status = PlanStatus::kGoalInvalid;
      result.message = "goal: " + bad;
    } else {
      result.status = PlanStatus::kGoalInvalid;
      result.invalid_waypoint = static_cast<int>(i - 1);
      result.message = "waypoints[" + std::to_string(i - 1) + "]: " + bad;
    }
    result.timings.connect_ms = MsSince(check_ns);
    result.timings.total_ms = MsSince(start_ns);
    return result;
  }
  result.timings.connect_ms = MsSince(check_ns);

  // 2 + 3. Legs, shortened one by one (the waypoints stay).
  ShortenOptions shorten;
  shorten.max_cost_increase = request.max_cost_increase;
  shorten.required_clearance_m = path_clearance_m;
  std::vector<size_t> stops;
  for (size_t leg = 0; leg + 1 < points.size(); ++leg) {
    MAV_ASSIGN_OR_RETURN(internal::LegOutcome outcome, plan_leg(points[leg], points[leg + 1]));
    result.timings.connect_ms += outcome.connect_ms;
    result.timings.search_ms += outcome.search_ms;
    result.timings.shorten_ms += outcome.shorten_ms;
    if (outcome.status != PlanStatus::kSuccess) {
      result.status = outcome.status;
      result.message = points.size() > 2 ? "leg " + std::to_string(leg) + ": " + outcome.message
                                         : outcome.message;
      result.timings.total_ms = MsSince(start_ns);
      return result;
    }
    if (outcome.shortened.empty()) {
      const int64_t t0 = MonotonicNowNs();
      outcome.shortened = ShortenPath(map, request.weights, outcome.raw, shorten, stop);
      result.timings.shorten_ms += MsSince(t0);
      MAV_RETURN_IF_ERROR(stop.Check("plan"));
    }
    // Join the legs without repeating the waypoint.
    const size_t skip = result.path.empty() ? 0 : 1;
    result.path.insert(result.path.end(), outcome.raw.begin() + skip, outcome.raw.end());
    result.shortened_path.insert(result.shortened_path.end(), outcome.shortened.begin() + skip,
                                 outcome.shortened.end());
    if (leg + 2 < points.size()) stops.push_back(result.shortened_path.size() - 1);
  }
  result.path_cost = EvaluatePathCost(map, request.weights, result.path);
  result.shortened_cost = EvaluatePathCost(map, request.weights, result.shortened_path);

  // 4. Trajectory.
  TrajectoryOptions options;
  options.limits = request.limits;
  options.required_clearance_m = map.robot_radius();
  options.corner_clearance_m = 0.5 * (map.robot_radius() + path_clearance_m);
  options.yaw_policy = request.yaw_policy;
  options.start_yaw_rad = request.start_yaw_rad;
  Result<TrajectoryResult> trajectory =
      PlanTrajectory(map, result.shortened_path, stops, options, stop);
  if (!trajectory.ok()) {
    if (trajectory.status().code() == StatusCode::kDeadlineExceeded ||
        trajectory.status().code() == StatusCode::kCancelled) {
      return trajectory.status();
    }
    result.status = PlanStatus::kTrajectoryFailed;
    result.message = trajectory.status().message();
    result.timings.total_ms = MsSince(start_ns);
    return result;
  }
  result.trajectory = std::move(trajectory->trajectory);
  result.timings.speed_plan_ms = trajectory->speed_plan_ms;
  result.timings.spline_ms = trajectory->spline_ms;
  result.timings.check_ms = trajectory->check_ms;
  result.duration_s = trajectory->duration_s;
  result.max_speed_mps = trajectory->max_speed_mps;
  result.mean_speed_mps = trajectory->mean_speed_mps;
  result.trajectory_length_m = trajectory->length_m;
  result.trajectory_min_clearance_m = trajectory->min_clearance_m;
  result.trajectory_refits = trajectory->refits;
  result.status = PlanStatus::kSuccess;
  result.timings.total_ms = MsSince(start_ns);
  return result;
}

}  // namespace internal

const char* PlanStatusName(PlanStatus status) {
  switch (status) {
    case PlanStatus::kSuccess:
      return "SUCCESS";
    case PlanStatus::kNoPath:
      return "NO_PATH";
    case PlanStatus::kStartInvalid:
      return "START_INVALID";
    case PlanStatus::kGoalInvalid:
      return "GOAL_INVALID";
    case PlanStatus::kTimeout:
      return "TIMEOUT";
    case PlanStatus::kTrajectoryFailed:
      return "TRAJECTORY_FAILED";
  }
  return "UNKNOWN";
}

bool PlanRequest::IsValid(std::string* why) const {
  std::ostringstream msg;
  if (!start.allFinite()) {
    msg << "start: not finite";
  } else if (!goal.allFinite()) {
    msg << "goal: not finite";
  } else {
    for (size_t i = 0; i < waypoints.size(); ++i) {
      if (!waypoints[i].allFinite()) {
        msg << "waypoints[" << i << "]: not finite";
        break;
      }
    }
  }
  if (msg.str().empty()) {
    std::string sub;
    if (!weights.IsValid(&sub)) {
      msg << "weights." << sub;
    } else if (!limits.IsValid(&sub)) {
      msg << "limits." << sub;
    } else if (!(max_cost_increase >= 0 && max_cost_increase <= 10)) {
      msg << "max_cost_increase: must be in [0, 10], got " << max_cost_increase;
    } else if (!(time_budget_s > 0 && time_budget_s <= 600)) {
      msg << "time_budget_s: must be in (0, 600] s, got " << time_budget_s;
    } else if (!std::isfinite(start_yaw_rad)) {
      msg << "start_yaw_rad: not finite";
    } else if (connection_candidates < 1 || connection_candidates > 1000) {
      msg << "connection_candidates: must be in [1, 1000], got " << connection_candidates;
    }
  }
  if (msg.str().empty()) return true;
  if (why) *why = msg.str();
  return false;
}

Result<PlanResult> PlanPath(const ClearanceMap& map, const Roadmap* roadmap,
                            const PlanRequest& request, const Termination& stop) {
  if (roadmap == nullptr || !request.use_roadmap || roadmap->num_milestones() == 0) {
    PlanRequest fresh = request;
    fresh.use_roadmap = false;
    OmplPeerOptions options;
    options.planner = OmplPlanner::kPrmStar;
    options.time_budget_s = request.time_budget_s;
    options.seed = request.seed;
    // PlanWithOmpl with our shortening: see ompl_planners.cc.
    return internal::RunPipeline(
        map, fresh,
        [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
          return internal::FreshOmplLeg(map, options, /*simplify=*/false, a, b, stop);
        },
        map.robot_radius() + options.clearance_margin_m, stop);
  }
  MAV_RETURN_IF_ERROR(roadmap->CheckBelongsTo(map));
  return internal::RunPipeline(
      map, request,
      [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
        return RoadmapLeg(map, *roadmap, request, a, b, stop);
      },
      map.robot_radius() + roadmap->info().clearance_margin_m, stop);
}

}  // namespace mav::planning
