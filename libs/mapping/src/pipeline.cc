#include "mav/mapping/pipeline.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <optional>
#include <utility>

#include <opencv2/core/mat.hpp>

#include "mav/common/time.h"

namespace mav::mapping {
namespace {

// Validates like OctomapMapper::InsertKeyframe so a bad pair never reaches either mapper.
Status CheckImage(const cv::Mat& image, const camera::RectifiedStereo& rig, const char* name) {
  const std::string n = name;
  if (image.empty()) return Status::InvalidArgument(n + ": empty image");
  if (image.type() != CV_8UC1) {
    return Status::InvalidArgument(n + ": expected CV_8UC1 (8-bit grey), got type " +
                                   std::to_string(image.type()));
  }
  if (image.cols != rig.width || image.rows != rig.height) {
    return Status::InvalidArgument(n + ": size " + std::to_string(image.cols) + "x" +
                                   std::to_string(image.rows) + " differs from the rig " +
                                   std::to_string(rig.width) + "x" + std::to_string(rig.height));
  }
  return Status::Ok();
}

localization::ImageView View(const cv::Mat& image) {
  return {image.data, image.cols, image.rows, static_cast<int>(image.step[0])};
}

}  // namespace

const char* MappingMethodName(MappingMethod method) {
  switch (method) {
    case MappingMethod::kSparseMesh:
      return "sparse-mesh";
    case MappingMethod::kOctomap:
      return "octomap";
  }
  return "?";
}

bool MappingPipelineOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  std::string sub;
  if (!run_sparse_mesh && !run_octomap) {
    return fail("run_sparse_mesh/run_octomap: at least one method must run");
  }
  if (!keyframes.IsValid(&sub)) return fail("keyframes." + sub);
  if (!sparse.IsValid(&sub)) return fail("sparse." + sub);
  if (!meshing.IsValid(&sub)) return fail("meshing." + sub);
  if (!mesh_to_grid.IsValid(&sub)) return fail("mesh_to_grid." + sub);
  if (!occlusion_check.IsValid(&sub)) return fail("occlusion_check." + sub);
  if (!octomap.IsValid(&sub)) return fail("octomap." + sub);
  return true;
}

struct MappingPipeline::Impl {
  camera::RectifiedStereo rig;
  MappingPipelineOptions options;
  KeyframeSelector selector;
  std::optional<SparsePointCloud> sparse;
  std::optional<OctomapMapper> octomap;
  std::vector<geometry::SE3> keyframe_poses;
  int64_t frames = 0;

  Impl(const camera::RectifiedStereo& r, const MappingPipelineOptions& o)
      : rig(r), options(o), selector(o.keyframes) {}
};

MappingPipeline::MappingPipeline(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
MappingPipeline::MappingPipeline(MappingPipeline&&) noexcept = default;
MappingPipeline& MappingPipeline::operator=(MappingPipeline&&) noexcept = default;
MappingPipeline::~MappingPipeline() = default;

Result<MappingPipeline> MappingPipeline::Create(const camera::RectifiedStereo& rig,
                                                const MappingPipelineOptions& options) {
  std::string why;
  if (!rig.IsValid(&why)) return Status::InvalidArgument("rig: " + why);
  if (!options.IsValid(&why)) return Status::InvalidArgument("options." + why);
  auto impl = std::make_unique<Impl>(rig, options);
  if (options.run_sparse_mesh) {
    MAV_ASSIGN_OR_RETURN(SparsePointCloud sparse, SparsePointCloud::Create(rig, options.sparse));
    impl->sparse.emplace(std::move(sparse));
  }
  if (options.run_octomap) {
    MAV_ASSIGN_OR_RETURN(OctomapMapper octomap, OctomapMapper::Create(options.octomap));
    impl->octomap.emplace(std::move(octomap));
  }
  return MappingPipeline(std::move(impl));
}

Result<bool> MappingPipeline::ConsiderFrame(const geometry::SE3& T_world_cam) {
  if (!T_world_cam.Translation().allFinite() || !T_world_cam.Rotation().coeffs().allFinite()) {
    return Status::InvalidArgument("T_world_cam: non-finite pose");
  }
  ++impl_->frames;
  return impl_->selector.Consider(T_world_cam);
}

Status MappingPipeline::InsertKeyframe(const cv::Mat& left, const cv::Mat& right,
                                       const geometry::SE3& T_world_cam) {
  MAV_RETURN_IF_ERROR(CheckImage(left, impl_->rig, "left"));
  MAV_RETURN_IF_ERROR(CheckImage(right, impl_->rig, "right"));
  if (!T_world_cam.Translation().allFinite() || !T_world_cam.Rotation().coeffs().allFinite()) {
    return Status::InvalidArgument("T_world_cam: non-finite pose");
  }
  if (impl_->sparse) {
    auto id = impl_->sparse->AddKeyframe(View(left), View(right), T_world_cam);
    if (!id.ok()) return id.status();
  }
  if (impl_->octomap) {
    MAV_RETURN_IF_ERROR(impl_->octomap->InsertKeyframe(left, right, impl_->rig, T_world_cam));
  }
  impl_->keyframe_poses.push_back(T_world_cam);
  return Status::Ok();
}

Result<bool> MappingPipeline::AddFrame(const cv::Mat& left, const cv::Mat& right,
                                       const geometry::SE3& T_world_cam) {
  MAV_ASSIGN_OR_RETURN(const bool is_keyframe, ConsiderFrame(T_world_cam));
  if (is_keyframe) MAV_RETURN_IF_ERROR(InsertKeyframe(left, right, T_world_cam));
  return is_keyframe;
}

MeshToGridOptions MeshToGridOptionsFor(MapPreference preference) {
  MeshToGridOptions o;
  o.free_requires_traversal = true;
  o.carve_radius_voxels = 1;
  o.occupy_surface_voxels = preference == MapPreference::kSafety;
  return o;
}

bool KeepUncheckedPointsFor(MapPreference preference) {
  return preference != MapPreference::kSafety;
}

OcclusionCheckOptions OcclusionCheckFor(MapPreference preference) {
  OcclusionCheckOptions o;
  o.enabled = preference == MapPreference::kSafety;
  return o;
}

bool OcclusionCheckOptions::IsValid(std::string* why) const {
  if (!(min_range_m > 0.0) || !std::isfinite(min_range_m)) {
    if (why != nullptr) *why = "min_range_m: must be finite and > 0 [m]";
    return false;
  }
  if (!(margin_m >= 0.0) || !std::isfinite(margin_m)) {
    if (why != nullptr) *why = "margin_m: must be finite and >= 0 [m]";
    return false;
  }
  return true;
}

BuildOptions BuildOptions::For(MapPreference preference) {
  BuildOptions o;
  o.meshing = MeshingOptionsFor(preference);
  o.mesh_to_grid = MeshToGridOptionsFor(preference);
  o.keep_unchecked_points = KeepUncheckedPointsFor(preference);
  o.occlusion_check = OcclusionCheckFor(preference);
  return o;
}

void ApplyMapPreference(MapPreference preference, MappingPipelineOptions* options) {
  const BuildOptions preferred = BuildOptions::For(preference);
  options->meshing = *preferred.meshing;
  options->mesh_to_grid = *preferred.mesh_to_grid;
  options->sparse.keep_unchecked_points = *preferred.keep_unchecked_points;
  options->occlusion_check = *preferred.occlusion_check;
}

bool BuildOptions::IsValid(std::string* why) const {
  std::string sub;
  if (meshing.has_value() && !meshing->IsValid(&sub)) {
    if (why != nullptr) *why = "meshing." + sub;
    return false;
  }
  if (mesh_to_grid.has_value() && !mesh_to_grid->IsValid(&sub)) {
    if (why != nullptr) *why = "mesh_to_grid." + sub;
    return false;
  }
  if (occlusion_check.has_value() && !occlusion_check->IsValid(&sub)) {
    if (why != nullptr) *why = "occlusion_check." + sub;
    return false;
  }
  if (min_visibility < 1 || min_visibility > 100) {
    if (why != nullptr) {
      *why = "min_visibility: must be in [1, 100], got " + std::to_string(min_visibility);
    }
    return false;
  }
  return true;
}

namespace {

std::vector<MapPoint> VisiblePoints(const SparsePointCloud& sparse, int min_visibility,
                                    bool keep_unchecked_points) {
  std::vector<MapPoint> points = sparse.Points(keep_unchecked_points);
  if (min_visibility > 1) {
    std::erase_if(points, [&](const MapPoint& p) {
      return static_cast<int>(p.keyframes.size()) < min_visibility;
    });
  }
  return points;
}

// The occlusion check of far single-view points (OcclusionCheckOptions): a first mesh and grid of
// the other points, then the far single-view points seen through its surfaces are dropped from
// out->points (the others keep their order).
Status DropPointsSeenThroughSurfaces(
    const std::string& name, const std::vector<MapPoint>& sight_points,
    const GridGeometry& geometry, const MeshingOptions& meshing_options,
    const MeshToGridOptions& grid_options, const OcclusionCheckOptions& occlusion,
    const Termination& termination, const std::function<void(const char*, double)>& report,
    MethodMap* out) {
  const int64_t stage = MonotonicNowNs();
  std::vector<MapPoint> trusted, far_single_view;
  std::vector<size_t> far_index;  // into out->points
  for (size_t i = 0; i < out->points.size(); ++i) {
    const MapPoint& p = out->points[i];
    // SparsePointCloud's keyframe ids are their indices.
    if (p.keyframes.size() == 1 &&
        (out->keyframe_views[static_cast<size_t>(p.keyframes[0])].center_world - p.p_world).norm() >
            occlusion.min_range_m) {
      far_single_view.push_back(p);
      far_index.push_back(i);
    } else {
      trusted.push_back(p);
    }
  }
  out->occlusion_checked_points = static_cast<int64_t>(far_single_view.size());
  // Nothing to check, or too few trusted points for a first mesh: every point is meshed.
  if (!far_single_view.empty() && trusted.size() >= 4) {
    report("occlusion check (first pass: mesh and grid of the trusted points)", 0.05);
    Result<MeshingResult> first = BuildMesh(trusted, out->keyframe_views, meshing_options);
    if (!first.ok()) {
      return Status(first.status().code(),
                    name + " (occlusion check): " + first.status().message());
    }
    MAV_RETURN_IF_ERROR(termination.Check("BuildMap (" + name + ", after the first pass)"));
    // Only the occupied voxels matter here. Without a safety margin (which grows occupied
    // voxels into free ones) the lines of sight only turn unknown voxels free, so the first
    // grid skips them: the same occupied voxels, and the first pass costs a quarter
    // (room-easy: 0.33 s instead of 1.30 s).
    MeshToGridOptions first_options = grid_options;
    if (first_options.occupied_margin_voxels == 0) {
      first_options.carve_lines_of_sight = false;
      first_options.free_near_ray_voxels = -1;
    }
    Result<OccupancyGrid> first_grid =
        MeshToOccupancy(*first, sight_points, out->keyframe_views, geometry, first_options);
    if (!first_grid.ok()) {
      return Status(first_grid.status().code(),
                    name + " (occlusion check): " + first_grid.status().message());
    }
    Result<std::vector<bool>> seen_through = PointsSeenThroughSurfaces(
        *first_grid, far_single_view, out->keyframe_views, occlusion.margin_m);
    if (!seen_through.ok()) {
      return Status(seen_through.status().code(),
                    name + " (occlusion check): " + seen_through.status().message());
    }
    // Drop the points seen through a surface; the others keep their order.
    std::vector<bool> drop(out->points.size(), false);
    for (size_t i = 0; i < far_index.size(); ++i) {
      if ((*seen_through)[i]) drop[far_index[i]] = true;
    }
    size_t kept = 0;
    for (size_t i = 0; i < out->points.size(); ++i) {
      if (drop[i]) continue;
      if (kept != i) out->points[kept] = std::move(out->points[i]);
      ++kept;
    }
    out->occluded_points = static_cast<int64_t>(out->points.size() - kept);
    out->points.resize(kept);
  }
  out->occlusion_check_ms = MsSince(stage);
  MAV_RETURN_IF_ERROR(termination.Check("BuildMap (" + name + ", after the occlusion check)"));
  return Status::Ok();
}

// The grid's unknown voxels as `unknown` says, then its voxels counted.
void ApplyUnknownHandling(UnknownHandling unknown, MethodMap* map) {
  if (unknown != UnknownHandling::kKeepUnknown) {
    const VoxelState to =
        unknown == UnknownHandling::kAsOccupied ? VoxelState::kOccupied : VoxelState::kFree;
    std::vector<VoxelState>& states = map->grid.mutable_states();
    std::replace(states.begin(), states.end(), VoxelState::kUnknown, to);
  }
  map->occupied_voxels = map->grid.Count(VoxelState::kOccupied);
  map->free_voxels = map->grid.Count(VoxelState::kFree);
  map->unknown_voxels = map->grid.Count(VoxelState::kUnknown);
}

}  // namespace

GridGeometry MappingPipeline::GeometryAround(double resolution, double padding_m,
                                             int min_visibility) const {
  std::vector<MapPoint> points;
  std::vector<KeyframeView> views;
  if (impl_->sparse) {
    // Every point either preference may mesh, so one box fits both.
    points = VisiblePoints(*impl_->sparse, min_visibility, /*keep_unchecked_points=*/true);
    views = impl_->sparse->keyframes();
  } else {
    for (size_t i = 0; i < impl_->keyframe_poses.size(); ++i) {
      views.push_back({static_cast<int>(i), impl_->keyframe_poses[i].Translation()});
    }
  }
  return GridGeometryAround(points, views, resolution, padding_m);
}

Result<MethodMap> MappingPipeline::Build(MappingMethod method, const GridGeometry& geometry,
                                         const BuildOptions& options,
                                         const Termination& termination,
                                         const ProgressCallback& progress) {
  const int64_t start = MonotonicNowNs();
  std::string why;
  if (!geometry.IsValid(&why)) return Status::InvalidArgument("geometry: " + why);
  if (!options.IsValid(&why)) return Status::InvalidArgument(why);
  if (impl_->keyframe_poses.empty()) {
    return Status::FailedPrecondition(
        "empty map: no keyframes yet (stream frames with poses or insert keyframes first)");
  }
  const std::string name = MappingMethodName(method);
  auto report = [&](const char* stage, double fraction) {
    if (progress) progress(stage, fraction);
  };
  MethodMap out;
  out.method = method;
  out.keyframes = static_cast<int64_t>(impl_->keyframe_poses.size());
  if (method == MappingMethod::kSparseMesh) {
    if (!impl_->sparse) return Status::FailedPrecondition("the pipeline runs no sparse mesher");
    const SparsePointCloud& sparse = *impl_->sparse;
    const bool keep_unchecked =
        options.keep_unchecked_points.value_or(impl_->options.sparse.keep_unchecked_points);
    out.points = VisiblePoints(sparse, options.min_visibility, keep_unchecked);
    // A session too short to check any point (a single keyframe, say) meshes what it has.
    if (!keep_unchecked && out.points.size() < 4) {
      out.points = VisiblePoints(sparse, options.min_visibility, true);
    }
    out.keyframe_views = sparse.keyframes();
    if (out.points.size() < 4) {
      return Status::FailedPrecondition(
          "empty map: " + std::to_string(out.points.size()) +
          " sparse points (after min_visibility), the Delaunay triangulation needs 4");
    }
    out.per_keyframe_ms = sparse.stats().TotalMs();
    const MeshingOptions& meshing_options = options.meshing.value_or(impl_->options.meshing);
    const MeshToGridOptions& grid_options =
        options.mesh_to_grid.value_or(impl_->options.mesh_to_grid);
    // Free space from every line of sight: to the rejected single-view points too, and to the
    // verified stereo matches that became no point.
    const std::vector<MapPoint> sight_points =
        impl_->options.extra_lines_of_sight ? sparse.SightPoints() : sparse.AllPoints();
    for (const MapPoint& p : sight_points) {
      out.lines_of_sight += static_cast<int64_t>(p.keyframes.size());
    }
    const OcclusionCheckOptions& occlusion =
        options.occlusion_check.value_or(impl_->options.occlusion_check);
    if (occlusion.enabled) {
      MAV_RETURN_IF_ERROR(DropPointsSeenThroughSurfaces(name, sight_points, geometry,
                                                        meshing_options, grid_options, occlusion,
                                                        termination, report, &out));
    }
    report("meshing (Delaunay, visibility, graph cut)", 0.1);
    int64_t stage = MonotonicNowNs();
    Result<MeshingResult> meshing = BuildMesh(out.points, out.keyframe_views, meshing_options);
    if (!meshing.ok())
      return Status(meshing.status().code(), name + ": " + meshing.status().message());
    out.meshing = std::move(meshing).value();
    out.meshing_ms = MsSince(stage);
    MAV_RETURN_IF_ERROR(termination.Check("BuildMap (" + name + ", after meshing)"));
    report("mesh to occupancy grid", 0.7);
    stage = MonotonicNowNs();
    Result<OccupancyGrid> grid =
        MeshToOccupancy(out.meshing, sight_points, out.keyframe_views, geometry, grid_options);
    if (!grid.ok()) return Status(grid.status().code(), name + ": " + grid.status().message());
    out.grid = std::move(grid).value();
    out.to_grid_ms = MsSince(stage);
  } else {
    if (!impl_->octomap) return Status::FailedPrecondition("the pipeline runs no OctoMap mapper");
    OctomapMapper& octomap = *impl_->octomap;
    const double prune_before = octomap.stats().finish_ms;
    const OctomapMapperStats& stats = octomap.Finish();
    out.prune_ms = stats.finish_ms - prune_before;
    out.per_keyframe_ms = stats.TotalMs() - stats.finish_ms;
    out.range_points = stats.TotalPoints();
    MAV_RETURN_IF_ERROR(termination.Check("BuildMap (" + name + ", after pruning)"));
    report("octree to occupancy grid", 0.2);
    const int64_t stage = MonotonicNowNs();
    Result<OccupancyGrid> grid = octomap.ToGrid(geometry);
    if (!grid.ok()) return Status(grid.status().code(), name + ": " + grid.status().message());
    out.grid = std::move(grid).value();
    out.to_grid_ms = MsSince(stage);
  }
  ApplyUnknownHandling(options.unknown, &out);
  MAV_RETURN_IF_ERROR(termination.Check("BuildMap (" + name + ")"));
  out.build_ms = MsSince(start);
  return out;
}

Result<MappingOutput> MappingPipeline::Finish(const GridGeometry& geometry) {
  std::string why;
  if (!geometry.IsValid(&why)) return Status::InvalidArgument("geometry: " + why);
  if (impl_->keyframe_poses.empty()) {
    return Status::FailedPrecondition("Finish: no keyframe was inserted");
  }
  MappingOutput out;
  out.frames = std::max<int64_t>(impl_->frames, static_cast<int64_t>(impl_->keyframe_poses.size()));
  out.keyframes = static_cast<int64_t>(impl_->keyframe_poses.size());
  out.keyframe_poses = impl_->keyframe_poses;

  if (impl_->sparse) {
    MAV_ASSIGN_OR_RETURN(MethodMap map, Build(MappingMethod::kSparseMesh, geometry));
    const SparsePointCloud& sparse = *impl_->sparse;
    out.has_sparse_mesh = true;
    out.points = std::move(map.points);
    out.keyframe_views = std::move(map.keyframe_views);
    out.meshing = std::move(map.meshing);
    out.sparse_mesh_grid = std::move(map.grid);
    out.lines_of_sight = map.lines_of_sight;
    out.occlusion_checked_points = map.occlusion_checked_points;
    out.occluded_points = map.occluded_points;
    out.sparse_stats = sparse.stats();
    SparseMeshTiming& t = out.sparse_mesh_timing;
    t.extraction_s = sparse.stats().TotalExtractionMs() * 1e-3;
    t.matching_s = sparse.stats().TotalMatchingMs() * 1e-3;
    t.merging_s = sparse.stats().TotalMergingMs() * 1e-3;
    t.occlusion_check_s = map.occlusion_check_ms * 1e-3;
    t.meshing_s = map.meshing_ms * 1e-3;
    t.to_grid_s = map.to_grid_ms * 1e-3;
    t.total_s = map.per_keyframe_ms * 1e-3 + t.occlusion_check_s + t.meshing_s + t.to_grid_s;
  }

  if (impl_->octomap) {
    MAV_ASSIGN_OR_RETURN(MethodMap map, Build(MappingMethod::kOctomap, geometry));
    const OctomapMapperStats& stats = impl_->octomap->stats();
    out.has_octomap = true;
    out.octomap_grid = std::move(map.grid);
    out.octomap_stats = stats;
    OctomapTiming& t = out.octomap_timing;
    t.to_grid_s = map.to_grid_ms * 1e-3;
    t.disparity_s = stats.TotalDisparityMs() * 1e-3;
    t.points_s = stats.TotalPointsMs() * 1e-3;
    t.insertion_s = stats.TotalInsertionMs() * 1e-3;
    t.finish_s = stats.finish_ms * 1e-3;
    t.total_s = stats.TotalMs() * 1e-3 + t.to_grid_s;
  }
  return out;
}

int64_t MappingPipeline::num_frames() const { return impl_->frames; }
int64_t MappingPipeline::num_keyframes() const {
  return static_cast<int64_t>(impl_->keyframe_poses.size());
}
const MappingPipelineOptions& MappingPipeline::options() const { return impl_->options; }
const OctomapMapper* MappingPipeline::octomap_mapper() const {
  return impl_->octomap ? &*impl_->octomap : nullptr;
}
const SparsePointCloud* MappingPipeline::sparse_points() const {
  return impl_->sparse ? &*impl_->sparse : nullptr;
}

void MappingPipeline::Reset() {
  impl_->selector.Reset();
  if (impl_->sparse) impl_->sparse->Reset();
  if (impl_->octomap) impl_->octomap->Reset();
  impl_->keyframe_poses.clear();
  impl_->frames = 0;
}

}  // namespace mav::mapping
