#include "mav/control/estimator.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <deque>

#include <gtest/gtest.h>

#include "mav/common/time.h"
#include "test_flight.h"

namespace mav::control {
namespace {

using testing::ImuAt;
using testing::PoseAt;
using testing::TruthAt;

constexpr int64_t kImuNs = 10'000'000;    // 100 Hz
constexpr int64_t kPoseNs = 100'000'000;  // 10 Hz

geometry::SE3 Mount() {
  return geometry::SE3(geometry::RotationFromRollPitchYaw(0.2, -0.1, 0.3),
                       Eigen::Vector3d(0.03, -0.07, 0.1));
}

EstimatorOptions Options() {
  EstimatorOptions o;
  o.pose_sources[0].T_body_sensor = Mount();
  return o;
}

TEST(EstimatorTest, NoiseFreeConvergesToGroundTruth) {
  Estimator e = *Estimator::Create(Options());
  const int64_t delay = 100'000'000;
  for (int64_t t = 0; t <= SecondsToNs(30); t += kImuNs) {
    e.FeedImu(ImuAt(t));
    if (t >= delay && (t - delay) % kPoseNs == 0) {
      ASSERT_TRUE(e.FeedPose(PoseAt(t - delay, Mount())).ok());
    }
  }
  const auto truth = TruthAt(30);
  // The Euler prediction of this brisk motion (0.6 m/s, 0.6 m/s^2, yawing 0.3 rad/s) leaves a
  // discretisation error of a few millimetres that the corrections hold there.
  EXPECT_LT((e.state().p_world - truth.p).norm(), 6e-3);
  EXPECT_LT((e.state().v_world - truth.v).norm(), 3e-2);
  EXPECT_LT(geometry::AngleBetween(e.state().q_world_body, truth.q), 4e-3);
  EXPECT_TRUE(e.converged());
}

// Hovering (no discretisation error): the estimate converges to the truth itself.
TEST(EstimatorTest, NoiseFreeHoverConvergesExactly) {
  Estimator e = *Estimator::Create(Options());
  const Eigen::Quaterniond q(geometry::RotationFromRollPitchYaw(0.02, -0.03, 0.7));
  const Eigen::Vector3d p(1, 2, 3);
  const geometry::SE3 T_world_sensor = geometry::SE3(q, p) * Mount();
  for (int64_t t = 0; t <= SecondsToNs(60); t += kImuNs) {
    e.FeedImu(ImuMeasurement{t, Eigen::Vector3d::Zero(),
                             q.conjugate() * Eigen::Vector3d(0, 0, kGravity)});
    if (t >= kPoseNs && t % kPoseNs == 0) {
      ASSERT_TRUE(e.FeedPose(PoseMeasurement{t - kPoseNs, 0, T_world_sensor}).ok());
    }
  }
  EXPECT_LT((e.state().p_world - p).norm(), 1e-6);
  EXPECT_LT(e.state().v_world.norm(), 1e-6);
  EXPECT_LT(geometry::AngleBetween(e.state().q_world_body, q), 1e-6);
  EXPECT_LT(e.state().accel_offset.norm(), 1e-5);
  EXPECT_LT(e.state().gyro_offset.norm(), 1e-6);
}

// The health gate: a pose far from the prediction is refused (and counted) and leaves the
// estimate as a filter that never saw it; the gate opens with the time since the last accepted
// pose.
TEST(EstimatorTest, GateRejectsAJumpAndOpensWithTime) {
  EstimatorOptions o = Options();
  o.pose_gate_m = 0.3;
  o.pose_gate_growth_mps = 0.3;
  o.pose_gate_rad = 0.2;
  Estimator gated = *Estimator::Create(o);
  Estimator blind = *Estimator::Create(o);  // gets no pose after 5 s
  const Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  const Eigen::Vector3d p(1, 2, 3);
  int64_t t = 0;
  // IMU of a vehicle at rest to end_ns; a pose at `measured` every kPoseNs (to `gated` only
  // when `both` is false). Returns the last pose's status.
  auto feed_until = [&](int64_t end_ns, const geometry::SE3& measured, bool both) {
    Status last;
    for (; t <= end_ns; t += kImuNs) {
      const ImuMeasurement m{t, Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, kGravity)};
      gated.FeedImu(m);
      blind.FeedImu(m);
      if (t % kPoseNs != 0) continue;
      last = gated.FeedPose(PoseMeasurement{t, 0, measured});
      if (both) {
        EXPECT_TRUE(blind.FeedPose(PoseMeasurement{t, 0, measured}).ok());
      }
    }
    return last;
  };
  ASSERT_TRUE(feed_until(SecondsToNs(5), geometry::SE3(q, p), true).ok());
  const uint64_t merged = gated.counters().poses_merged;
  // 0.5 m off, 0.1 s after the last accepted pose: the gate is 0.33 m.
  const geometry::SE3 jumped(q, p + Eigen::Vector3d(0.5, 0, 0));
  const Status jump = feed_until(SecondsToNs(5.1), jumped, false);
  EXPECT_EQ(jump.code(), StatusCode::kFailedPrecondition) << jump.ToString();
  EXPECT_NE(jump.message().find("position residual"), std::string::npos) << jump.message();
  EXPECT_EQ(gated.counters().poses_rejected, 1u);
  EXPECT_EQ(gated.counters().poses_merged, merged);
  EXPECT_LT((gated.state().p_world - blind.state().p_world).norm(), 1e-12)
      << "a rejected pose moved the estimate";
  // A rotation beyond 0.2 rad is refused too.
  const geometry::SE3 turned(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ())),
                             gated.state().p_world);
  const Status rotation = feed_until(SecondsToNs(5.2), turned, false);
  EXPECT_NE(rotation.message().find("rotation residual"), std::string::npos) << rotation.ToString();
  EXPECT_EQ(gated.counters().poses_rejected, 2u);
  // After ~0.7 s without an accepted pose the gate is 0.3 + 0.3 * 0.7 > 0.5 m: taken.
  (void)feed_until(SecondsToNs(6.2), jumped, false);
  EXPECT_GT(gated.counters().poses_merged, merged);
}

TEST(EstimatorTest, LearnsImuOffsets) {
  Estimator e = *Estimator::Create(Options());
  const Eigen::Vector3d ba(0.2, 0.1, -0.3), bg(-0.02, 0.008, -0.01);
  for (int64_t t = 0; t <= SecondsToNs(40); t += kImuNs) {
    ImuMeasurement m = ImuAt(t);
    m.accel += ba;
    m.gyro += bg;
    e.FeedImu(m);
    if (t >= kPoseNs && t % kPoseNs == 0) {
      ASSERT_TRUE(e.FeedPose(PoseAt(t - kPoseNs, Mount())).ok());
    }
  }
  EXPECT_LT((e.state().gyro_offset - bg).norm(), 2e-3);
  EXPECT_LT((e.state().accel_offset - ba).norm(), 5e-2);
  EXPECT_LT((e.state().p_world - TruthAt(40).p).norm(), 5e-3);
}

// A pose merged at its stamp after the delay, then the IMU re-applied, gives the estimate a
// filter fed on time would have if it had seen the same poses.
TEST(EstimatorTest, DelayedReplayEqualsOnTimeFilter) {
  const int64_t delay = 100'000'000;
  Estimator on_time = *Estimator::Create(Options());
  Estimator delayed = *Estimator::Create(Options());
  std::deque<std::pair<int64_t, Estimator>> snapshots;  // on_time right after each pose
  std::vector<ImuMeasurement> imu;
  int compared = 0;
  for (int64_t t = 0; t <= SecondsToNs(12); t += kImuNs) {
    ImuMeasurement m = ImuAt(t);
    m.accel += Eigen::Vector3d(0.05 * std::sin(t * 1e-9), 0.02, -0.03);  // not noise free
    imu.push_back(m);
    on_time.FeedImu(m);
    delayed.FeedImu(m);
    if (t % kPoseNs == 0) {
      ASSERT_TRUE(on_time.FeedPose(PoseAt(t, Mount())).ok());
      snapshots.emplace_back(t, on_time);
    }
    if (t >= delay && (t - delay) % kPoseNs == 0) {
      const int64_t stamp = t - delay;
      ASSERT_TRUE(delayed.FeedPose(PoseAt(stamp, Mount())).ok());
      // Replay the on-time snapshot at the stamp through the same IMU samples.
      while (snapshots.front().first < stamp) snapshots.pop_front();
      ASSERT_EQ(snapshots.front().first, stamp);
      Estimator replay = snapshots.front().second;
      for (const ImuMeasurement& s : imu) {
        if (s.t_ns > stamp && s.t_ns <= t) replay.FeedImu(s);
      }
      EXPECT_LT((replay.state().p_world - delayed.state().p_world).norm(), 1e-9);
      EXPECT_LT((replay.state().v_world - delayed.state().v_world).norm(), 1e-9);
      EXPECT_LT(geometry::AngleBetween(replay.state().q_world_body, delayed.state().q_world_body),
                1e-9);
      EXPECT_LT((replay.state().accel_offset - delayed.state().accel_offset).norm(), 1e-9);
      ++compared;
    }
  }
  EXPECT_GT(compared, 100);
}

TEST(EstimatorTest, TwoSourcesWithTheirMountings) {
  EstimatorOptions o = Options();
  PoseSourceOptions second;
  second.rate_hz = 20;
  second.T_body_sensor = geometry::SE3(geometry::RotationFromRollPitchYaw(-0.1, 0.2, -0.3),
                                       Eigen::Vector3d(-0.05, 0.08, 0.1));
  o.pose_sources.push_back(second);
  Estimator e = *Estimator::Create(o);
  for (int64_t t = 0; t <= SecondsToNs(20); t += kImuNs) {
    e.FeedImu(ImuAt(t));
    if (t >= kPoseNs && t % kPoseNs == 0) {
      ASSERT_TRUE(e.FeedPose(PoseAt(t - kPoseNs, Mount(), 0)).ok());
    }
    if (t >= 80'000'000 && (t - 80'000'000) % 50'000'000 == 0) {
      ASSERT_TRUE(e.FeedPose(PoseAt(t - 80'000'000, second.T_body_sensor, 1)).ok());
    }
  }
  EXPECT_LT((e.state().p_world - TruthAt(20).p).norm(), 6e-3);
  EXPECT_LT(geometry::AngleBetween(e.state().q_world_body, TruthAt(20).q), 4e-3);
  EXPECT_EQ(e.counters().poses_merged, 200u + 399u);
  EXPECT_EQ(e.counters().poses_dropped, 0u);
}

// Two sources whose delays put their poses out of stamp order on arrival (a 150 ms late one and a
// 30 ms late one): each late pose is merged at its stamp and the later-stamped poses merged before
// it are re-applied after it, so the result equals a filter fed every pose on time, in stamp order.
TEST(EstimatorTest, OutOfOrderPosesEqualAFilterFedInStampOrder) {
  EstimatorOptions o = Options();
  PoseSourceOptions second;
  second.T_body_sensor = geometry::SE3(geometry::RotationFromRollPitchYaw(-0.1, 0.2, -0.3),
                                       Eigen::Vector3d(-0.05, 0.08, 0.1));
  o.pose_sources.push_back(second);
  Estimator on_time = *Estimator::Create(o);
  Estimator late = *Estimator::Create(o);
  struct Pending {
    int64_t arrival;
    PoseMeasurement pose;
  };
  std::vector<Pending> pending;
  const int64_t end = SecondsToNs(8);
  for (int64_t t = 0; t <= end; t += kImuNs) {
    ImuMeasurement m = ImuAt(t);
    m.accel += Eigen::Vector3d(0.05, -0.02, 0.03);
    on_time.FeedImu(m);
    late.FeedImu(m);
    // Source 0 stamps at 0, 100, ... ms (150 ms late); source 1 at 50, 150, ... ms (30 ms late).
    if (t % kPoseNs == 0) {
      const PoseMeasurement p = PoseAt(t, Mount(), 0);
      ASSERT_TRUE(on_time.FeedPose(p).ok());
      pending.push_back({t + 150'000'000, p});
    }
    // (source 1 starts after source 0's first pose has initialised both filters)
    if (t % kPoseNs == 50'000'000 && t > 200'000'000) {
      const PoseMeasurement p = PoseAt(t, second.T_body_sensor, 1);
      ASSERT_TRUE(on_time.FeedPose(p).ok());
      pending.push_back({t + 30'000'000, p});
    }
    for (auto it = pending.begin(); it != pending.end();) {
      if (it->arrival <= t) {
        ASSERT_TRUE(late.FeedPose(it->pose).ok());
        it = pending.erase(it);
      } else {
        ++it;
      }
    }
  }
  for (const Pending& p : pending) ASSERT_TRUE(late.FeedPose(p.pose).ok());  // the rest, at the end
  EXPECT_LT((late.state().p_world - on_time.state().p_world).norm(), 1e-9);
  EXPECT_LT((late.state().v_world - on_time.state().v_world).norm(), 1e-9);
  EXPECT_LT(geometry::AngleBetween(late.state().q_world_body, on_time.state().q_world_body), 1e-9);
  EXPECT_LT((late.state().accel_offset - on_time.state().accel_offset).norm(), 1e-9);
  EXPECT_LT((late.state().gyro_offset - on_time.state().gyro_offset).norm(), 1e-9);
  EXPECT_EQ(late.counters().poses_merged, on_time.counters().poses_merged);
}

// A source whose frame is tipped 3 degrees (a VO's tilt drift): without the alignment the
// estimate tilts with it, and the motion it reports climbs where the truth is level; with a
// loose tilt sigma and the alignment the estimate keeps gravity's tilt, the source's frame is
// turned back, and the positions follow the true motion up to a constant offset.
struct TiltedSourceRun {
  double worst_tilt_rad = 0;   // estimate vs truth, over the last 10 s
  double height_spread_m = 0;  // max - min of the height error over the last 10 s
  double frame_tilt_rad = 0;   // of source_frame() * the source's tipped frame
};

TiltedSourceRun FlyWithTiltedSource(double tilt_sigma_rad, double align_tilt_s) {
  EstimatorOptions o = Options();
  o.pose_sources[0].tilt_sigma_rad = tilt_sigma_rad;
  o.pose_sources[0].align_tilt_s = align_tilt_s;
  Estimator e = *Estimator::Create(o);
  const Eigen::Quaterniond tip(Eigen::AngleAxisd(3 * M_PI / 180, Eigen::Vector3d::UnitX()));
  const Eigen::Vector3d pivot(0, 0, 1);
  const geometry::SE3 tipped(tip, pivot - tip * pivot);
  // The first pose is true (a VO starts at a known pose); the tip comes after the estimate has
  // converged (converge_s, while it learns the offsets against the source's tilt).
  TiltedSourceRun run;
  double low = 1e9, high = -1e9;
  for (int64_t t = 0; t <= SecondsToNs(40); t += kImuNs) {
    e.FeedImu(ImuAt(t));
    if (t < kPoseNs || t % kPoseNs != 0) continue;
    PoseMeasurement pose = PoseAt(t - kPoseNs, Mount());
    if (t > SecondsToNs(6)) pose.T_world_sensor = tipped * pose.T_world_sensor;
    EXPECT_TRUE(e.FeedPose(pose).ok());
    if (t < SecondsToNs(30)) continue;
    const testing::TruthState truth = TruthAt(NsToSeconds(t));
    const Eigen::Vector3d up = e.state().q_world_body.conjugate() * Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d true_up = truth.q.conjugate() * Eigen::Vector3d::UnitZ();
    run.worst_tilt_rad = std::max(run.worst_tilt_rad, std::acos(std::min(1.0, up.dot(true_up))));
    const double dz = e.state().p_world.z() - truth.p.z();
    low = std::min(low, dz);
    high = std::max(high, dz);
  }
  run.height_spread_m = high - low;
  const Eigen::Vector3d frame_up =
      (e.source_frame(0) * tipped).Rotation().conjugate() * Eigen::Vector3d::UnitZ();
  run.frame_tilt_rad = std::acos(std::min(1.0, frame_up.z()));
  return run;
}

TEST(EstimatorTest, AlignsASourceFrameTiltedAgainstGravity) {
  const TiltedSourceRun plain = FlyWithTiltedSource(0, 0);
  const TiltedSourceRun aligned = FlyWithTiltedSource(0.17, 2.0);
  // Without: the estimate leans with the source and the level motion reads as climbing.
  EXPECT_GT(plain.worst_tilt_rad, 0.02);
  EXPECT_GT(plain.height_spread_m, 0.06);
  EXPECT_NEAR(plain.frame_tilt_rad, 3 * M_PI / 180, 1e-9);  // the frame is left alone
  // With: gravity's tilt, the frame turned back, the height error nearly constant.
  EXPECT_LT(aligned.worst_tilt_rad, 0.01);
  EXPECT_LT(aligned.frame_tilt_rad, 0.008);
  EXPECT_LT(aligned.height_spread_m, 0.02);
  std::printf(
      "tilted source: plain tilt %.4f rad, spread %.4f m; aligned %.4f rad, %.4f m, "
      "frame %.4f rad\n",
      plain.worst_tilt_rad, plain.height_spread_m, aligned.worst_tilt_rad, aligned.height_spread_m,
      aligned.frame_tilt_rad);
}

TEST(EstimatorTest, RejectsBadInput) {
  Estimator e = *Estimator::Create(Options());
  EXPECT_EQ(e.FeedPose(PoseAt(0, Mount())).code(), StatusCode::kOutOfRange);  // no IMU yet
  e.FeedImu(ImuAt(SecondsToNs(2)));
  EXPECT_EQ(e.FeedPose(PoseAt(0, Mount())).code(), StatusCode::kOutOfRange);  // too old
  EXPECT_EQ(e.FeedPose(PoseAt(SecondsToNs(2), Mount(), 3)).code(), StatusCode::kInvalidArgument);
  EstimatorOptions bad = Options();
  bad.pose_sources[0].rate_hz = 0;
  const auto r = Estimator::Create(bad);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("pose_sources[0].rate_hz"), std::string::npos);
  bad = Options();
  bad.pose_sources[0].align_tilt_s = -1;
  const auto align = Estimator::Create(bad);
  ASSERT_FALSE(align.ok());
  EXPECT_NE(align.status().message().find("pose_sources[0].align_tilt_s"), std::string::npos);
  bad = Options();
  bad.pose_sources[0].tilt_sigma_rad = std::nan("");
  const auto tilt = Estimator::Create(bad);
  ASSERT_FALSE(tilt.ok());
  EXPECT_NE(tilt.status().message().find("pose_sources[0].tilt_sigma_rad"), std::string::npos);
}

}  // namespace
}  // namespace mav::control
