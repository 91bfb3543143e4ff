// mav-eval mapping: runs the sparse multi-view mesher and the OctoMap + dense-stereo baseline on
// the same keyframes of an EuRoC directory with ground-truth poses and occupancy, scores both
// with the paper's collision-check protocol and prints its Tables 3 and 4 (Holzmann et al. 2015)
// with the paper's figures beside ours (mav/eval/mapping_eval.h).

#include <cmath>
#include <cstdio>
#include <functional>
#include <iostream>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "clients/plot/mapping_figure.h"
#include "commands.h"
#include "mav/common/file.h"
#include "mav/common/flags.h"
#include "mav/dataset/occupancy_io.h"
#include "mav/eval/mapping_eval.h"
#include "mav/mapping/mesh.h"
#include "output.h"

namespace mav::eval_cli {
namespace {

using mapping::MappingPipelineOptions;

constexpr const char* kCommand = "mav-eval mapping";

// The command line. `given` holds the pipeline flags' values (the defaults where not given);
// PipelineOptions turns them and --prefer into the pipeline's options.
struct MappingFlags {
  std::string data, method = "all", out_dir, json_path, prefer = "safety";
  int64_t max_frames = 0;
  bool no_figure = false, error_attribution = false;
  MappingPipelineOptions given;
  double keyframe_rotation_deg = mapping::KeyframeOptions().min_rotation_rad * 180.0 / M_PI;
  int64_t points_per_keyframe = given.sparse.target_points_per_keyframe;
  int64_t foreground_points = given.sparse.foreground_points_per_keyframe;
  int64_t carve_radius = given.mesh_to_grid.carve_radius_voxels;
  int64_t safety_margin = given.mesh_to_grid.occupied_margin_voxels;
  int64_t free_near_ray = given.mesh_to_grid.free_near_ray_voxels;
  int64_t verify_window = given.sparse.verify_window_keyframes;
  int64_t weak_surface_min_views = given.meshing.weak_surface_min_views;
  double occlusion_range_m = given.occlusion_check.min_range_m;
};

// The pipeline flags before --prefer in the help.
void AddPointAndGridFlags(FlagParser* flags, MappingFlags* f) {
  mapping::SparsePointsOptions& sparse = f->given.sparse;
  mapping::MeshToGridOptions& grid = f->given.mesh_to_grid;
  flags->AddInt64("points-per-keyframe", &f->points_per_keyframe,
                  "sparse-mesh: stereo points kept per keyframe (the paper: ~100)", 1, 100000);
  flags->AddDouble("stereo-uniqueness", &sparse.stereo_uniqueness_ratio,
                   "sparse-mesh: a stereo match's SAD must be at most this x the second best on "
                   "its row");
  flags->AddDouble("max-depth", &sparse.max_depth_m, "sparse-mesh: deepest stereo point [m]");
  flags->AddInt64("foreground-points", &f->foreground_points,
                  "sparse-mesh: extra points per keyframe at depth discontinuities (thin "
                  "structures; 0 = the paper's selection)",
                  0, 100000);
  flags->AddDouble("foreground-drop", &sparse.foreground_depth_drop,
                   "sparse-mesh: relative depth drop below the neighbourhood median for those");
  flags->AddDouble("mesh-sigma", &f->given.meshing.sigma,
                   "sparse-mesh: distance behind a point of its inside (sink) cell [m]");
  flags->AddBool("free-requires-traversal", &grid.free_requires_traversal,
                 "sparse-mesh: outside cells are free only where a line of sight crossed them");
  flags->AddInt64("carve-radius", &f->carve_radius,
                  "sparse-mesh: radius of the free-space lines of sight [voxels]", 0, 8);
  flags->AddDouble(
      "carve-thick-stop", &grid.thick_stop_m,
      "sparse-mesh: the thick part of a line of sight ends this far before its point [m]");
  flags->AddInt64("safety-margin", &f->safety_margin,
                  "sparse-mesh: free voxels this close to an occupied one become occupied [voxels]",
                  0, 8);
  flags->AddInt64("free-near-ray", &f->free_near_ray,
                  "sparse-mesh: outside cells are free only this close to a line of sight "
                  "[voxels; -1 = everywhere]",
                  -1, 8);
  flags->AddBool("extra-sight", &f->given.extra_lines_of_sight,
                 "sparse-mesh: free space also from the verified stereo matches not selected as "
                 "points");
  flags->AddInt64("verify-window", &f->verify_window,
                  "sparse-mesh: keyframes that check a single-view point (0 = no verification)", 0,
                  16);
  flags->AddBool("keep-unchecked", &sparse.keep_unchecked_points,
                 "sparse-mesh: mesh single-view points that no other keyframe could check "
                 "(default: from --prefer)");
  flags->AddDouble("mesh-lambda", &f->given.meshing.lambda_quality,
                   "sparse-mesh: weight of the surface-quality term");
}

// The pipeline flags after --prefer in the help.
void AddWeakSurfaceAndOcclusionFlags(FlagParser* flags, MappingFlags* f) {
  mapping::MeshingOptions& meshing = f->given.meshing;
  flags->AddDouble("weak-surface-weight", &meshing.weak_surface_weight,
                   "sparse-mesh: extra weight of a line of sight at a free-space-support jump "
                   "(Jancosek and Pajdla 2011; 0 = off; default: from --prefer)");
  flags->AddDouble("weak-surface-ratio", &meshing.weak_surface_ratio,
                   "sparse-mesh: a jump: support behind the point <= this x the support in front");
  flags->AddDouble("weak-surface-depth", &meshing.weak_surface_depth,
                   "sparse-mesh: distance behind the point searched for the least support [m]");
  flags->AddDouble("weak-surface-min-support", &meshing.weak_surface_min_support,
                   "sparse-mesh: least support in front of the point for a jump [lines of sight]");
  flags->AddInt64(
      "weak-surface-min-views", &f->weak_surface_min_views,
      "sparse-mesh: least number of observing keyframes of a point for the extra weight", 1,
      100000);
  flags->AddBool("all-reobservations", &f->given.sparse.apply_all_reobservations,
                 "sparse-mesh: apply every re-observation of an existing point, beyond the target");
  flags->AddBool("occupy-surface-voxels", &f->given.mesh_to_grid.occupy_surface_voxels,
                 "sparse-mesh: voxels touching the mesh are occupied (default: from --prefer)");
  flags->AddDouble("occlusion-check-range", &f->occlusion_range_m,
                   "sparse-mesh: single-view points farther than this from their keyframe are "
                   "dropped if seen through a surface of the other points' mesh [m] (0 = off; "
                   "default: from --prefer, on for safety)");
  flags->AddDouble("occlusion-check-margin", &f->given.occlusion_check.margin_m,
                   "sparse-mesh: the last part of such a line of sight that is not checked [m]");
}

FlagParser MakeFlags(MappingFlags* f) {
  FlagParser flags(
      "mav-eval mapping --data DIR [--method sparse-mesh|octomap|all] [--out DIR] [--json FILE] "
      "[--frames N]");
  flags.AddString("data", &f->data,
                  "EuRoC directory with ground-truth poses and DIR/ground_truth/occupancy.mavocc "
                  "(e.g. from mav-sim generate)");
  flags.AddString("method", &f->method, "sparse-mesh, octomap or all");
  flags.AddString("out", &f->out_dir,
                  "directory for mesh.ply, the occupancy grids (.bt) and mapping.png "
                  "(default DIR/eval)");
  flags.AddString("json", &f->json_path, "write every figure as {method: {metric: value}}");
  flags.AddInt64("frames", &f->max_frames, "use only the first N frames (0 = all)", 0,
                 std::numeric_limits<int64_t>::max());
  flags.AddDouble("keyframe-translation", &f->given.keyframes.min_translation_m,
                  "camera-centre distance to the last keyframe that makes a keyframe [m]");
  flags.AddDouble("keyframe-rotation-deg", &f->keyframe_rotation_deg,
                  "rotation to the last keyframe that makes a keyframe [deg]");
  flags.AddBool("no-figure", &f->no_figure, "do not draw mapping.png");
  flags.AddBool("error-attribution", &f->error_attribution,
                "also print where each map's wrong voxels are and what setting each class right "
                "would score");
  AddPointAndGridFlags(&flags, f);
  flags.AddString(
      "prefer", &f->prefer,
      "sparse-mesh: safety (fewer missed collisions: weakly supported surfaces, "
      "voxels touching the mesh occupied, only checked points meshed, far single-view points "
      "seen through a surface dropped; the default) "
      "or mcc (the paper's weights: the best MCC)");
  AddWeakSurfaceAndOcclusionFlags(&flags, f);
  return flags;
}

// The pipeline's options: the flags' values, then the preference's meshing, grid rules, point
// choice and occlusion check (ApplyMapPreference), then those of the preference's fields the
// command line set. InvalidArgument naming the flag.
Result<MappingPipelineOptions> PipelineOptions(const MappingFlags& f, const FlagParser& flags) {
  std::optional<mapping::MapPreference> preference;
  for (const mapping::MapPreference p :
       {mapping::MapPreference::kSafety, mapping::MapPreference::kMcc}) {
    if (f.prefer == mapping::MapPreferenceName(p)) preference = p;
  }
  if (!preference) {
    return Status::InvalidArgument("--prefer: '" + f.prefer + "' is not safety or mcc");
  }
  MappingPipelineOptions o = f.given;
  o.sparse.target_points_per_keyframe = static_cast<int>(f.points_per_keyframe);
  o.sparse.foreground_points_per_keyframe = static_cast<int>(f.foreground_points);
  o.sparse.verify_window_keyframes = static_cast<int>(f.verify_window);
  o.keyframes.min_rotation_rad = f.keyframe_rotation_deg * M_PI / 180.0;
  mapping::ApplyMapPreference(*preference, &o);
  const MappingPipelineOptions& g = f.given;
  const std::vector<std::pair<const char*, std::function<void()>>> overrides = {
      {"keep-unchecked", [&] { o.sparse.keep_unchecked_points = g.sparse.keep_unchecked_points; }},
      {"mesh-sigma", [&] { o.meshing.sigma = g.meshing.sigma; }},
      {"mesh-lambda", [&] { o.meshing.lambda_quality = g.meshing.lambda_quality; }},
      {"weak-surface-weight",
       [&] { o.meshing.weak_surface_weight = g.meshing.weak_surface_weight; }},
      {"weak-surface-ratio", [&] { o.meshing.weak_surface_ratio = g.meshing.weak_surface_ratio; }},
      {"weak-surface-depth", [&] { o.meshing.weak_surface_depth = g.meshing.weak_surface_depth; }},
      {"weak-surface-min-support",
       [&] { o.meshing.weak_surface_min_support = g.meshing.weak_surface_min_support; }},
      {"weak-surface-min-views",
       [&] { o.meshing.weak_surface_min_views = static_cast<int>(f.weak_surface_min_views); }},
      {"free-requires-traversal",
       [&] { o.mesh_to_grid.free_requires_traversal = g.mesh_to_grid.free_requires_traversal; }},
      {"carve-radius",
       [&] { o.mesh_to_grid.carve_radius_voxels = static_cast<int>(f.carve_radius); }},
      {"carve-thick-stop", [&] { o.mesh_to_grid.thick_stop_m = g.mesh_to_grid.thick_stop_m; }},
      {"safety-margin",
       [&] { o.mesh_to_grid.occupied_margin_voxels = static_cast<int>(f.safety_margin); }},
      {"free-near-ray",
       [&] { o.mesh_to_grid.free_near_ray_voxels = static_cast<int>(f.free_near_ray); }},
      {"occupy-surface-voxels",
       [&] { o.mesh_to_grid.occupy_surface_voxels = g.mesh_to_grid.occupy_surface_voxels; }},
      {"occlusion-check-margin", [&] { o.occlusion_check.margin_m = g.occlusion_check.margin_m; }},
      // 0 = off; any other non-positive value is rejected by OcclusionCheckOptions::IsValid.
      {"occlusion-check-range", [&] {
         o.occlusion_check.enabled = f.occlusion_range_m != 0.0;
         if (o.occlusion_check.enabled) o.occlusion_check.min_range_m = f.occlusion_range_m;
       }}};
  for (const auto& [flag, apply] : overrides) {
    if (flags.WasSet(flag)) apply();
  }
  if (f.method == "sparse-mesh") {
    o.run_octomap = false;
  } else if (f.method == "octomap") {
    o.run_sparse_mesh = false;
  } else if (f.method != "all") {
    return Status::InvalidArgument("--method: unknown method '" + f.method +
                                   "' (known: sparse-mesh, octomap, all)");
  }
  if (std::string why; !o.IsValid(&why)) {
    return Status::InvalidArgument("invalid flag value: " + why);
  }
  return o;
}

// The meshes, grids and figure in `out_dir`; the names written are appended to `written`.
Status WriteFiles(const MappingFlags& f, const std::string& out_dir, const eval::MappingSummary& s,
                  std::vector<std::string>* written) {
  MAV_RETURN_IF_ERROR(MakeDirectories(out_dir));
  const mapping::MappingOutput& out = s.output;
  auto write = [&](Status status, const std::string& file) {
    if (status.ok()) written->push_back(file);
    return status;
  };
  if (out.has_sparse_mesh) {
    MAV_RETURN_IF_ERROR(
        write(mapping::WritePly(out_dir + "/mesh.ply", out.meshing.mesh), "mesh.ply"));
    mapping::TriangleMesh cloud;
    for (const auto& p : out.points) cloud.vertices.push_back(p.p_world);
    MAV_RETURN_IF_ERROR(write(mapping::WritePly(out_dir + "/points.ply", cloud), "points.ply"));
    MAV_RETURN_IF_ERROR(
        write(dataset::WriteOctomapBt(out.sparse_mesh_grid, out_dir + "/sparse_mesh.bt"),
              "sparse_mesh.bt"));
    // The stack's own grid format as well: lossless, same geometry as the ground truth.
    MAV_RETURN_IF_ERROR(
        write(dataset::WriteMavocc(out.sparse_mesh_grid, out_dir + "/sparse_mesh.mavocc"),
              "sparse_mesh.mavocc"));
  }
  if (out.has_octomap) {
    MAV_RETURN_IF_ERROR(
        write(s.pipeline->octomap_mapper()->WriteBinary(out_dir + "/octomap.bt"), "octomap.bt"));
  }
  if (f.no_figure) return Status::Ok();
  const std::string title = "mapping: " + (s.preset.empty() ? s.data : s.preset) + ", " +
                            std::to_string(out.keyframes) + " keyframes, " +
                            std::to_string(out.points.size()) + " points";
  return write(plot::WriteMappingFigure(out_dir + "/mapping.png", title, out, s.truth),
               "mapping.png");
}

}  // namespace

int RunMapping(const std::vector<std::string>& args) {
  MappingFlags f;
  FlagParser flags = MakeFlags(&f);
  if (std::optional<int> done = ParseDataCommand(flags, args, kCommand, f.data)) return *done;
  eval::MappingEvalOptions options;
  Result<MappingPipelineOptions> pipeline = PipelineOptions(f, flags);
  if (!pipeline.ok()) return Fail(kCommand, pipeline.status().message(), 2);
  options.data = f.data;
  options.max_frames = f.max_frames;
  options.pipeline = *pipeline;
  options.error_attribution = f.error_attribution;
  const std::string out_dir = f.out_dir.empty() ? f.data + "/eval" : f.out_dir;

  ProgressPrinter progress;
  Result<eval::MappingSummary> summary = eval::EvaluateMapping(options, progress.Callback());
  if (!summary.ok()) return Fail(kCommand, summary.status().message());
  if (Status s = PrintReport(eval::MappingReport(*summary), f.json_path); !s.ok()) {
    return Fail(kCommand, s.message());
  }
  std::vector<std::string> written;
  if (Status s = WriteFiles(f, out_dir, *summary, &written); !s.ok()) {
    return Fail(kCommand, s.message());
  }
  std::printf("wrote %s/{", out_dir.c_str());
  for (size_t i = 0; i < written.size(); ++i) {
    std::printf("%s%s", i ? ", " : "", written[i].c_str());
  }
  std::printf("}%s\n", f.json_path.empty() ? "" : (" and " + f.json_path).c_str());
  return 0;
}

}  // namespace mav::eval_cli
