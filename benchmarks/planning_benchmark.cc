// Planning hot paths on the contest's power plant map (maps/power_plant.bt, 0.25 m,
// 50 x 50 x 50 m), robot radius 0.5 m:
//   BM_DistanceMap/<method>: parsing the OctoMap, filling the grid and the distance transform,
//     ours (exact point-to-cube, 2 threads) and DynamicEDT3D (the paper's, 1 thread);
//   BM_RoadmapBuild: PRM* with the default options (100 k milestones, seed 1);
//   BM_RoadmapLoad: reading the same roadmap back from its file's bytes;
//   BM_Query: one PlanPath (connection, search, shortening, speed plan, spline and its 1 cm
//     clearance check) per iteration, cycling over the fixed query set (the t4_3 legs plus 15
//     blocked and 15 free 20-40 m queries, seed 1); median and p99 over the set as counters;
//   BM_Clearance / BM_HasClearance: the map's two queries at random points.
// Figures and commands: docs/benchmarks.md, "Planning".
#include <benchmark/benchmark.h>

#include <memory>
#include <random>

#include "mav/common/file.h"
#include "mav/common/stats.h"
#include "mav/planning/planner.h"
#include "mav/planning/planning_map.h"
#include "mav/planning/reference_path.h"
#include "tests/common/build_paths.h"

namespace mav::planning {
namespace {

const std::string kMapPath = mav::testing::SourceDir() + "/maps/power_plant.bt";

struct Fixture {
  std::string bytes;
  std::shared_ptr<const PlanningMap> map;
  std::shared_ptr<const Roadmap> roadmap;
  std::string roadmap_bytes;
  std::vector<EvaluationQuery> queries;

  static Fixture* Get(bool with_roadmap) {
    static Fixture* f = nullptr;
    if (f == nullptr) {
      f = new Fixture;
      auto bytes = ReadFileToString(kMapPath);
      if (!bytes.ok()) return f;
      f->bytes = *bytes;
      f->map = *PlanningMap::LoadBytes(f->bytes, kMapPath, MapOptions{});
    }
    if (with_roadmap && f->map && !f->roadmap) {
      f->roadmap = *Roadmap::Build(*f->map, RoadmapOptions{});
      f->roadmap_bytes = f->roadmap->Serialize();
      for (const auto& [a, b] :
           {std::pair<Eigen::Vector3d, Eigen::Vector3d>{{2, -27, 15}, {20, -15, 15}},
            {{20, -15, 15}, {25, 0, 5}},
            {{25, 0, 5}, {0, 0, 1}}}) {
        EvaluationQuery q;
        q.start = a;
        q.goal = b;
        f->queries.push_back(q);
      }
      RandomQueryOptions options;  // seed 1, 15 blocked, 15 free
      auto random = RandomQueries(*f->map, options);
      if (random.ok()) f->queries.insert(f->queries.end(), random->begin(), random->end());
    }
    return f;
  }
};

void BM_DistanceMap(benchmark::State& state) {
  Fixture* f = Fixture::Get(false);
  if (!f->map) return state.SkipWithError("power_plant.bt is absent");
  MapOptions options;
  options.distance_method = state.range(0) ? DistanceMethod::kDynamicEdt3d : DistanceMethod::kExact;
  MapInfo info;
  for (auto _ : state) {
    auto map = PlanningMap::LoadBytes(f->bytes, kMapPath, options);
    if (!map.ok()) return state.SkipWithError(map.status().ToString().c_str());
    info = (*map)->info();
  }
  state.SetLabel(state.range(0) ? "dynamicedt3d" : "exact");
  state.counters["load_ms"] = info.load_ms;
  state.counters["distance_map_ms"] = info.distance_map_ms;
  state.counters["voxels"] = static_cast<double>(info.memory.grid_voxels);
  state.counters["MB"] = info.memory.bytes / 1e6;
}
BENCHMARK(BM_DistanceMap)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_RoadmapBuild(benchmark::State& state) {
  Fixture* f = Fixture::Get(false);
  if (!f->map) return state.SkipWithError("power_plant.bt is absent");
  RoadmapInfo info;
  for (auto _ : state) {
    auto roadmap = Roadmap::Build(*f->map, RoadmapOptions{});
    if (!roadmap.ok()) return state.SkipWithError(roadmap.status().ToString().c_str());
    info = (*roadmap)->info();
  }
  state.counters["milestones"] = static_cast<double>(info.milestones);
  state.counters["edges"] = static_cast<double>(info.edges);
  state.counters["MB"] = info.memory_bytes / 1e6;
}
BENCHMARK(BM_RoadmapBuild)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();

void BM_RoadmapLoad(benchmark::State& state) {
  Fixture* f = Fixture::Get(true);
  if (!f->roadmap) return state.SkipWithError("power_plant.bt is absent");
  for (auto _ : state) {
    auto roadmap = Roadmap::Deserialize(f->roadmap_bytes, "roadmap", *f->map);
    if (!roadmap.ok()) return state.SkipWithError(roadmap.status().ToString().c_str());
    benchmark::DoNotOptimize(roadmap);
  }
  state.counters["file_MB"] = f->roadmap_bytes.size() / 1e6;
}
BENCHMARK(BM_RoadmapLoad)->Unit(benchmark::kMillisecond);

void BM_Query(benchmark::State& state) {
  Fixture* f = Fixture::Get(true);
  if (!f->roadmap || f->queries.empty()) return state.SkipWithError("power_plant.bt is absent");
  std::vector<double> ms;
  size_t i = 0, failed = 0;
  for (auto _ : state) {
    const EvaluationQuery& q = f->queries[i++ % f->queries.size()];
    PlanRequest request;
    request.start = q.start;
    request.goal = q.goal;
    auto result = PlanPath(*f->map, f->roadmap.get(), request);
    failed += !result.ok() || !result->ok();
    ms.push_back(result.ok() ? result->timings.total_ms : 0);
  }
  const RuntimeStats stats = SummarizeRuntimes(ms);
  state.counters["queries"] = static_cast<double>(f->queries.size());
  state.counters["median_ms"] = stats.median_ms;
  state.counters["p99_ms"] = stats.p99_ms;
  state.counters["max_ms"] = stats.max_ms;
  state.counters["failed"] = static_cast<double>(failed);
}
BENCHMARK(BM_Query)->Unit(benchmark::kMillisecond);

void RandomPoints(const PlanningMap& map, std::vector<Eigen::Vector3d>* points) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(0, 1);
  const Box& b = map.bounds();
  for (int i = 0; i < 4096; ++i) {
    points->push_back(b.min + b.size().cwiseProduct(Eigen::Vector3d(u(rng), u(rng), 0.5 * u(rng))));
  }
}

void BM_HasClearance(benchmark::State& state) {
  Fixture* f = Fixture::Get(false);
  if (!f->map) return state.SkipWithError("power_plant.bt is absent");
  std::vector<Eigen::Vector3d> points;
  RandomPoints(*f->map, &points);
  size_t i = 0;
  for (auto _ : state) benchmark::DoNotOptimize(f->map->HasClearance(points[i++ & 4095], 0.5));
}
BENCHMARK(BM_HasClearance);

void BM_Clearance(benchmark::State& state) {
  Fixture* f = Fixture::Get(false);
  if (!f->map) return state.SkipWithError("power_plant.bt is absent");
  std::vector<Eigen::Vector3d> points;
  RandomPoints(*f->map, &points);
  size_t i = 0;
  for (auto _ : state) benchmark::DoNotOptimize(f->map->Clearance(points[i++ & 4095]));
}
BENCHMARK(BM_Clearance);

}  // namespace
}  // namespace mav::planning

BENCHMARK_MAIN();
