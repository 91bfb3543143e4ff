#pragma once
// The mapping pipeline of Holzmann et al., "Performance Evaluation of Vision-Based Algorithms for
// MAVs" (OAGM 2015), Section 2.2, with the paper's baseline beside it on the same keyframes:
//
//   frames (rectified pair + pose) --KeyframeSelector--> keyframes --+--> sparse-mesh:
//                                                                     |     SparsePointCloud (~100
//                                                                     |     stereo points / kf,
//                                                                     |     merged with visibility)
//                                                                     |     -> BuildMesh (Labatut
//                                                                     |     et al. 2007)
//                                                                     |     -> MeshToOccupancy
//                                                                     +--> octomap: OctomapMapper
//                                                                           (dense SGBM + OctoMap)
//                                                                           -> ToGrid
//
// Both mappers see exactly the same keyframes. Per keyframe only the per-keyframe work runs
// (sparse stereo points, dense stereo + ray casting); the meshing and both grid conversions run
// in Build() (one method) or Finish() (both, for the paper's tables), after the last frame, as in
// the paper ("After receiving the last frame, we put all stored data into a multi-view meshing
// algorithm"). The mapping service's BuildMap runs Build(): the service and mav-eval produce the
// same grid from the same keyframes.
//
// Runtime of a method for the whole data set (the paper's Table 3) = the sum of its per-keyframe
// work + its Finish() work, measured with a monotonic wall clock. Reading and rectifying the
// images and the keyframe selection are shared by both methods and counted in neither.
//
// OpenCV stays out of this header (cv::Mat is forward-declared). Not thread-safe.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "mav/camera/stereo.h"
#include "mav/common/status.h"
#include "mav/common/termination.h"
#include "mav/geometry/se3.h"
#include "mav/mapping/delaunay_graph_cut.h"
#include "mav/mapping/keyframes.h"
#include "mav/mapping/mesh_to_grid.h"
#include "mav/mapping/octomap_mapper.h"
#include "mav/mapping/sparse_points.h"
#include "mav/mapping/types.h"

namespace cv {
class Mat;
}

namespace mav::mapping {

enum class MappingMethod { kSparseMesh, kOctomap };
const char* MappingMethodName(MappingMethod method);  // "sparse-mesh", "octomap"

// What a map preference (MapPreference, delaunay_graph_cut.h) sets besides the mesher's weights
// (docs/mapping.md, "Missed-collision budget"):
//  * kSafety: voxels touching the mesh are occupied (MeshToGridOptions::occupy_surface_voxels, the
//    conservative rasterisation the ground truth uses too) and the unchecked single-view points are
//    left out of the mesh (SparsePointsOptions::keep_unchecked_points = false; their lines of sight
//    still free space), and far single-view points seen through a surface are dropped
//    (OcclusionCheckOptions below). With the weak surfaces this brings the full presets' missed
//    collisions to 0.12-0.47 % (two seeds; the budget of 0.5 % is met on all six).
//  * kMcc: none of these, i.e. the best collision-check MCC.
// The pipeline's grid options (traversal rule, thick lines of sight) with the preference applied.
MeshToGridOptions MeshToGridOptionsFor(MapPreference preference);
bool KeepUncheckedPointsFor(MapPreference preference);

// The occlusion check of far single-view points (docs/mapping.md, "Occlusion check of far
// single-view points"). A point seen by one keyframe only, from farther than `min_range_m`, has a
// depth too uncertain to trust on its own (stereo depth noise grows as Z^2: a quarter pixel of
// disparity is ~3 cm at 2.5 m and ~12 cm at 5 m on EuRoC's rig, against the mesher's 5 cm sink
// distance). Build() then meshes in two passes: first the other points alone, rasterised like the
// map; a far single-view point whose line of sight crosses an occupied voxel of that first grid
// more than `margin_m` before the point was seen through a surface and is left out of the final
// mesh (PointsSeenThroughSurfaces, mesh_to_grid.h; its line of sight still frees space up to the
// first surface, as every rejected point's does). The others fill in what the first pass lacked.
// This removes the stereo mismatches on room-hard's textureless ceiling, triangulated 0.2-1.4 m
// behind it, whose lines of sight freed the slab: the missed collisions there fall from 0.78 / 0.59
// % to 0.12 / 0.31 %.
struct OcclusionCheckOptions {
  bool enabled = false;
  double min_range_m = 2.5;  // [m], > 0
  double margin_m = 0.3;     // [m], >= 0: a half-pixel disparity error at 5.5 m
  // False with the offending field named in *why ("min_range_m: ...").
  bool IsValid(std::string* why) const;
};
OcclusionCheckOptions OcclusionCheckFor(MapPreference preference);  // on for kSafety only

struct MappingPipelineOptions {
  bool run_sparse_mesh = true;
  bool run_octomap = true;
  KeyframeOptions keyframes;
  SparsePointsOptions sparse = [] {
    SparsePointsOptions o;
    o.keep_unchecked_points = KeepUncheckedPointsFor(MapPreference::kSafety);
    return o;
  }();
  // The stack's default map favours safety (MapPreference::kSafety: weakly supported surfaces,
  // the conservative grid and only checked points; docs/mapping.md, "Missed-collision budget");
  // ApplyMapPreference(MapPreference::kMcc, ...) gives the best-MCC map, the paper's weights.
  MeshingOptions meshing = MeshingOptionsFor(MapPreference::kSafety);
  // free_requires_traversal on: in the rendered rooms the noisy ceiling and wall points (a few cm
  // of depth noise seen at grazing angles) give large outside-labelled cells that reach into the
  // solid slabs; only cells a line of sight actually crossed are free space that was observed.
  // On the full room-easy preset this cut missed collisions from 6.6 % to 1.0 % and raised the
  // MCC from 0.73 to 0.76 (docs/mapping.md, "Pipeline").
  // carve_radius_voxels = 1: thick lines of sight free the small untraversed outside cells just
  // in front of the surfaces (full presets: room-easy 0.783 -> 0.805, medium 0.716 -> 0.745, hard
  // 0.619 -> 0.684 MCC; docs/results/mapping-history.md, "Fourth pass").
  MeshToGridOptions mesh_to_grid = MeshToGridOptionsFor(MapPreference::kSafety);
  OcclusionCheckOptions occlusion_check = OcclusionCheckFor(MapPreference::kSafety);
  OctomapMapperOptions octomap;
  // Free space also from the verified stereo matches that were not selected as points
  // (SparsePointCloud::SightPoints()); false: only from the points (AllPoints(), the rejected
  // single-view points included).
  bool extra_lines_of_sight = true;

  // False with the offending field named in *why ("sparse.max_depth_m: ...", "run_sparse_mesh/
  // run_octomap: at least one method must run").
  bool IsValid(std::string* why) const;
};

// Sets meshing, mesh_to_grid, occlusion_check and sparse.keep_unchecked_points of `options` to the
// preference's.
void ApplyMapPreference(MapPreference preference, MappingPipelineOptions* options);

// Wall-clock seconds of the sparse-mesh method, per stage.
struct SparseMeshTiming {
  double extraction_s = 0;       // feature extraction, all keyframes
  double matching_s = 0;         // stereo matching + sub-pixel refinement, all keyframes
  double merging_s = 0;          // re-observation, selection, triangulation, all keyframes
  double occlusion_check_s = 0;  // the first pass of the occlusion check (mesh, grid, check)
  double meshing_s = 0;          // BuildMesh (Delaunay + visibility + graph cut + extraction)
  double to_grid_s = 0;          // MeshToOccupancy
  double total_s = 0;            // the sum: the whole data set
};

// Wall-clock seconds of the OctoMap baseline, per stage.
struct OctomapTiming {
  double disparity_s = 0;  // dense stereo, all keyframes
  double points_s = 0;     // disparity -> world points, all keyframes
  double insertion_s = 0;  // OctoMap ray casting, all keyframes
  double finish_s = 0;     // final pruning
  double to_grid_s = 0;    // ToGrid
  double total_s = 0;      // the sum: the whole data set
};

struct MappingOutput {
  int64_t frames = 0;     // frames offered (AddFrame / ConsiderFrame) or keyframes inserted
  int64_t keyframes = 0;  // keyframes inserted
  std::vector<geometry::SE3> keyframe_poses;  // T_world_cam of every keyframe

  bool has_sparse_mesh = false;
  std::vector<MapPoint> points;              // the global sparse cloud with visibility
  std::vector<KeyframeView> keyframe_views;  // camera centres (ids index keyframe_poses)
  MeshingResult meshing;                     // mesh, labelled tetrahedra, stats
  OccupancyGrid sparse_mesh_grid;            // on the geometry given to Finish()
  int64_t lines_of_sight = 0;                // given to MeshToOccupancy (SightPoints())
  int64_t occlusion_checked_points = 0;      // MethodMap's
  int64_t occluded_points = 0;
  SparsePointsStats sparse_stats;
  SparseMeshTiming sparse_mesh_timing;

  bool has_octomap = false;
  OccupancyGrid octomap_grid;  // on the geometry given to Finish()
  OctomapMapperStats octomap_stats;
  OctomapTiming octomap_timing;
};

// How a built grid labels the voxels that no ray or surface explained.
enum class UnknownHandling { kKeepUnknown, kAsOccupied, kAsFree };

// Options of one Build().
struct BuildOptions {
  // Sparse mesh: the mesher's options (unset: the pipeline's) and the minimum number of keyframes
  // that saw a point for it to be meshed ([1, 100]; the lines of sight are kept for all).
  std::optional<MeshingOptions> meshing;
  int min_visibility = 1;
  // The grid rules, whether unchecked single-view points are meshed (when fewer than 4 checked
  // points exist, e.g. after one keyframe, the unchecked ones are) and the occlusion check (unset:
  // the pipeline's).
  std::optional<MeshToGridOptions> mesh_to_grid;
  std::optional<bool> keep_unchecked_points;
  std::optional<OcclusionCheckOptions> occlusion_check;
  // Both methods: the unknown voxels of the built grid kept, or made occupied or free (the
  // mapping service's BuildMapRequest.unknown).
  UnknownHandling unknown = UnknownHandling::kKeepUnknown;

  // All four from a map preference (the mapping service's BuildMapRequest.prefer).
  static BuildOptions For(MapPreference preference);
  bool IsValid(std::string* why) const;
};

// One method's map from the keyframes inserted so far.
struct MethodMap {
  MappingMethod method = MappingMethod::kSparseMesh;
  int64_t keyframes = 0;
  OccupancyGrid grid;  // on the geometry given to Build(), after BuildOptions::unknown
  // The grid's voxels by state.
  int64_t occupied_voxels = 0;
  int64_t free_voxels = 0;
  int64_t unknown_voxels = 0;

  // Sparse mesh only.
  std::vector<MapPoint> points;              // the points meshed (after min_visibility and the
                                             // occlusion check)
  std::vector<KeyframeView> keyframe_views;  // camera centres (ids index the keyframes)
  MeshingResult meshing;                     // mesh, labelled tetrahedra, stats
  int64_t lines_of_sight = 0;                // given to MeshToOccupancy (SightPoints())
  // The occlusion check: far single-view points checked, and of them left out (seen through a
  // surface of the first pass).
  int64_t occlusion_checked_points = 0;
  int64_t occluded_points = 0;

  // Octomap only: range points inserted over all keyframes.
  int64_t range_points = 0;

  // Wall time, ms: the method's per-keyframe work over all keyframes so far, and this build's
  // stages (occlusion_check = its first pass: mesh, grid and check; meshing = Delaunay +
  // visibility + graph cut + surface; prune = the octree's final pruning; to_grid = mesh or octree
  // -> grid).
  double per_keyframe_ms = 0;
  double occlusion_check_ms = 0;
  double meshing_ms = 0;
  double prune_ms = 0;
  double to_grid_ms = 0;
  double build_ms = 0;
};

class MappingPipeline {
 public:
  // InvalidArgument naming the field for an invalid rig ("rig: ...") or options ("options.<f>").
  static Result<MappingPipeline> Create(const camera::RectifiedStereo& rig,
                                        const MappingPipelineOptions& options = {});

  MappingPipeline(MappingPipeline&&) noexcept;
  MappingPipeline& operator=(MappingPipeline&&) noexcept;
  ~MappingPipeline();

  // Keyframe selection on a pose stream: true if the frame with this pose (rectified left camera
  // in the world) becomes a keyframe; the caller then passes its images to InsertKeyframe. Lets
  // a reader load and rectify only the keyframes' images. InvalidArgument for a non-finite pose.
  Result<bool> ConsiderFrame(const geometry::SE3& T_world_cam);

  // Integrates one keyframe into both mappers (no selection). `left`, `right`: rectified CV_8UC1
  // images of the rig's size. InvalidArgument naming "left"/"right"/"T_world_cam" leaves both
  // maps unchanged.
  Status InsertKeyframe(const cv::Mat& left, const cv::Mat& right,
                        const geometry::SE3& T_world_cam);

  // ConsiderFrame + InsertKeyframe if selected. Returns whether the frame became a keyframe.
  Result<bool> AddFrame(const cv::Mat& left, const cv::Mat& right,
                        const geometry::SE3& T_world_cam);

  // The map of one method on `geometry`: for the sparse mesh, meshing (Labatut et al. 2007) of
  // the points seen by >= min_visibility keyframes and MeshToOccupancy with every line of sight;
  // for OctoMap, the octree's pruning and ToGrid. Keyframes keep arriving afterwards; Build may be
  // called again. FailedPrecondition without keyframes, for a method the pipeline does not run,
  // or with fewer than 4 points to mesh ("empty map: ..."); InvalidArgument naming the field
  // ("geometry: ...", "meshing.<f>: ..."); the mesher's errors with "sparse-mesh: " in front.
  // The grid's unknown voxels are then handled as options.unknown says and its voxels counted
  // (the mapping service publishes this grid as it is). `termination` is checked between the
  // stages (DEADLINE_EXCEEDED / CANCELLED: nothing is kept); `progress` reports "occlusion check"
  // (0.05, only when it runs), "meshing" (0.1), "mesh to grid" (0.7), "octree to grid" (0.2).
  Result<MethodMap> Build(MappingMethod method, const GridGeometry& geometry,
                          const BuildOptions& options = {}, const Termination& termination = {},
                          const ProgressCallback& progress = {});

  // The grid around the keyframe camera centres and the points seen by >= min_visibility
  // keyframes (the unchecked ones included, whatever the preference), grown by `padding_m`
  // (GridGeometryAround). The geometry only: check its
  // num_voxels() against a limit before building.
  GridGeometry GeometryAround(double resolution, double padding_m, int min_visibility = 1) const;

  // Build() of every method the pipeline runs, with the pipeline's options, on `geometry` (pass
  // the ground truth's to compare voxel by voxel), with the paper's whole-data-set timing.
  Result<MappingOutput> Finish(const GridGeometry& geometry);

  int64_t num_frames() const;
  int64_t num_keyframes() const;
  const MappingPipelineOptions& options() const;
  // The baseline's octree (for WriteBinary); null when options.run_octomap is false.
  const OctomapMapper* octomap_mapper() const;
  const SparsePointCloud* sparse_points() const;

  // Forgets everything (options unchanged).
  void Reset();

 private:
  struct Impl;
  explicit MappingPipeline(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace mav::mapping
