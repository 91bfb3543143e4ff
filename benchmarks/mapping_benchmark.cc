// Mapping hot paths on the synthetic room (mav/mapping/synthetic_scene.h): 8 x 6 x 3 m, four
// obstacles, keyframes on a loop, ~100 points per keyframe, up to 4 views per point, 1 cm noise.
//   BM_BuildMesh/300: the full-room scale of the paper's data sets (214-432 keyframes).
#include <benchmark/benchmark.h>

#include "mav/mapping/collision_eval.h"
#include "mav/mapping/delaunay_graph_cut.h"
#include "mav/mapping/mesh_to_grid.h"
#include "mav/mapping/pipeline.h"
#include "mav/mapping/synthetic_scene.h"

namespace mav::mapping {
namespace {

struct Fixture {
  SyntheticScene scene = MakeRoomScene();
  std::vector<MapPoint> points;
  std::vector<KeyframeView> keyframes;
  GridGeometry geometry;

  explicit Fixture(int num_keyframes) {
    SyntheticObservationOptions options;
    options.num_keyframes = num_keyframes;
    SampleRoomObservations(scene, options, &points, &keyframes);
    geometry.origin = Eigen::Vector3d(-0.2, -0.2, -0.2);
    geometry.resolution = 0.05;
    geometry.size = Eigen::Vector3i(168, 128, 68);
  }
};

// Args: keyframes; map preference (0 = kMcc, the paper's weights; 1 = kSafety, the pipeline's
// default: the weakly-supported-surface pass on top).
void BM_BuildMesh(benchmark::State& state) {
  const Fixture f(static_cast<int>(state.range(0)));
  const MeshingOptions options =
      MeshingOptionsFor(state.range(1) != 0 ? MapPreference::kSafety : MapPreference::kMcc);
  MeshingStats stats;
  for (auto _ : state) {
    auto result = BuildMesh(f.points, f.keyframes, options);
    benchmark::DoNotOptimize(result);
    stats = result->stats;
  }
  state.counters["points"] = static_cast<double>(f.points.size());
  state.counters["rays"] = static_cast<double>(stats.num_rays);
  state.counters["cells"] = stats.num_finite_cells;
  state.counters["t_triangulation_s"] = stats.triangulation_s;
  state.counters["t_visibility_s"] = stats.visibility_s;
  state.counters["t_graph_cut_s"] = stats.graph_cut_s;
  state.counters["support_jumps"] = static_cast<double>(stats.weak_surface_rays);
}
BENCHMARK(BM_BuildMesh)
    ->Args({120, 0})
    ->Args({300, 0})
    ->Args({300, 1})
    ->Unit(benchmark::kMillisecond);

// Arg: the lines of sight's radius in voxels (0 = thin; the pipeline's default is 1).
void BM_MeshToOccupancy(benchmark::State& state) {
  const Fixture f(300);
  const auto meshing = BuildMesh(f.points, f.keyframes);
  MeshToGridOptions options;
  options.carve_radius_voxels = static_cast<int>(state.range(0));
  for (auto _ : state) {
    auto grid = MeshToOccupancy(*meshing, f.points, f.keyframes, f.geometry, options);
    benchmark::DoNotOptimize(grid);
  }
}
BENCHMARK(BM_MeshToOccupancy)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// Arg: the map preference's grid options (MeshToGridOptionsFor): 0 = kSafety (voxels touching the
// mesh occupied, the default), 1 = kMcc.
void BM_MeshToOccupancyPreference(benchmark::State& state) {
  const Fixture f(300);
  const auto meshing = BuildMesh(f.points, f.keyframes);
  const MeshToGridOptions options =
      MeshToGridOptionsFor(state.range(0) == 0 ? MapPreference::kSafety : MapPreference::kMcc);
  for (auto _ : state) {
    auto grid = MeshToOccupancy(*meshing, f.points, f.keyframes, f.geometry, options);
    benchmark::DoNotOptimize(grid);
  }
}
BENCHMARK(BM_MeshToOccupancyPreference)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// The occlusion check's test (pipeline.h, OcclusionCheckOptions): every line of sight of the
// 300-keyframe room (29.5 k points, 106 k lines of sight; a full preset checks 3-7 k far
// single-view points) traced through the safety grid of its mesh.
void BM_PointsSeenThroughSurfaces(benchmark::State& state) {
  const Fixture f(300);
  const auto meshing = BuildMesh(f.points, f.keyframes, MeshingOptionsFor(MapPreference::kSafety));
  const auto grid = MeshToOccupancy(*meshing, f.points, f.keyframes, f.geometry,
                                    MeshToGridOptionsFor(MapPreference::kSafety));
  int64_t lines = 0, seen_through = 0;
  for (const MapPoint& p : f.points) lines += static_cast<int64_t>(p.keyframes.size());
  for (auto _ : state) {
    auto seen = PointsSeenThroughSurfaces(*grid, f.points, f.keyframes, 0.3);
    benchmark::DoNotOptimize(seen);
    seen_through = 0;
    for (const bool b : *seen) seen_through += b ? 1 : 0;
  }
  state.counters["points"] = static_cast<double>(f.points.size());
  state.counters["lines_of_sight"] = static_cast<double>(lines);
  state.counters["seen_through"] = static_cast<double>(seen_through);
}
BENCHMARK(BM_PointsSeenThroughSurfaces)->Unit(benchmark::kMillisecond);

// The whole pipeline as mav-eval runs it, with the collision MCC as a counter.
void BM_MeshGridEvaluate(benchmark::State& state) {
  const Fixture f(300);
  const OccupancyGrid truth = f.scene.TruthGrid(f.geometry);
  double mcc = 0.0;
  for (auto _ : state) {
    const auto meshing = BuildMesh(f.points, f.keyframes);
    const auto grid = MeshToOccupancy(*meshing, f.points, f.keyframes, f.geometry);
    const auto eval = EvaluateCollisions(truth, *grid);
    mcc = eval->Mcc();
  }
  state.counters["mcc"] = mcc;
}
BENCHMARK(BM_MeshGridEvaluate)->Unit(benchmark::kMillisecond)->Iterations(2);

void BM_EvaluateCollisions(benchmark::State& state) {
  const Fixture f(1);
  const OccupancyGrid truth = f.scene.TruthGrid(f.geometry);
  for (auto _ : state) {
    auto eval = EvaluateCollisions(truth, truth);
    benchmark::DoNotOptimize(eval);
  }
  state.counters["voxels"] = static_cast<double>(truth.num_voxels());
}
BENCHMARK(BM_EvaluateCollisions)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace mav::mapping

BENCHMARK_MAIN();
