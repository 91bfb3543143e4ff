// Cost of the OctoMap + dense-stereo baseline per keyframe at 752x480, and the keyframe counts of
// the default selection on the full room presets.
//
//   octomap_mapper_benchmark --benchmark_counters_tabular=true
//
// Frames come from the simulator (mav::sim::Scenario, preset room-easy, seed 1, ideal rectified
// rig): the first kNumKeyframes keyframes chosen by SelectKeyframes from the ground-truth poses,
// rendered once before timing. Every iteration inserts the next of them into one mapper, so the
// map grows as in a real data set. Counters (per keyframe): disparity_ms, points_ms,
// insertion_ms, points. The paper's libELAS needed ~250 ms per pair on its 2-core i7 VM.

#include <cstdio>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>

#include "mav/mapping/keyframes.h"
#include "mav/mapping/octomap_mapper.h"
#include "mav/sim/scenario.h"

namespace mav::mapping {
namespace {

constexpr int kNumKeyframes = 12;

struct Keyframe {
  cv::Mat left, right;
  geometry::SE3 T_world_cam;
};

struct Frames {
  camera::RectifiedStereo stereo;
  std::vector<Keyframe> keyframes;
};

std::vector<StampedCameraPose> CameraPoses(const sim::Scenario& scenario) {
  std::vector<StampedCameraPose> poses;
  for (int64_t k = 0; k < scenario.num_frames(); ++k) {
    const int64_t t_ns = scenario.FrameTimeNs(k);
    poses.push_back(
        {t_ns, scenario.StateAt(t_ns).T_world_body * scenario.calibration().T_body_cam0});
  }
  return poses;
}

const Frames& SimFrames() {
  static const Frames* frames = [] {
    auto* f = new Frames;
    sim::ScenarioOptions options;
    options.preset = "room-easy";
    options.rectified = true;
    options.frames = 400;
    auto scenario = sim::Scenario::Create(options);
    if (!scenario.ok()) {
      std::fprintf(stderr, "%s\n", scenario.status().ToString().c_str());
      std::abort();
    }
    const camera::PinholeRadTan& cam0 = scenario->calibration().cam0;
    f->stereo.width = cam0.width;
    f->stereo.height = cam0.height;
    f->stereo.fx = cam0.fx;
    f->stereo.fy = cam0.fy;
    f->stereo.cx = cam0.cx;
    f->stereo.cy = cam0.cy;
    f->stereo.baseline = scenario->calibration().Baseline();
    const std::vector<StampedCameraPose> poses = CameraPoses(*scenario);
    auto indices = SelectKeyframes(poses);
    for (int64_t i : *indices) {
      if (static_cast<int>(f->keyframes.size()) == kNumKeyframes) break;
      Keyframe kf;
      scenario->RenderStereo(i, &kf.left, &kf.right);
      kf.T_world_cam = poses[i].T_world_cam;
      f->keyframes.push_back(std::move(kf));
    }
    return f;
  }();
  return *frames;
}

// Args: matcher (0 SGBM 3-way, 1 SGBM 5-direction, 2 BM), discretize (0/1), pixel_stride.
void BM_InsertKeyframe(benchmark::State& state) {
  const Frames& frames = SimFrames();
  OctomapMapperOptions options;
  options.matcher = state.range(0) == 2 ? StereoMatcherType::kBm : StereoMatcherType::kSgbm;
  options.sgbm_three_way = state.range(0) == 0;
  if (options.matcher == StereoMatcherType::kBm) options.block_size = 9;
  options.discretize = state.range(1) != 0;
  options.pixel_stride = static_cast<int>(state.range(2));
  auto mapper = OctomapMapper::Create(options);
  size_t next = 0;
  for (auto _ : state) {
    const Keyframe& kf = frames.keyframes[next];
    if (!mapper->InsertKeyframe(kf.left, kf.right, frames.stereo, kf.T_world_cam).ok()) {
      state.SkipWithError("InsertKeyframe failed");
      break;
    }
    if (++next == frames.keyframes.size()) next = 0;
  }
  const OctomapMapperStats& stats = mapper->stats();
  const double n = static_cast<double>(stats.keyframes.size());
  state.counters["disparity_ms"] = stats.TotalDisparityMs() / n;
  state.counters["points_ms"] = stats.TotalPointsMs() / n;
  state.counters["insertion_ms"] = stats.TotalInsertionMs() / n;
  state.counters["points"] = static_cast<double>(stats.TotalPoints()) / n;
  state.counters["leaves"] = static_cast<double>(mapper->NumLeaves());
}
BENCHMARK(BM_InsertKeyframe)
    ->ArgNames({"matcher", "discretize", "stride"})
    ->Args({0, 1, 4})  // the default: SGBM 3-way, discretized, stride 4
    ->Args({1, 1, 4})  // SGBM 5 directions
    ->Args({2, 1, 4})  // BM
    ->Args({0, 0, 4})  // without discretization
    ->Args({0, 1, 2})  // denser sampling
    ->Args({0, 1, 1})  // every pixel
    ->Iterations(kNumKeyframes)
    ->Unit(benchmark::kMillisecond);

// The map after all keyframes, sampled to the room's 8 x 8 x 3 m evaluation grid at 5 cm, and
// one MAV-sized box query.
void BM_ToGridAndClassify(benchmark::State& state) {
  const Frames& frames = SimFrames();
  auto mapper = OctomapMapper::Create();
  for (const Keyframe& kf : frames.keyframes) {
    (void)mapper->InsertKeyframe(kf.left, kf.right, frames.stereo, kf.T_world_cam);
  }
  mapper->Finish();
  GridGeometry geometry;
  geometry.origin = Eigen::Vector3d(-4.0, -4.0, 0.0);
  geometry.resolution = 0.05;
  geometry.size = Eigen::Vector3i(160, 160, 60);
  const bool grid = state.range(0) == 0;
  const Eigen::AlignedBox3d box(Eigen::Vector3d(0.2, -0.3, 1.0), Eigen::Vector3d(0.8, 0.3, 1.2));
  for (auto _ : state) {
    if (grid) {
      benchmark::DoNotOptimize(mapper->ToGrid(geometry));
    } else {
      benchmark::DoNotOptimize(mapper->Classify(box));
    }
  }
  state.counters["leaves"] = static_cast<double>(mapper->NumLeaves());
}
BENCHMARK(BM_ToGridAndClassify)->ArgName("classify")->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

// Keyframes the default selection keeps on each full room preset (seed 1); the paper kept
// 214 / 284 / 432 of 2839 / 1559 / 2079 frames.
void BM_SelectKeyframesRoomPreset(benchmark::State& state) {
  static const char* kPresets[] = {"room-easy", "room-medium", "room-hard"};
  sim::ScenarioOptions options;
  options.preset = kPresets[state.range(0)];
  options.rectified = true;
  auto scenario = sim::Scenario::Create(options);
  const std::vector<StampedCameraPose> poses = CameraPoses(*scenario);
  size_t keyframes = 0;
  for (auto _ : state) {
    auto indices = SelectKeyframes(poses);
    keyframes = indices->size();
    benchmark::DoNotOptimize(indices);
  }
  state.SetLabel(options.preset);
  state.counters["frames"] = static_cast<double>(poses.size());
  state.counters["keyframes"] = static_cast<double>(keyframes);
}
BENCHMARK(BM_SelectKeyframesRoomPreset)
    ->ArgName("preset")
    ->DenseRange(0, 2)
    ->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace mav::mapping

BENCHMARK_MAIN();
