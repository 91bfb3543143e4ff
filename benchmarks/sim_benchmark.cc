// Simulator hot paths: rendering one stereo pair of each preset (single thread; frames are
// spread over the whole preset, so adaptive motion-blur sub-frames count as they occur) and the
// exact ground-truth occupancy of a room; per-stage costs of one room-hard image (ray casting +
// shading, reprojection blur, image formation). Figures: docs/benchmarks.md ("Simulator").
//
//   build/bin/benchmarks/sim_benchmark --benchmark_repetitions=3
//       --benchmark_report_aggregates_only=true   (one command line)

#include <algorithm>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>

#include "mav/common/check.h"
#include "mav/sim/occupancy.h"
#include "mav/sim/presets.h"
#include "mav/sim/renderer.h"
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

// Per-stage costs of one room-hard image (left camera): ray casting + shading, reprojection blur,
// image formation. Same frames as BM_RenderStereo.
struct Parts {
  std::shared_ptr<mav::sim::World> world;
  std::unique_ptr<mav::sim::CameraRenderer> renderer;
  std::vector<mav::geometry::SE3> mid, open, close;
  mav::sim::ImageEffects effects;
};

const Parts& GetParts(const std::string& preset) {
  static std::map<std::string, std::unique_ptr<Parts>> cache;
  auto it = cache.find(preset);
  if (it != cache.end()) return *it->second;
  const mav::sim::Scenario& scenario = GetScenario(preset);
  auto parts = std::make_unique<Parts>();
  mav::Result<mav::sim::Preset> p = mav::sim::MakePreset(preset);
  MAV_CHECK(p.ok());
  parts->world = p->world;
  parts->effects = p->effects;
  parts->world->BuildTextures(1);
  const auto& calib = scenario.calibration();
  parts->renderer = std::make_unique<mav::sim::CameraRenderer>(parts->world, calib.cam0);
  const int64_t dt = static_cast<int64_t>(p->effects.shutter_s * 0.5e9);
  for (int64_t f = 0; f < scenario.num_frames(); f += 37) {
    const int64_t t = scenario.FrameTimeNs(f);
    auto pose = [&](int64_t tn) {
      tn = std::clamp(tn, scenario.FrameTimeNs(0), scenario.FrameTimeNs(scenario.num_frames() - 1));
      return scenario.StateAt(tn).T_world_body * calib.T_body_cam0;
    };
    parts->mid.push_back(pose(t));
    parts->open.push_back(pose(t - dt));
    parts->close.push_back(pose(t + dt));
  }
  return *cache.emplace(preset, std::move(parts)).first->second;
}

// `lanes`: 16 (AVX-512), 8 (AVX2) or 4 (SSE2) where the CPU has them (the default: the widest),
// the same images.
void BM_Radiance(benchmark::State& state, const std::string& preset, int lanes) {
  const Parts& parts = GetParts(preset);
  mav::sim::CameraRenderer renderer(parts.world, parts.renderer->camera());
  renderer.SetSimdLanes(lanes);
  if (renderer.simd_lanes() != lanes) return state.SkipWithError("this CPU lacks the instructions");
  std::vector<float> radiance, range;
  size_t k = 0;
  for (auto _ : state) {
    renderer.RenderRadiance(parts.mid[k], &radiance, &range);
    benchmark::DoNotOptimize(radiance.data());
    k = (k + 1) % parts.mid.size();
  }
}

void BM_Blur(benchmark::State& state, const std::string& preset, int lanes) {
  const Parts& parts = GetParts(preset);
  mav::sim::CameraRenderer renderer(parts.world, parts.renderer->camera());
  renderer.SetSimdLanes(lanes);
  if (renderer.simd_lanes() != lanes) return state.SkipWithError("this CPU lacks the instructions");
  std::vector<std::vector<float>> radiance(parts.mid.size()), range(parts.mid.size());
  for (size_t k = 0; k < parts.mid.size(); ++k)
    renderer.RenderRadiance(parts.mid[k], &radiance[k], &range[k]);
  std::vector<float> blurred;
  size_t k = parts.mid.size() / 2;  // the first iteration (profilers) in mid-flight
  for (auto _ : state) {
    renderer.BlurByReprojection(radiance[k], range[k], parts.mid[k], parts.open[k], parts.close[k],
                                parts.effects.reprojection_max_samples, &blurred);
    benchmark::DoNotOptimize(blurred.data());
    k = (k + 1) % parts.mid.size();
  }
}

void BM_FormImage(benchmark::State& state, const std::string& preset, int lanes) {
  const Parts& parts = GetParts(preset);
  std::vector<float> radiance;
  parts.renderer->RenderRadiance(parts.mid[0], &radiance);
  cv::Mat image;
  uint64_t key = 0;
  for (auto _ : state) {
    mav::sim::FormImage(radiance, parts.renderer->width(), parts.renderer->height(), 1.1,
                        parts.effects.noise_sigma, ++key, &image, lanes);
    benchmark::DoNotOptimize(image.data);
  }
}
// clang-format off
BENCHMARK_CAPTURE(BM_Radiance, room-hard/16-lanes, std::string("room-hard"), 16)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Radiance, room-hard/8-lanes, std::string("room-hard"), 8)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Radiance, room-hard/4-lanes, std::string("room-hard"), 4)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Blur, room-hard/16-lanes, std::string("room-hard"), 16)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Blur, room-hard/8-lanes, std::string("room-hard"), 8)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Blur, room-hard/4-lanes, std::string("room-hard"), 4)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_FormImage, room-hard/16-lanes, std::string("room-hard"), 16)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_FormImage, room-hard/8-lanes, std::string("room-hard"), 8)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_FormImage, room-hard/4-lanes, std::string("room-hard"), 4)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Radiance, plant/16-lanes, std::string("plant"), 16)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Radiance, plant/8-lanes, std::string("plant"), 8)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Radiance, plant/4-lanes, std::string("plant"), 4)->Unit(benchmark::kMillisecond);
// clang-format on

void BM_ComputeOccupancy(benchmark::State& state) {
  std::shared_ptr<mav::sim::World> world = mav::sim::BuildRoomWorld(mav::sim::RoomStyle());
  for (auto _ : state) {
    mav::dataset::OccupancyGrid grid = mav::sim::ComputeOccupancy(*world, 0.05);
    benchmark::DoNotOptimize(grid.states().data());
    state.counters["voxels"] = static_cast<double>(grid.num_voxels());
  }
}
BENCHMARK(BM_ComputeOccupancy)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
