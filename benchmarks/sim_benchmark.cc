// Simulator hot paths: rendering one stereo pair of each preset (single thread; frames are
// spread over the whole preset, so adaptive motion-blur sub-frames count as they occur) and the
// exact ground-truth occupancy of a room. Figures: docs/benchmarks.md ("Simulator").
//
//   build-sim/bin/benchmarks/sim_benchmark --benchmark_min_time=3

#include <map>
#include <memory>
#include <string>

#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>

#include "mav/common/check.h"
#include "mav/sim/occupancy.h"
#include "mav/sim/presets.h"
#include "mav/sim/scenario.h"
#include "mav/sim/world.h"

namespace {

const mav::sim::Scenario& GetScenario(const std::string& preset) {
  static std::map<std::string, std::unique_ptr<mav::sim::Scenario>> cache;
  auto it = cache.find(preset);
  if (it == cache.end()) {
    mav::sim::ScenarioOptions o;
    o.preset = preset;
    o.seed = 1;
    mav::Result<mav::sim::Scenario> s = mav::sim::Scenario::Create(o);
    MAV_CHECK(s.ok()) << s.status().ToString();
    it = cache.emplace(preset, std::make_unique<mav::sim::Scenario>(std::move(s).value())).first;
  }
  return *it->second;
}

void BM_RenderStereo(benchmark::State& state, const std::string& preset) {
  const mav::sim::Scenario& scenario = GetScenario(preset);
  cv::Mat left, right;
  int64_t frame = 0;
  for (auto _ : state) {
    scenario.RenderStereo(frame, &left, &right);
    benchmark::DoNotOptimize(left.data);
    // A stride co-prime with the lengths visits frames all over the preset.
    frame = (frame + 37) % scenario.num_frames();
  }
  state.SetLabel(std::to_string(scenario.num_frames()) + " frames");
}
// clang-format off
BENCHMARK_CAPTURE(BM_RenderStereo, room-easy, std::string("room-easy"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_RenderStereo, room-medium, std::string("room-medium"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_RenderStereo, room-hard, std::string("room-hard"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_RenderStereo, plant, std::string("plant"))->Unit(benchmark::kMillisecond);
// clang-format on

void BM_ComputeOccupancy(benchmark::State& state) {
  std::shared_ptr<mav::sim::World> world = mav::sim::BuildRoomWorld(mav::sim::RoomStyle());
  for (auto _ : state) {
    mav::sim::OccupancyGrid grid = mav::sim::ComputeOccupancy(*world, 0.05);
    benchmark::DoNotOptimize(grid.states().data());
    state.counters["voxels"] = static_cast<double>(grid.num_voxels());
  }
}
BENCHMARK(BM_ComputeOccupancy)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
