// The mission logic (mav/mission/mission.h) flown in-process by the lock-step driver: the
// simulated vehicle sees the room through its rendered stereo camera, the VO tracks it live,
// the estimator fuses the VO with the IMU, the planner plans the legs. Asserts the issue's
// targets on a short room-easy mission, determinism, the health logic (a restarted localization
// is re-seeded and the mission completes; a long outage lands at a free column) and the
// refusal of a goal inside an obstacle before take-off.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "mav/dataset/mission_file.h"
#include "mav/mission/lockstep_driver.h"
#include "mav/mission/mission.h"
#include "tests/common/sanitizers.h"

namespace mav::mission {
namespace {

// From beside the shelf to the far side of the room, past the central crate.
dataset::MissionSpec ShortRoomMission() {
  dataset::MissionSpec m;
  m.world = "room-easy";
  m.start = Eigen::Vector3d(-2.0, 2.4, 0.0);
  m.altitude_m = 1.2;
  dataset::MissionGoal goal;
  goal.position = Eigen::Vector3d(2.2, -0.8, 1.0);
  goal.hover_s = 1.0;
  goal.line = 7;
  m.goals = {goal};
  m.land = true;
  m.source = "short_room.yaml";
  return m;
}

struct Flown {
  MissionReport report;
  std::vector<FlightSample> record;
  LockstepStats stats;
};

Flown Fly(const dataset::MissionSpec& mission, const LockstepOptions& options) {
  Result<std::unique_ptr<LockstepDriver>> driver = LockstepDriver::Create(mission, options);
  EXPECT_TRUE(driver.ok()) << driver.status().ToString();
  if (!driver.ok()) return {};
  Result<MissionReport> report = RunMission(mission, MissionOptions(), **driver);
  EXPECT_TRUE(report.ok()) << report.status().ToString();
  if (!report.ok()) return {};
  return {*std::move(report), (*driver)->record(), (*driver)->stats()};
}

bool HasEvent(const MissionReport& r, const std::string& text) {
  return std::any_of(r.events.begin(), r.events.end(),
                     [&](const MissionEvent& e) { return e.what.find(text) != std::string::npos; });
}

std::string Events(const MissionReport& r) {
  std::string s;
  for (const MissionEvent& e : r.events) s += std::to_string(e.t_s) + " " + e.what + "\n";
  return s;
}

TEST(LockstepMissionTest, FliesARoomMissionOnItsOwnEyesAndRepeatsItExactly) {
  LockstepOptions options;
  options.vehicle.seed = 3;
  const Flown a = Fly(ShortRoomMission(), options);
  ASSERT_EQ(a.report.outcome, MissionOutcome::kCompleted) << a.report.error << "\n"
                                                          << Events(a.report);
  EXPECT_EQ(a.stats.collisions, 0);
  ASSERT_EQ(a.report.goals.size(), 1u);
  EXPECT_TRUE(a.report.goals[0].reached);
  EXPECT_LE(a.report.goals[0].error_m, 0.15);
  EXPECT_LE(EstimateRmsError(a.record), 0.05) << "ATE of the VO-fused estimate";
  EXPECT_GT(a.stats.frames, 200u) << "the VO tracked the flight's own images";
  EXPECT_EQ(a.stats.vo_lost, 0u);
  EXPECT_GE(a.report.plans, 1);
  EXPECT_LT(a.record.back().p_true.z(), 0.15) << "landed";

  if (test_support::kUnderAddressSanitizer) return;  // the rest is the Release run's
  // Same seed, same mission: the same flight, to the millimetre.
  const Flown b = Fly(ShortRoomMission(), options);
  ASSERT_EQ(a.record.size(), b.record.size());
  double worst = 0;
  for (size_t i = 0; i < a.record.size(); ++i) {
    worst = std::max({worst, (a.record[i].p_true - b.record[i].p_true).norm(),
                      (a.record[i].p_est - b.record[i].p_est).norm()});
  }
  EXPECT_LE(worst, 1e-3);
  EXPECT_EQ(a.report.outcome, b.report.outcome);
}

TEST(LockstepMissionTest, RestartedLocalizationIsReseededAndTheMissionCompletes) {
  if (test_support::kUnderAddressSanitizer) GTEST_SKIP() << "two more flights: Release only";
  LockstepOptions options;
  options.vehicle.seed = 3;
  // Down for 2 s mid-leg, back without a reference (a restarted service).
  options.outages.push_back({12.0, 2.0, true});
  const Flown f = Fly(ShortRoomMission(), options);
  EXPECT_EQ(f.report.outcome, MissionOutcome::kCompleted) << f.report.error << "\n"
                                                          << Events(f.report);
  EXPECT_EQ(f.stats.collisions, 0);
  EXPECT_EQ(f.report.holds, 1);
  EXPECT_TRUE(HasEvent(f.report, "re-seeded")) << Events(f.report);
  EXPECT_GE(f.report.replans, 1) << "the interrupted leg is planned again from the hold";
  EXPECT_LE(f.report.goals[0].error_m, 0.15);
}

// Down for 6 s: after 3 s the vehicle lands, moving first to the nearest free column (it held
// 0.3 m from the crate); the localization comes back restarted during the descent, is re-seeded
// and guides the touchdown.
TEST(LockstepMissionTest, LongLocalizationLossLandsAtAFreeColumn) {
  if (test_support::kUnderAddressSanitizer) GTEST_SKIP() << "another flight: Release only";
  LockstepOptions options;
  options.vehicle.seed = 3;
  options.outages.push_back({12.0, 6.0, true});
  const Flown f = Fly(ShortRoomMission(), options);
  EXPECT_EQ(f.report.outcome, MissionOutcome::kLandedOnFault) << Events(f.report);
  EXPECT_EQ(f.stats.collisions, 0) << Events(f.report);
  EXPECT_TRUE(HasEvent(f.report, "hold: no accepted pose")) << Events(f.report);
  EXPECT_NE(f.report.error.find("no accepted pose"), std::string::npos) << f.report.error;
  EXPECT_LT(f.record.back().p_true.z(), 0.15) << "on the ground";
  EXPECT_FALSE(f.report.goals[0].visited);
}

TEST(LockstepMissionTest, GoalInsideAnObstacleIsRefusedBeforeTakeOff) {
  dataset::MissionSpec mission = ShortRoomMission();
  dataset::MissionGoal inside;
  inside.position = Eigen::Vector3d(0.0, 0.0, 0.5);  // in the central crate
  inside.line = 9;
  mission.goals.push_back(inside);
  LockstepOptions options;
  Result<std::unique_ptr<LockstepDriver>> driver = LockstepDriver::Create(mission, options);
  ASSERT_TRUE(driver.ok()) << driver.status().ToString();
  Result<MissionReport> report = RunMission(mission, MissionOptions(), **driver);
  ASSERT_TRUE(report.ok());
  EXPECT_EQ(report->outcome, MissionOutcome::kAborted);
  EXPECT_NE(report->error.find("goals[1] (short_room.yaml:9)"), std::string::npos) << report->error;
  EXPECT_NE(report->error.find("no take-off"), std::string::npos) << report->error;
  EXPECT_TRUE((*driver)->record().empty()) << "nothing was flown";
}

// The online map (MapSource::kOnline): built during the flight from the VO's keyframes, rebuilt
// as they come, the planner's map, written out and scored against the exact world. Its quality
// does not yet let a mission complete reliably (docs/mission.md): the mechanics are asserted.
TEST(LockstepMissionTest, OnlineMapIsBuiltFromTheFlightsKeyframes) {
  if (test_support::kUnderAddressSanitizer) GTEST_SKIP() << "another flight: Release only";
  dataset::MissionSpec mission = ShortRoomMission();
  LockstepOptions options;
  options.vehicle.seed = 3;
  options.map_source = MapSource::kOnline;
  options.map_rebuild_s = 1.0;  // more map versions than plans: their roadmaps wait for a plan
  Result<std::unique_ptr<LockstepDriver>> driver = LockstepDriver::Create(mission, options);
  ASSERT_TRUE(driver.ok()) << driver.status().ToString();
  MissionOptions mission_options;
  mission_options.face_goals = true;
  mission_options.timeout_s = 14;  // take-off and the start of the leg
  Result<MissionReport> report = RunMission(mission, mission_options, **driver);
  ASSERT_TRUE(report.ok());
  const LockstepStats stats = (*driver)->stats();
  EXPECT_GE(stats.keyframes, 3);
  EXPECT_GT(stats.map_rebuilds, stats.plans);
  EXPECT_LT(stats.map_errors, stats.map_rebuilds + stats.keyframes);
  // A roadmap for the first map, then only when a plan finds a map newer than its roadmap.
  EXPECT_GE(stats.roadmap_builds, 1u);
  EXPECT_LE(stats.roadmap_builds, 1 + stats.plans);
  EXPECT_LE(stats.roadmap_builds, 1 + stats.map_rebuilds);
  std::printf("online map: %llu rebuilds, %llu plans, %llu roadmaps\n",
              static_cast<unsigned long long>(stats.map_rebuilds),
              static_cast<unsigned long long>(stats.plans),
              static_cast<unsigned long long>(stats.roadmap_builds));
  EXPECT_NE(stats.map_description.find("online map"), std::string::npos) << stats.map_description;
  const Result<MapQuality> quality = (*driver)->EvaluateMap();
  ASSERT_TRUE(quality.ok()) << quality.status().ToString();
  EXPECT_TRUE(quality->observable_only);
  EXPECT_GT(quality->positions, 0);
  EXPECT_GT(quality->mcc, 0.0) << "better than chance";
  const std::string path = ::testing::TempDir() + "/online_map.bt";
  ASSERT_TRUE((*driver)->WriteMap(path).ok());
  LockstepOptions vo_less;
  vo_less.vehicle.pose_source = PoseSource::kContest;
  vo_less.map_source = MapSource::kOnline;
  const Result<std::unique_ptr<LockstepDriver>> refused = LockstepDriver::Create(mission, vo_less);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.status().message().find("map_source"), std::string::npos);
}

// The hover figures: ground truth against the goal over [hover start + 5 s, hover end).
TEST(LockstepMissionTest, HoverScoreIsTheRmsOverTheSettledWindow) {
  GoalReport goal;
  goal.goal = Eigen::Vector3d(1, 2, 1);
  goal.visited = true;
  goal.hover_start_s = 10;
  goal.reached_at_s = 40;
  std::vector<FlightSample> record;
  for (int k = 0; k <= 900; ++k) {  // 45 s at 20 Hz
    FlightSample s;
    s.t_s = k * 0.05;
    // 0.3 m off while settling (before 15 s), then 0.01 m; 0.02 rad/s.
    s.p_true = goal.goal + Eigen::Vector3d(s.t_s < 15 ? 0.3 : 0.01, 0, 0);
    s.omega_true = Eigen::Vector3d(0, 0.02, 0);
    record.push_back(s);
  }
  const eval::WindowRms hover = ScoreHover(record, goal);
  EXPECT_EQ(hover.samples, 500);  // [15, 40) s
  EXPECT_NEAR(hover.position_rms_m, 0.01, 1e-12);
  EXPECT_NEAR(hover.angular_rate_rms_radps, 0.02, 1e-12);
  goal.visited = false;
  EXPECT_EQ(ScoreHover(record, goal).samples, 0);
}

TEST(LockstepMissionTest, InvalidOptionsNameTheField) {
  dataset::MissionSpec mission = ShortRoomMission();
  LockstepOptions options;
  options.vehicle.vo_latency_s = -1;
  Result<std::unique_ptr<LockstepDriver>> driver = LockstepDriver::Create(mission, options);
  ASSERT_FALSE(driver.ok());
  EXPECT_NE(driver.status().message().find("vo_latency_s"), std::string::npos);
  options = LockstepOptions();
  mission.world = "moon";
  driver = LockstepDriver::Create(mission, options);
  ASSERT_FALSE(driver.ok());
  EXPECT_NE(driver.status().message().find("world"), std::string::npos)
      << driver.status().ToString();
  MissionOptions bad;
  bad.land_after_s = 0.5;  // below hold_after_s
  mission = ShortRoomMission();
  driver = LockstepDriver::Create(mission, LockstepOptions());
  ASSERT_TRUE(driver.ok());
  Result<MissionReport> report = RunMission(mission, bad, **driver);
  ASSERT_FALSE(report.ok());
  EXPECT_NE(report.status().message().find("land_after_s"), std::string::npos);
}

}  // namespace
}  // namespace mav::mission
