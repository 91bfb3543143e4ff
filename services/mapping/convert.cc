#include "services/mapping/convert.h"

#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <tuple>

#include "mav/mapping/octomap_mapper.h"

namespace mav::mapping_service {

using service_common::Number;

namespace {

// A double option: 0 keeps `*target`; otherwise finite and in [lo, hi] (lo exclusive when
// `lo_open`).
Status DoubleOption(double value, double lo, bool lo_open, double hi, const std::string& field,
                    double* target) {
  if (value == 0.0) return Status::Ok();
  const bool low_ok = lo_open ? value > lo : value >= lo;
  if (!std::isfinite(value) || !low_ok || value > hi) {
    return Status::InvalidArgument(field + ": must be " + (lo_open ? "> " : ">= ") + Number(lo) +
                                   (std::isfinite(hi) ? " and <= " + Number(hi) : "") +
                                   " and finite, got " + Number(value));
  }
  if (target != nullptr) *target = value;
  return Status::Ok();
}

Eigen::AlignedBox3d BoundsOf(const dataset::GridGeometry& g) {
  return Eigen::AlignedBox3d(g.origin, g.origin + g.size.cast<double>() * g.resolution);
}

}  // namespace

Result<std::optional<MappingMethod>> MethodFromProto(v1::MappingMethod method,
                                                     const std::string& field,
                                                     bool allow_unspecified) {
  if (method == v1::MAPPING_METHOD_UNSPECIFIED && allow_unspecified) {
    return std::optional<MappingMethod>();
  }
  MAV_ASSIGN_OR_RETURN(const MappingMethod m, kMappingMethodCodec.FromProto(method, field));
  return std::optional<MappingMethod>(m);
}

v1::MappingMethod ToProto(MappingMethod method) { return kMappingMethodCodec.ToProto(method); }

Result<PoseSource> PoseSourceFromProto(v1::PoseSource source) {
  return kPoseSourceCodec.FromProto(source, "pose_source");
}

v1::PoseSource ToProto(PoseSource source) { return kPoseSourceCodec.ToProto(source); }

Result<SessionConfig> SessionFromProto(const v1::StartSessionRequest& request,
                                       const SessionConfig& defaults) {
  SessionConfig config = defaults;
  const v1::KeyframeOptions& k = request.keyframes();
  constexpr double kInf = std::numeric_limits<double>::infinity();
  MAV_RETURN_IF_ERROR(DoubleOption(k.min_translation_m(), 0.0, true, kInf,
                                   "keyframes.min_translation_m",
                                   &config.keyframes.min_translation_m));
  double rotation_deg = 0;
  MAV_RETURN_IF_ERROR(DoubleOption(k.min_rotation_deg(), 0.0, true, 180.0,
                                   "keyframes.min_rotation_deg", &rotation_deg));
  // The proto's default is 10 deg (the library's 12 deg is tuned for mav-eval's full presets).
  config.keyframes.min_rotation_rad = (rotation_deg == 0 ? 10.0 : rotation_deg) * M_PI / 180.0;
  if (k.max_keyframes() > 100000) {
    return Status::InvalidArgument("keyframes.max_keyframes: must be <= 100000, got " +
                                   std::to_string(k.max_keyframes()));
  }
  config.max_keyframes = k.max_keyframes() == 0 ? 5000 : static_cast<int>(k.max_keyframes());
  if (k.features_per_keyframe() > 10000) {
    return Status::InvalidArgument("keyframes.features_per_keyframe: must be <= 10000, got " +
                                   std::to_string(k.features_per_keyframe()));
  }
  config.features_per_keyframe =
      k.features_per_keyframe() == 0 ? 100 : static_cast<int>(k.features_per_keyframe());
  MAV_RETURN_IF_ERROR(DoubleOption(k.max_depth_m(), 0.5, false, 100.0, "keyframes.max_depth_m",
                                   &config.max_depth_m));
  config.sparse_mesh_only = request.sparse_mesh_only();
  MAV_ASSIGN_OR_RETURN(config.pose_source, PoseSourceFromProto(request.pose_source()));
  return config;
}

Result<BuildRequest> BuildFromProto(const v1::BuildMapRequest& request) {
  BuildRequest out;
  MAV_ASSIGN_OR_RETURN(std::optional<MappingMethod> method,
                       MethodFromProto(request.method(), "method", false));
  out.method = *method;
  const double resolution = request.resolution_m();
  if (resolution != 0.0 && (!std::isfinite(resolution) || resolution < 0.01 || resolution > 2.0)) {
    return Status::InvalidArgument("resolution_m: must be in [0.01, 2] m, got " +
                                   Number(resolution));
  }
  out.resolution_m = resolution == 0.0 ? 0.05 : resolution;
  if (request.has_bounds()) {
    MAV_ASSIGN_OR_RETURN(Eigen::AlignedBox3d bounds, BoxFromProto(request.bounds(), "bounds"));
    if ((bounds.max() - bounds.min()).minCoeff() <= 0.0) {
      return Status::InvalidArgument("bounds: empty box (zero extent on an axis)");
    }
    out.bounds = bounds;
  }
  MAV_ASSIGN_OR_RETURN(out.unknown, kUnknownHandlingCodec.FromProto(request.unknown(), "unknown"));
  MAV_ASSIGN_OR_RETURN(const mapping::MapPreference preference,
                       kMapPreferenceCodec.FromProto(request.prefer(), "prefer"));
  const mapping::BuildOptions preferred = mapping::BuildOptions::For(preference);
  out.meshing = *preferred.meshing;
  out.mesh_to_grid = *preferred.mesh_to_grid;
  out.keep_unchecked_points = *preferred.keep_unchecked_points;
  out.occlusion_check = *preferred.occlusion_check;
  if (request.surfaces_only()) {
    out.mesh_to_grid.occupy_inside_cells = false;
    out.mesh_to_grid.occupy_surface_voxels = true;
  }

  constexpr double kInf = std::numeric_limits<double>::infinity();
  const v1::SparseMeshOptions& s = request.sparse_mesh();
  MAV_RETURN_IF_ERROR(DoubleOption(s.free_space_weight(), 0.0, true, kInf,
                                   "sparse_mesh.free_space_weight", &out.meshing.alpha_vis));
  MAV_RETURN_IF_ERROR(
      DoubleOption(s.inside_weight(), 0.0, true, kInf, "sparse_mesh.inside_weight", nullptr));
  // The mesher gives a line of sight one weight, alpha_vis, for its free-space facets and for the
  // cell behind the point (Labatut et al. 2007): a separate inside weight is not a free choice.
  if (s.inside_weight() != 0.0 && s.inside_weight() != out.meshing.alpha_vis) {
    return Status::InvalidArgument(
        "sparse_mesh.inside_weight: the mesher uses free_space_weight (alpha_vis = " +
        Number(out.meshing.alpha_vis) + ") for the cell behind a point too; leave 0 or equal");
  }
  if (s.smoothness_weight() < 0.0 || !std::isfinite(s.smoothness_weight())) {
    return Status::InvalidArgument("sparse_mesh.smoothness_weight: must be >= 0 and finite, got " +
                                   Number(s.smoothness_weight()));
  }
  if (s.smoothness_weight() != 0.0) out.meshing.lambda_quality = s.smoothness_weight();
  if (s.min_visibility() > 100) {
    return Status::InvalidArgument("sparse_mesh.min_visibility: must be in [1, 100], got " +
                                   std::to_string(s.min_visibility()));
  }
  out.min_visibility = s.min_visibility() == 0 ? 1 : static_cast<int>(s.min_visibility());
  MAV_RETURN_IF_ERROR(DoubleOption(s.max_ray_length_m(), 0.0, true, kInf,
                                   "sparse_mesh.max_ray_length_m", &out.meshing.max_ray_length));

  // The baseline integrates every keyframe as it arrives (dense stereo + ray casting), with the
  // library's options; a build only samples the octree. Per-build values are validated and must
  // equal the values in use (or be 0).
  const v1::OctomapOptions& o = request.octomap();
  const mapping::OctomapMapperOptions used;
  auto same = [&](double value, double in_use, const std::string& field) -> Status {
    if (value == 0.0 || value == in_use) return Status::Ok();
    return Status::InvalidArgument(field +
                                   ": the OctoMap baseline integrates keyframes as they "
                                   "arrive with " +
                                   Number(in_use) + "; a build cannot change it (leave 0)");
  };
  MAV_RETURN_IF_ERROR(
      DoubleOption(o.max_range_m(), 0.0, true, kInf, "octomap.max_range_m", nullptr));
  MAV_RETURN_IF_ERROR(same(o.max_range_m(), used.max_range_m, "octomap.max_range_m"));
  if (o.prob_hit() != 0.0 && !(o.prob_hit() > 0.5 && o.prob_hit() < 1.0)) {
    return Status::InvalidArgument("octomap.prob_hit: must be in (0.5, 1), got " +
                                   Number(o.prob_hit()));
  }
  MAV_RETURN_IF_ERROR(same(o.prob_hit(), used.prob_hit, "octomap.prob_hit"));
  if (o.prob_miss() != 0.0 && !(o.prob_miss() > 0.0 && o.prob_miss() < 0.5)) {
    return Status::InvalidArgument("octomap.prob_miss: must be in (0, 0.5), got " +
                                   Number(o.prob_miss()));
  }
  MAV_RETURN_IF_ERROR(same(o.prob_miss(), used.prob_miss, "octomap.prob_miss"));
  if (o.num_disparities() % 16 != 0 || o.num_disparities() > 512) {
    return Status::InvalidArgument(
        "octomap.num_disparities: must be a multiple of 16 in [16, 512], got " +
        std::to_string(o.num_disparities()));
  }
  MAV_RETURN_IF_ERROR(same(o.num_disparities(), used.num_disparities, "octomap.num_disparities"));
  if (o.pixel_step() > 64) {
    return Status::InvalidArgument("octomap.pixel_step: must be in [1, 64], got " +
                                   std::to_string(o.pixel_step()));
  }
  MAV_RETURN_IF_ERROR(same(o.pixel_step(), used.pixel_stride, "octomap.pixel_step"));
  return out;
}

void ToProto(const MapStats& stats, v1::BuildMapResponse* out) {
  out->set_method(ToProto(stats.method));
  out->set_keyframes(stats.keyframes);
  out->set_points(stats.points);
  out->set_tetrahedra(stats.tetrahedra);
  out->set_mesh_vertices(stats.mesh_vertices);
  out->set_mesh_faces(stats.mesh_faces);
  v1::OccupancyStats* o = out->mutable_occupancy();
  o->set_resolution_m(stats.geometry.resolution);
  ToProto(BoundsOf(stats.geometry), o->mutable_bounds());
  o->set_occupied_voxels(static_cast<uint64_t>(stats.occupied_voxels));
  o->set_free_voxels(static_cast<uint64_t>(stats.free_voxels));
  o->set_unknown_voxels(static_cast<uint64_t>(stats.unknown_voxels));
  v1::MappingTiming* t = out->mutable_timing();
  t->set_total_ms(stats.timing.total_ms);
  t->set_features_ms(stats.timing.features_ms);
  t->set_dense_stereo_ms(stats.timing.dense_stereo_ms);
  t->set_delaunay_ms(stats.timing.delaunay_ms);
  t->set_graph_cut_ms(stats.timing.graph_cut_ms);
  t->set_surface_ms(stats.timing.surface_ms);
  t->set_insertion_ms(stats.timing.insertion_ms);
  t->set_rasterize_ms(stats.timing.rasterize_ms);
}

void ToProto(const KeyframeResult& result, v1::InsertKeyframeResponse* out) {
  out->set_accepted(result.accepted);
  out->set_keyframe_index(result.keyframe_index);
  out->set_features(result.features);
  out->set_points_total(result.points_total);
  out->set_processing_ms(result.processing_ms);
}

void ToProto(const MapperStatus& status, v1::MappingStatus* out) {
  out->set_session_active(status.session_active);
  out->set_pose_source(ToProto(status.pose_source));
  out->set_frames_seen(status.frames_seen);
  out->set_keyframes(status.keyframes);
  out->set_points(status.points);
  out->set_frames_without_pose(status.frames_without_pose);
  out->set_building(status.building);
  if (status.building) {
    out->mutable_build_progress()->set_stage(status.build_stage);
    out->mutable_build_progress()->set_fraction(status.build_fraction);
    out->mutable_build_progress()->set_elapsed_s(status.build_elapsed_s);
  }
  for (const MapStats& map : status.maps) ToProto(map, out->add_maps());
  ToProto(status.keyframe_ms, out->mutable_keyframe_ms());
  out->set_worker_busy(status.worker_busy);
  out->set_queue_depth(status.queue_depth);
}

v1::CollisionState ToProto(mapping::BoxQuery::Answer answer, bool unknown_is_collision) {
  switch (answer) {
    case mapping::BoxQuery::Answer::kFree:
      return v1::COLLISION_STATE_FREE;
    case mapping::BoxQuery::Answer::kCollision:
      return v1::COLLISION_STATE_COLLISION;
    case mapping::BoxQuery::Answer::kUnknown:
      return unknown_is_collision ? v1::COLLISION_STATE_COLLISION : v1::COLLISION_STATE_UNKNOWN;
  }
  return v1::COLLISION_STATE_UNSPECIFIED;
}

}  // namespace mav::mapping_service
