#pragma once
// mav.v1 planning messages <-> libs/planning types (planner_core.h). Requests are validated here,
// with messages that start with the field path as the request spells it ("start.x: not finite",
// "waypoints[2].z: not finite", "limits.max_speed_mps: must be in [0, 20] m/s, got 25"), and
// the proto's "0 = default" rules are applied, so the library's own checks never see a value
// the contract refuses.

#include <string>

#include <google/protobuf/repeated_field.h>
#include <Eigen/Core>

#include "mav/v1/common.pb.h"
#include "mav/v1/mapping.pb.h"  // the map a planning service fetches from mapping
#include "mav/v1/planning.pb.h"

#include "mav/common/status.h"
#include "mav/geometry/polynomial_trajectory.h"
#include "mav/planning/planner.h"
#include "mav/planning/planning_map.h"
#include "mav/planning/roadmap.h"
#include "services/common/proto_codec.h"
#include "services/planning/planner_core.h"

namespace mav::planning_service {

// Replies carry at most this many TrajectorySamples (~175 bytes each on the wire): they must fit
// gRPC's 4 MiB message limit.
inline constexpr size_t kMaxSamples = 20000;
// PlanPathRequest.waypoints at most (a request must also fit the 4 MiB limit).
inline constexpr int kMaxWaypoints = 1000;

// A point that must be set and finite: InvalidArgument "<field>: not set" / "<field>.y: not
// finite".
Result<Eigen::Vector3d> PointFromProto(const v1::Vector3& point, const std::string& field,
                                       bool set = true);
// The shared messages (vectors, trajectories) go through the one codec.
using service_common::ToProto;
using service_common::TrajectoryFromProto;

// MapOptions with the proto's defaults; `field` prefixes messages ("options.robot_radius_m: ...").
Result<planning::MapOptions> MapOptionsFromProto(const v1::MapOptions& options,
                                                 const std::string& field);
void ToProto(const planning::MapInfo& info, const planning::MapOptions& options, v1::MapInfo* out);

Result<planning::RoadmapOptions> RoadmapOptionsFromProto(const v1::BuildRoadmapRequest& request);
void ToProto(const planning::RoadmapInfo& info, const std::string& source, v1::RoadmapInfo* out);

// The whole PlanPathRequest (defaults applied, every field validated).
Result<planning::PlanRequest> PlanRequestFromProto(const v1::PlanPathRequest& request);

// The reply of a plan (no plan_id, no samples: the service sets them).
void ToProto(const PlanOutcome& outcome, v1::PlanPathResponse* out);

void ToProto(const geometry::TrajectoryPoint& point, v1::TrajectorySample* out);

// Appends samples every dt_s from 0 to the end (end included). RESOURCE_EXHAUSTED "<field>: N
// samples, more than 20000 ..." (nothing appended) when too many.
Status AppendSamples(const geometry::PolynomialTrajectory& trajectory, double dt_s,
                     const std::string& field,
                     google::protobuf::RepeatedPtrField<v1::TrajectorySample>* out);

void ToProto(const CoreStatus& status, v1::PlanningStatus* out);

// The enums of planning.proto (tests/contract/shared_messages_test.cc checks each table).
// UNSPECIFIED means EXACT.
inline constexpr auto kDistanceMethodCodec =
    service_common::MakeEnumCodec<v1::DistanceMethod, planning::DistanceMethod>(
        v1::DistanceMethod_descriptor,
        {{v1::DISTANCE_METHOD_EXACT, planning::DistanceMethod::kExact},
         {v1::DISTANCE_METHOD_DYNAMIC_EDT3D, planning::DistanceMethod::kDynamicEdt3d}},
        planning::DistanceMethod::kExact);

// The map a planning service asks a mapping service for (UNSPECIFIED: the one it built last).
inline constexpr auto kMappingMethodRefCodec =
    service_common::MakeEnumCodec<v1::MappingMethodRef, v1::MappingMethod>(
        v1::MappingMethodRef_descriptor,
        {{v1::MAPPING_METHOD_REF_SPARSE_MESH, v1::MAPPING_METHOD_SPARSE_MESH},
         {v1::MAPPING_METHOD_REF_OCTOMAP, v1::MAPPING_METHOD_OCTOMAP}},
        v1::MAPPING_METHOD_UNSPECIFIED);

}  // namespace mav::planning_service
