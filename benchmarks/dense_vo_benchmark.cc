// Runtime of the dense direct stereo VO (mav::localization::DenseVo) on simulated EuRoC-like
// 752x480 rectified pairs (room presets of mav::sim). Pin to one core for the target:
//   taskset -c 0 bin/benchmarks/dense_vo_benchmark --benchmark_min_time=2
// BM_DenseVoFrame is the full per-frame cost (pyramid + tracking + keyframes when taken), with
// gyro = 1 also the rotation prior and the gyro check (the hint is the true rotation between the
// frames); "CPU" is the thread's CPU time, robust to other load on the machine.

#include <cstdint>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>

#include "mav/camera/stereo.h"
#include "mav/common/check.h"
#include "mav/geometry/se3.h"
#include "mav/localization/dense_vo.h"
#include "mav/sim/scenario.h"

namespace mav::localization {
namespace {

struct Sequence {
  camera::RectifiedStereo rig;
  std::vector<cv::Mat> left, right;
  std::vector<MotionHint> gyro;  // gyro[k]: the true rotation from frame k - 1 to k
};

// Renders `frames` consecutive rectified pairs of a preset once per process.
const Sequence& GetSequence(const std::string& preset, int frames) {
  static std::vector<std::pair<std::string, Sequence>> cache;
  for (const auto& [name, seq] : cache) {
    if (name == preset) return seq;
  }
  sim::ScenarioOptions options;
  options.preset = preset;
  options.frames = frames;
  options.rectified = true;
  auto scenario = sim::Scenario::Create(options);
  MAV_CHECK(scenario.ok()) << scenario.status().ToString();
  Sequence seq;
  const camera::StereoCalibration& calib = scenario->calibration();
  seq.rig.width = calib.cam0.width;
  seq.rig.height = calib.cam0.height;
  seq.rig.fx = calib.cam0.fx;
  seq.rig.fy = calib.cam0.fy;
  seq.rig.cx = calib.cam0.cx;
  seq.rig.cy = calib.cam0.cy;
  seq.rig.baseline = calib.Baseline();
  geometry::SE3 T_world_previous;
  for (int k = 0; k < frames; ++k) {
    cv::Mat l, r;
    scenario->RenderStereo(k, &l, &r);
    seq.left.push_back(l);
    seq.right.push_back(r);
    const geometry::SE3 T_world_cam =
        scenario->StateAt(scenario->FrameTimeNs(k)).T_world_body * calib.T_body_cam0;
    seq.gyro.push_back(MotionHint{k == 0 ? Eigen::Quaterniond::Identity()
                                         : (T_world_previous.Inverse() * T_world_cam).Rotation()});
    T_world_previous = T_world_cam;
  }
  cache.emplace_back(preset, std::move(seq));
  return cache.back().second;
}

DenseVoOptions OptionsFor(int finest_level) {
  DenseVoOptions options;
  options.finest_level = finest_level;
  return options;
}

// Full per-frame cost over a sequence (keyframes included at their natural rate).
void BM_DenseVoFrame(benchmark::State& state, const std::string& preset) {
  const int frames = 100;
  const Sequence& seq = GetSequence(preset, frames);
  auto vo = DenseVo::Create(seq.rig, OptionsFor(static_cast<int>(state.range(0))));
  MAV_CHECK(vo.ok()) << vo.status().ToString();
  const bool gyro = state.range(1) != 0;
  int k = 0;
  int64_t keyframes = 0, lost = 0, processed = 0;
  double tracking_ms = 0, keyframe_ms = 0, pyramid_ms = 0;
  for (auto _ : state) {
    if (k == frames) {
      // Restart the sequence (the Reset itself is negligible).
      vo->Reset();
      k = 0;
    }
    auto result = vo->ProcessFrame(int64_t{k} * 50'000'000, seq.left[k], seq.right[k],
                                   gyro && k > 0 ? &seq.gyro[k] : nullptr);
    benchmark::DoNotOptimize(result);
    keyframes += result->new_keyframe ? 1 : 0;
    lost += result->state != TrackingState::kOk ? 1 : 0;
    tracking_ms += result->timing.tracking_ms;
    keyframe_ms += result->timing.keyframe_ms;
    pyramid_ms += result->timing.pyramid_ms;
    ++processed;
    ++k;
  }
  state.counters["keyframe_ratio"] = static_cast<double>(keyframes) / processed;
  state.counters["not_ok"] = static_cast<double>(lost);  // LOST or DEGRADED
  state.counters["track_ms"] = tracking_ms / processed;
  state.counters["kf_ms"] = keyframe_ms / processed;
  state.counters["pyr_ms"] = pyramid_ms / processed;
}
BENCHMARK_CAPTURE(BM_DenseVoFrame, room_easy, std::string("room-easy"))
    ->Args({0, 0})
    ->Args({0, 1})
    ->Args({1, 0})
    ->ArgNames({"finest_level", "gyro"})
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DenseVoFrame, room_hard, std::string("room-hard"))
    ->Args({0, 0})
    ->Args({0, 1})
    ->ArgNames({"finest_level", "gyro"})
    ->Unit(benchmark::kMillisecond);

// A keyframe alone: block matching, depth pyramid, pixel selection (first frame after Reset).
void BM_DenseVoKeyframe(benchmark::State& state) {
  const Sequence& seq = GetSequence("room-easy", 100);
  DenseVoOptions options;
  options.depth_level = static_cast<int>(state.range(0));
  options.num_disparities = options.depth_level == 0 ? 96 : 48;
  auto vo = DenseVo::Create(seq.rig, options);
  MAV_CHECK(vo.ok());
  for (auto _ : state) {
    vo->Reset();
    auto result = vo->ProcessFrame(0, seq.left[0], seq.right[0], nullptr);
    benchmark::DoNotOptimize(result);
  }
}
BENCHMARK(BM_DenseVoKeyframe)
    ->Arg(0)
    ->Arg(1)
    ->ArgName("depth_level")
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace mav::localization

BENCHMARK_MAIN();
