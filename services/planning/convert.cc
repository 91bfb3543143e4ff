#include "services/planning/convert.h"

#include <cmath>
#include <cstdio>
#include <utility>
#include <vector>

#include "services/common/proto_codec.h"

namespace mav::planning_service {

namespace {

// Six significant digits, as a user would type the value.
std::string Text(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.6g", v);
  return buf;
}

// `value` of `field`: 0 takes `fallback`; otherwise finite and in [0, hi] ("(0, hi]" reads the
// same for a field where 0 means the default).
Result<double> ZeroMeansDefault(double value, double fallback, double hi, const std::string& field,
                                const char* unit) {
  if (!std::isfinite(value) || value < 0 || value > hi) {
    return Status::InvalidArgument(field + ": must be in [0, " + Text(hi) + "] " + unit +
                                   " (0 = " + Text(fallback) + "), got " + Text(value));
  }
  return value == 0 ? fallback : value;
}

Status InRange(double value, double lo, double hi, const std::string& field, const char* unit) {
  if (!std::isfinite(value) || value < lo || value > hi) {
    return Status::InvalidArgument(field + ": must be in [" + Text(lo) + ", " + Text(hi) + "] " +
                                   unit + ", got " + Text(value));
  }
  return Status::Ok();
}

void BoxToProto(const planning::Box& box, v1::Box* out) {
  ToProto(box.min, out->mutable_min());
  ToProto(box.max, out->mutable_max());
}

v1::PlanStatus ToProto(planning::PlanStatus status) {
  switch (status) {
    case planning::PlanStatus::kSuccess:
      return v1::PLAN_STATUS_SUCCESS;
    case planning::PlanStatus::kNoPath:
      return v1::PLAN_STATUS_NO_PATH;
    case planning::PlanStatus::kStartInvalid:
      return v1::PLAN_STATUS_START_INVALID;
    case planning::PlanStatus::kGoalInvalid:
      return v1::PLAN_STATUS_GOAL_INVALID;
    case planning::PlanStatus::kTimeout:
      return v1::PLAN_STATUS_TIMEOUT;
    case planning::PlanStatus::kTrajectoryFailed:
      return v1::PLAN_STATUS_TRAJECTORY_FAILED;
  }
  return v1::PLAN_STATUS_UNSPECIFIED;
}

void ToProto(const planning::PathCost& cost, v1::PathCost* out) {
  out->set_length_m(cost.length_m);
  out->set_clearance_cost(cost.clearance_cost);
  out->set_altitude_change_m(cost.altitude_change_m);
  out->set_total(cost.total);
  out->set_min_clearance_m(cost.min_clearance_m);
}

void ToProto(const planning::PlanTimings& t, v1::PlanTimings* out) {
  out->set_connect_ms(t.connect_ms);
  out->set_search_ms(t.search_ms);
  out->set_shorten_ms(t.shorten_ms);
  out->set_speed_plan_ms(t.speed_plan_ms);
  out->set_spline_ms(t.spline_ms);
  out->set_check_ms(t.check_ms);
  out->set_total_ms(t.total_ms);
}

}  // namespace

Result<Eigen::Vector3d> PointFromProto(const v1::Vector3& point, const std::string& field,
                                       bool set) {
  if (!set) return Status::InvalidArgument(field + ": not set");
  return service_common::VectorFromProto(point, field);
}

Result<planning::MapOptions> MapOptionsFromProto(const v1::MapOptions& proto,
                                                 const std::string& field) {
  planning::MapOptions options;
  MAV_ASSIGN_OR_RETURN(options.robot_radius_m,
                       ZeroMeansDefault(proto.robot_radius_m(), options.robot_radius_m, 10,
                                        field + ".robot_radius_m", "m"));
  MAV_ASSIGN_OR_RETURN(options.max_distance_m,
                       ZeroMeansDefault(proto.max_distance_m(), options.max_distance_m, 50,
                                        field + ".max_distance_m", "m"));
  if (options.max_distance_m <= options.robot_radius_m) {
    return Status::InvalidArgument(field + ".max_distance_m: " + Text(options.max_distance_m) +
                                   " m must exceed the robot radius " +
                                   Text(options.robot_radius_m) + " m");
  }
  options.unknown_space =
      proto.unknown_is_free() ? planning::UnknownSpace::kFree : planning::UnknownSpace::kObstacle;
  if (proto.has_bounds()) {
    // The shared rules first (finite, ordered corners), then the planner's own: a volume.
    MAV_ASSIGN_OR_RETURN(const Eigen::AlignedBox3d bounds,
                         service_common::BoxFromProto(proto.bounds(), field + ".bounds"));
    planning::Box box{bounds.min(), bounds.max()};
    std::string why;
    if (!box.IsValid(field + ".bounds", &why)) return Status::InvalidArgument(why);
    options.planning_bounds = box;
  }
  MAV_ASSIGN_OR_RETURN(
      options.distance_method,
      kDistanceMethodCodec.FromProto(proto.distance_method(), field + ".distance_method"));
  return options;
}

void ToProto(const planning::MapInfo& info, const planning::MapOptions& options, v1::MapInfo* out) {
  out->set_resolution_m(info.resolution_m);
  BoxToProto(info.bounds, out->mutable_bounds());
  BoxToProto(info.planning_bounds, out->mutable_planning_bounds());
  out->set_occupied_voxels(info.occupied_voxels);
  out->set_free_voxels(info.free_voxels);
  out->set_unknown_voxels(info.unknown_voxels);
  out->set_load_ms(info.load_ms);
  out->set_distance_map_ms(info.distance_map_ms);
  out->set_source(info.source);
  out->set_memory_bytes(info.memory.bytes);
  out->set_fingerprint(info.fingerprint);
  out->set_octree_leaves(info.octree_leaves);
  out->set_robot_radius_m(options.robot_radius_m);
  out->set_distance_method(kDistanceMethodCodec.ToProto(options.distance_method));
}

Result<planning::RoadmapOptions> RoadmapOptionsFromProto(const v1::BuildRoadmapRequest& request) {
  planning::RoadmapOptions options;
  MAV_ASSIGN_OR_RETURN(
      options.time_budget_s,
      ZeroMeansDefault(request.time_budget_s(), options.time_budget_s, 600, "time_budget_s", "s"));
  if (request.max_milestones() != 0) options.max_milestones = request.max_milestones();
  options.seed = request.seed();
  MAV_RETURN_IF_ERROR(
      InRange(request.validity_resolution_m(), 0, 1, "validity_resolution_m", "m (0 = 1 cm)"));
  options.validity_resolution_m = request.validity_resolution_m();
  if (request.has_clearance_margin_m()) {
    MAV_RETURN_IF_ERROR(
        InRange(request.clearance_margin_m(), 0, 1, "clearance_margin_m", "m (unset = 0.05)"));
    options.clearance_margin_m = request.clearance_margin_m();
  }
  return options;
}

void ToProto(const planning::RoadmapInfo& info, const std::string& source, v1::RoadmapInfo* out) {
  out->set_milestones(info.milestones);
  out->set_edges(info.edges);
  out->set_build_s(info.build_s);
  out->set_seed(info.seed);
  out->set_largest_component(info.largest_component);
  out->set_memory_bytes(info.memory_bytes);
  out->set_load_ms(info.load_ms);
  out->set_clearance_margin_m(info.clearance_margin_m);
  out->set_validity_resolution_m(info.validity_resolution_m);
  out->set_robot_radius_m(info.robot_radius_m);
  out->set_map_fingerprint(info.map_fingerprint);
  out->set_source(source);
}

Result<planning::PlanRequest> PlanRequestFromProto(const v1::PlanPathRequest& r) {
  planning::PlanRequest request;
  MAV_ASSIGN_OR_RETURN(request.start, PointFromProto(r.start(), "start", r.has_start()));
  MAV_ASSIGN_OR_RETURN(request.goal, PointFromProto(r.goal(), "goal", r.has_goal()));
  if (r.waypoints_size() > kMaxWaypoints) {
    return Status::InvalidArgument("waypoints: " + std::to_string(r.waypoints_size()) +
                                   " waypoints, at most " + std::to_string(kMaxWaypoints));
  }
  for (int i = 0; i < r.waypoints_size(); ++i) {
    MAV_ASSIGN_OR_RETURN(Eigen::Vector3d p,
                         PointFromProto(r.waypoints(i), "waypoints[" + std::to_string(i) + "]"));
    request.waypoints.push_back(p);
  }

  const v1::CostWeights& w = r.weights();
  const std::pair<double, const char*> weights[] = {{w.length_weight(), "length_weight"},
                                                    {w.clearance_weight(), "clearance_weight"},
                                                    {w.altitude_weight(), "altitude_weight"}};
  for (const auto& [value, name] : weights) {
    if (!std::isfinite(value) || value < 0) {
      return Status::InvalidArgument(std::string("weights.") + name +
                                     ": must be finite and >= 0, got " + Text(value));
    }
  }
  // All zero (unset) = the defaults; otherwise exactly as given (e.g. length only).
  if (w.length_weight() != 0 || w.clearance_weight() != 0 || w.altitude_weight() != 0) {
    request.weights.length = w.length_weight();
    request.weights.clearance = w.clearance_weight();
    request.weights.altitude = w.altitude_weight();
  }

  if (r.has_max_cost_increase()) {
    MAV_RETURN_IF_ERROR(InRange(r.max_cost_increase(), 0, 10, "max_cost_increase", "(a fraction)"));
    request.max_cost_increase = r.max_cost_increase();
  }

  const v1::SpeedLimits& l = r.limits();
  planning::SpeedLimits& limits = request.limits;
  MAV_ASSIGN_OR_RETURN(
      limits.max_speed_mps,
      ZeroMeansDefault(l.max_speed_mps(), limits.max_speed_mps, 20, "limits.max_speed_mps", "m/s"));
  MAV_ASSIGN_OR_RETURN(limits.max_acceleration_mps2,
                       ZeroMeansDefault(l.max_acceleration_mps2(), limits.max_acceleration_mps2, 20,
                                        "limits.max_acceleration_mps2", "m/s^2"));
  MAV_ASSIGN_OR_RETURN(
      limits.max_lateral_acceleration_mps2,
      ZeroMeansDefault(l.max_lateral_acceleration_mps2(), limits.max_lateral_acceleration_mps2, 20,
                       "limits.max_lateral_acceleration_mps2", "m/s^2"));
  MAV_ASSIGN_OR_RETURN(limits.max_jerk_mps3,
                       ZeroMeansDefault(l.max_jerk_mps3(), limits.max_jerk_mps3, 200,
                                        "limits.max_jerk_mps3", "m/s^3"));

  request.use_roadmap = !r.has_use_roadmap() || r.use_roadmap();
  MAV_ASSIGN_OR_RETURN(
      request.time_budget_s,
      ZeroMeansDefault(r.time_budget_s(), request.time_budget_s, 600, "time_budget_s", "s"));
  request.seed = r.seed();
  if (r.sample_dt_s() != 0) {
    MAV_RETURN_IF_ERROR(InRange(r.sample_dt_s(), 0.001, 10, "sample_dt_s", "s (0 = no samples)"));
  }
  MAV_ASSIGN_OR_RETURN(request.yaw_policy,
                       service_common::kYawPolicyCodec.FromProto(r.yaw_policy(), "yaw_policy"));
  if (request.yaw_policy == geometry::YawPolicy::kSegment) {
    return Status::InvalidArgument(
        "yaw_policy: SEGMENT needs yaw polynomials per segment, which the planner does not plan "
        "(use CONSTANT or ALONG_PATH)");
  }
  if (!std::isfinite(r.start_yaw_rad())) {
    return Status::InvalidArgument("start_yaw_rad: not finite");
  }
  request.start_yaw_rad = r.start_yaw_rad();
  // Everything the contract refuses was refused above; this is the library's own backstop.
  std::string why;
  if (!request.IsValid(&why)) return Status::InvalidArgument(why);
  return request;
}

void ToProto(const PlanOutcome& outcome, v1::PlanPathResponse* out) {
  const planning::PlanResult& r = outcome.result;
  out->set_status(ToProto(r.status));
  out->set_message(r.message);
  for (const Eigen::Vector3d& p : r.path) ToProto(p, out->add_path());
  for (const Eigen::Vector3d& p : r.shortened_path) ToProto(p, out->add_shortened_path());
  ToProto(r.path_cost, out->mutable_path_cost());
  ToProto(r.shortened_cost, out->mutable_shortened_cost());
  if (!r.trajectory.empty()) ToProto(r.trajectory, out->mutable_trajectory());
  out->set_planning_ms(r.timings.planning_ms());
  out->set_trajectory_ms(r.timings.trajectory_ms());
  out->set_duration_s(r.duration_s);
  out->set_max_speed_mps(r.max_speed_mps);
  out->set_mean_speed_mps(r.mean_speed_mps);
  out->set_invalid_waypoint(r.invalid_waypoint);
  ToProto(r.timings, out->mutable_timings());
  out->set_trajectory_length_m(r.trajectory_length_m);
  out->set_trajectory_min_clearance_m(r.trajectory_min_clearance_m);
  out->set_trajectory_refits(r.trajectory_refits);
  out->set_map_fingerprint(outcome.map_fingerprint);
  out->set_used_roadmap(outcome.used_roadmap);
}

void ToProto(const geometry::TrajectoryPoint& point, v1::TrajectorySample* out) {
  out->set_t_s(point.t_s);
  ToProto(point.position, out->mutable_position());
  ToProto(point.velocity, out->mutable_velocity());
  ToProto(point.acceleration, out->mutable_acceleration());
  ToProto(point.jerk, out->mutable_jerk());
  ToProto(point.snap, out->mutable_snap());
  out->set_yaw_rad(point.yaw_rad);
  out->set_yaw_rate_radps(point.yaw_rate_radps);
}

Status AppendSamples(const geometry::PolynomialTrajectory& trajectory, double dt_s,
                     const std::string& field,
                     google::protobuf::RepeatedPtrField<v1::TrajectorySample>* out) {
  // Sample() gives 0, dt, 2 dt, ... below the end, then the end.
  const double steps = std::floor(trajectory.duration_s() / dt_s);
  const double count = steps + 2;
  if (count > static_cast<double>(kMaxSamples)) {
    return Status::ResourceExhausted(
        field + ": " + Text(count) + " samples of the " + Text(trajectory.duration_s()) +
        " s trajectory, more than " + std::to_string(kMaxSamples) +
        " (the reply must fit gRPC's 4 MiB limit); use a larger step or SampleTrajectory in parts");
  }
  for (const geometry::TrajectoryPoint& p : trajectory.Sample(dt_s)) ToProto(p, out->Add());
  return Status::Ok();
}

void ToProto(const CoreStatus& s, v1::PlanningStatus* out) {
  if (s.snapshot != nullptr) {
    out->set_map_loaded(true);
    ToProto(s.snapshot->map->info(), s.snapshot->map->options(), out->mutable_map());
    if (s.snapshot->roadmap != nullptr) {
      out->set_roadmap_ready(true);
      ToProto(s.snapshot->roadmap->info(), s.snapshot->roadmap_source, out->mutable_roadmap());
    }
  }
  out->set_busy(s.busy);
  out->set_operation(s.operation);
  out->set_roadmap_building(s.busy && s.operation == "BuildRoadmap");
  if (s.busy) {
    out->mutable_build_progress()->set_stage(s.stage);
    out->mutable_build_progress()->set_fraction(s.fraction);
    out->mutable_build_progress()->set_elapsed_s(s.elapsed_s);
  }
  out->set_plans(s.plans);
  out->set_plans_succeeded(s.plans_succeeded);
  service_common::ToProto(s.planning_ms, out->mutable_planning_ms());
  out->set_plans_in_flight(s.plans_in_flight);
  out->set_max_plans_in_flight(s.max_plans_in_flight);
  out->set_plans_rejected(s.plans_rejected);
  out->set_plans_failed(s.plans_failed);
  out->set_plans_stored(s.plans_stored);
  out->set_plan_history(static_cast<uint32_t>(PlannerCore::kPlanHistory));
  out->set_last_error(s.last_error);
}

}  // namespace mav::planning_service
