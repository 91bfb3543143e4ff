// Runtime of the sparse stereo visual odometry per 752x480 rectified pair, one thread.
//
//   build/bin/benchmarks/localization_benchmark --benchmark_filter=SparseVo
//
// The input is a periodic 16-frame sequence rendered by the test scene (a textured room, camera
// moving ~10 cm per frame on a circle while turning), so every processed pair is a tracked frame
// with a real motion and the constant-velocity prior is exercised as in a flight.

#include <cmath>
#include <vector>

#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>

#include "../tests/unit/localization/synthetic_stereo.h"
#include "mav/localization/features.h"
#include "mav/localization/matcher.h"
#include "mav/localization/sparse_vo.h"

namespace mav::localization {
namespace {

constexpr int kFrames = 16;

struct Sequence {
  camera::RectifiedStereo rig = synthetic::EurocLikeRig();
  std::vector<std::vector<uint8_t>> left, right;
  std::vector<cv::Mat> left_mat, right_mat;

  Sequence() {
    const synthetic::SyntheticRoom room;
    left.resize(kFrames);
    right.resize(kFrames);
    for (int k = 0; k < kFrames; ++k) {
      const double a = 2 * M_PI * k / kFrames;
      const geometry::SE3 T_world_cam(
          geometry::ExpSO3(Eigen::Vector3d(0.03 * std::sin(a), 0.15 * std::sin(a), 0)),
          Eigen::Vector3d(0.3 * std::cos(a), 0.1 * std::sin(2 * a), 0.3 * std::sin(a)));
      room.Render(rig, T_world_cam, &left[k], &right[k], /*noise_sigma=*/1.0, k + 1);
      left_mat.emplace_back(rig.height, rig.width, CV_8UC1, left[k].data());
      right_mat.emplace_back(rig.height, rig.width, CV_8UC1, right[k].data());
    }
  }
};

const Sequence& GetSequence() {
  static const Sequence* seq = new Sequence();
  return *seq;
}

void BM_SparseVo(benchmark::State& state, SparseVoMode mode) {
  const Sequence& seq = GetSequence();
  SparseVoOptions options;
  options.mode = mode;
  auto vo = SparseVo::Create(seq.rig, options);
  if (!vo.ok()) {
    state.SkipWithError(vo.status().ToString().c_str());
    return;
  }
  // Warm up one loop so that every timed frame is a tracked frame.
  for (int k = 0; k < kFrames; ++k) (void)vo->ProcessFrame(k, seq.left_mat[k], seq.right_mat[k]);
  int k = 0, lost = 0;
  double features = 0, matching = 0, estimation = 0, matches = 0, inliers = 0;
  for (auto _ : state) {
    auto r = vo->ProcessFrame(k, seq.left_mat[k % kFrames], seq.right_mat[k % kFrames]);
    ++k;
    lost += r->state != TrackingState::kOk;
    features += r->timing.features_ms;
    matching += r->timing.matching_ms;
    estimation += r->timing.estimation_ms;
    matches += r->num_matches;
    inliers += r->num_inliers;
  }
  state.counters["features_ms"] = features / k;
  state.counters["matching_ms"] = matching / k;
  state.counters["estimation_ms"] = estimation / k;
  state.counters["matches"] = matches / k;
  state.counters["inliers"] = inliers / k;
  state.counters["lost"] = lost;
}
BENCHMARK_CAPTURE(BM_SparseVo, pixel, SparseVoMode::kPixel)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_SparseVo, subpixel, SparseVoMode::kSubpixel)->Unit(benchmark::kMillisecond);

void BM_FeatureExtraction(benchmark::State& state) {
  const Sequence& seq = GetSequence();
  FeatureOptions options;
  options.half_resolution = state.range(0) != 0;
  FeatureExtractor extractor(options);
  FeatureSet fs;
  const ImageView view{seq.left[0].data(), seq.rig.width, seq.rig.height, seq.rig.width};
  for (auto _ : state) {
    extractor.Extract(view, &fs);
    benchmark::DoNotOptimize(fs.TotalFeatures());
  }
  state.counters["features"] = fs.TotalFeatures();
}
BENCHMARK(BM_FeatureExtraction)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

void BM_CircularMatching(benchmark::State& state) {
  const Sequence& seq = GetSequence();
  FeatureExtractor extractor({});
  FeatureSet fs[4];
  const uint8_t* images[4] = {seq.left[0].data(), seq.right[0].data(), seq.left[1].data(),
                              seq.right[1].data()};
  for (int i = 0; i < 4; ++i) {
    extractor.Extract({images[i], seq.rig.width, seq.rig.height, seq.rig.width}, &fs[i]);
  }
  MatcherOptions options;
  options.use_motion_prior = false;
  std::vector<QuadMatch> matches;
  for (auto _ : state) {
    MatchCircular(fs[0], fs[1], fs[2], fs[3], seq.rig, nullptr, options, &matches);
  }
  state.counters["matches"] = static_cast<double>(matches.size());
}
BENCHMARK(BM_CircularMatching)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace mav::localization

BENCHMARK_MAIN();
