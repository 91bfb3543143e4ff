// Scenario tests: time base, ground truth vs IMU, calibrations, presets, thread safety.

#include <sched.h>

#include <atomic>
#include <cmath>
#include <thread>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "mav/sim/occupancy.h"
#include "mav/sim/presets.h"
#include "mav/sim/scenario.h"
#include "mav/sim/scenario_source.h"
#include "mav/sim/world.h"

namespace mav::sim {
namespace {

Scenario Make(const std::string& preset, int64_t frames, bool rectified = false,
              uint64_t seed = 3) {
  ScenarioOptions o;
  o.preset = preset;
  o.frames = frames;
  o.rectified = rectified;
  o.seed = seed;
  Result<Scenario> s = Scenario::Create(o);
  EXPECT_TRUE(s.ok()) << s.status().ToString();
  return std::move(s).value();
}

TEST(ScenarioTest, TimeBaseGroundTruthAndImuAreConsistent) {
  const Scenario s = Make("room-medium", 60);
  ASSERT_EQ(s.num_frames(), 60);
  EXPECT_EQ(s.FrameTimeNs(0), 1403636579763555584LL);
  EXPECT_EQ(s.FrameTimeNs(7) - s.FrameTimeNs(6), 50'000'000);
  const std::vector<dataset::GroundTruthState> gt = s.GroundTruth();
  const std::vector<dataset::ImuSample> imu = s.ImuSamples();
  ASSERT_EQ(gt.size(), 59u * 10 + 1);  // 200 Hz over [frame 0, frame 59]
  ASSERT_EQ(imu.size(), gt.size());
  EXPECT_EQ(gt.front().t_ns, s.FrameTimeNs(0));
  EXPECT_EQ(gt.back().t_ns, s.FrameTimeNs(59));
  for (int64_t k = 0; k < 60; k += 7) {
    const dataset::GroundTruthState st = s.StateAt(s.FrameTimeNs(k));
    EXPECT_TRUE(st.T_world_body.IsApprox(gt[10 * k].T_world_body, 1e-9)) << k;
    EXPECT_EQ(imu[10 * k].t_ns, s.FrameTimeNs(k));
    // Noisy gyro within a few white-noise sigmas (1.7e-4 * sqrt(200) = 2.4e-3 rad/s) plus bias.
    const dataset::ImuSample ideal = s.IdealImuAt(s.FrameTimeNs(k));
    EXPECT_LT((imu[10 * k].gyro - ideal.gyro).norm(), 0.02) << k;
    EXPECT_LT((imu[10 * k].accel - ideal.accel).norm(), 0.3) << k;
  }
  // The body keeps its distance from the solids (the clearance function reached the generator).
  for (const auto& state : gt) {
    EXPECT_GT(s.world().SignedDistance(state.T_world_body.Translation()), 0.3);
  }
}

TEST(ScenarioTest, FullLengthsAreThePapersAndFramesOverride) {
  const int64_t expected[] = {2839, 1559, 2079, 2000};
  for (size_t i = 0; i < PresetNames().size(); ++i) {
    Result<Preset> p = MakePreset(PresetNames()[i]);
    ASSERT_TRUE(p.ok());
    EXPECT_EQ(p->full_frames, expected[i]) << PresetNames()[i];
  }
  const Scenario s = Make("room-easy", 0);
  EXPECT_EQ(s.num_frames(), 2839);
}

TEST(ScenarioTest, RectifiedRigIsAnIdealPinholePair) {
  const Scenario s = Make("room-easy", 10, /*rectified=*/true);
  const camera::StereoCalibration& c = s.calibration();
  EXPECT_FALSE(c.cam0.HasDistortion());
  EXPECT_FALSE(c.cam1.HasDistortion());
  EXPECT_EQ(c.cam0.fx, c.cam1.fx);
  EXPECT_EQ(c.cam0.cx, c.cam1.cx);
  const geometry::SE3 T01 = c.T_cam0_cam1();
  EXPECT_LT(T01.Rotation().angularDistance(Eigen::Quaterniond::Identity()), 1e-12);
  EXPECT_TRUE(T01.Translation().isApprox(Eigen::Vector3d(0.11, 0, 0), 1e-12));
  cv::Mat l, r;
  s.RenderStereo(5, &l, &r);
  cv::Scalar mu, sigma;
  cv::meanStdDev(l, mu, sigma);
  EXPECT_GT(sigma[0], 10.0);  // textured, not blank
  EXPECT_GT(mu[0], 30.0);
  EXPECT_LT(mu[0], 220.0);

  const Scenario raw = Make("room-easy", 10, /*rectified=*/false);
  EXPECT_TRUE(raw.calibration().cam0.HasDistortion());
  EXPECT_GT(
      raw.calibration().T_cam0_cam1().Rotation().angularDistance(Eigen::Quaterniond::Identity()),
      1e-4);
}

TEST(ScenarioTest, ConcurrentRenderingEqualsSequential) {
  const Scenario s = Make("room-hard", 30);
  cv::Mat l[4], r[4];
  std::thread a([&] { s.RenderStereo(11, &l[0], &r[0]); });
  std::thread b([&] { s.RenderStereo(23, &l[1], &r[1]); });
  a.join();
  b.join();
  s.RenderStereo(11, &l[2], &r[2]);
  s.RenderStereo(23, &l[3], &r[3]);
  EXPECT_EQ(cv::norm(l[0], l[2], cv::NORM_INF), 0);
  EXPECT_EQ(cv::norm(r[1], r[3], cv::NORM_INF), 0);
}

// FramePrefetcher: frames come back in order with what the on_rendered hook added (the
// simulator's CRC computed ahead), rendered under the scheduling policy asked for.
TEST(FramePrefetcherTest, RendersAheadAtTheRequestedPriorityWithTheHooksResult) {
  for (const FramePrefetcher::Priority priority :
       {FramePrefetcher::Priority::kNormal, FramePrefetcher::Priority::kIdle}) {
    std::atomic<int> other_policy{0};
    const int want = priority == FramePrefetcher::Priority::kIdle ? SCHED_IDLE : SCHED_OTHER;
    FramePrefetcher::Frames frames{6, [](int64_t k) { return 1000 * k; },
                                   [&](int64_t k, cv::Mat* left, cv::Mat* right) {
                                     if (sched_getscheduler(0) != want) ++other_policy;
                                     *left =
                                         cv::Mat(4, 4, CV_8UC1, cv::Scalar(static_cast<double>(k)));
                                     *right = left->clone();
                                     return Status::Ok();
                                   }};
    FramePrefetcher prefetcher(
        std::move(frames), /*threads=*/2, /*depth=*/3,
        [](RenderedFrame& frame) {
          frame.crc32 = static_cast<uint32_t>(100 + frame.index);
          return Status::Ok();
        },
        priority);
    for (int64_t k = 0; k < 6; ++k) {
      Result<RenderedFrame> frame = prefetcher.Get(k);
      ASSERT_TRUE(frame.ok()) << frame.status().ToString();
      EXPECT_EQ(frame->t_ns, 1000 * k);
      EXPECT_EQ(frame->left.at<uint8_t>(0, 0), k);
      ASSERT_TRUE(frame->crc32.has_value());
      EXPECT_EQ(*frame->crc32, 100 + k);
    }
    EXPECT_EQ(other_policy.load(), 0) << "rendered outside the requested policy";
  }
}

TEST(ScenarioTest, PlantRendersAndHasGroundTruthOccupancy) {
  const Scenario s = Make("plant", 20);
  cv::Mat l, r;
  s.RenderStereo(10, &l, &r);
  cv::Scalar mu, sigma;
  cv::meanStdDev(l, mu, sigma);
  EXPECT_GT(sigma[0], 5.0);
  const dataset::OccupancyGrid g = s.ComputeOccupancy(0.5);
  EXPECT_EQ(g.size(), Eigen::Vector3i(100, 100, 81));
  EXPECT_EQ(g.StateAt(Eigen::Vector3d(-8, -12, 5)),
            dataset::VoxelState::kOccupied);  // inside a tank
  EXPECT_EQ(g.StateAt(Eigen::Vector3d(0, -20, 20)), dataset::VoxelState::kFree);
  EXPECT_GT(g.Count(dataset::VoxelState::kOccupied), 1000);
}

TEST(ScenarioTest, DifficultyIncreasesAcrossRoomPresets) {
  Result<Preset> easy = MakePreset("room-easy");
  Result<Preset> medium = MakePreset("room-medium");
  Result<Preset> hard = MakePreset("room-hard");
  ASSERT_TRUE(easy.ok() && medium.ok() && hard.ok());
  EXPECT_LT(easy->effects.gain_amplitude, medium->effects.gain_amplitude);
  EXPECT_LT(medium->effects.gain_amplitude, hard->effects.gain_amplitude);
  EXPECT_LT(easy->effects.noise_sigma, hard->effects.noise_sigma);
  EXPECT_EQ(easy->effects.shutter_s, 0.0);
  EXPECT_LT(medium->effects.shutter_s, hard->effects.shutter_s);
  // The hard room has saturating emitters.
  bool saturating = false;
  for (const Material& m : hard->world->materials()) saturating |= m.emission > 1.5f;
  EXPECT_TRUE(saturating);
}

}  // namespace
}  // namespace mav::sim
