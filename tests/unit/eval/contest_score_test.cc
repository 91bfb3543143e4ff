#include "mav/eval/contest_score.h"

#include <gtest/gtest.h>

namespace mav::eval {
namespace {

using dataset::FlightTask;
using dataset::FlightTaskKind;

TEST(ContestScoreTest, BandsAsTheContestsScripts) {
  // Position / settling: > 100 % 0, (50, 100] 1.5, (10, 50] 3.5, <= 10 % 5.0.
  EXPECT_EQ(BandPoints(0.25, 0.2, false), 0.0);
  EXPECT_EQ(BandPoints(0.2, 0.2, false), 1.5);
  EXPECT_EQ(BandPoints(0.1001, 0.2, false), 1.5);
  EXPECT_EQ(BandPoints(0.1, 0.2, false), 3.5);
  EXPECT_EQ(BandPoints(0.055, 0.2, false), 3.5);  // the paper's hover: 3.5
  EXPECT_EQ(BandPoints(0.02, 0.2, false), 5.0);
  EXPECT_EQ(BandPoints(3.6, 10, false), 3.5);  // the paper's 3.6 s
  EXPECT_EQ(BandPoints(1.0, 10, false), 5.0);
  // Angular rate: 0 / 1 / 2 / 3.
  EXPECT_EQ(BandPoints(0.087, 0.2, true), 2.0);  // the paper's 0.087 rad/s
  EXPECT_EQ(BandPoints(0.15, 0.2, true), 1.0);
  EXPECT_EQ(BandPoints(0.02, 0.2, true), 3.0);
  EXPECT_EQ(BandPoints(0.3, 0.2, true), 0.0);
  EXPECT_EQ(BandPoints(NAN, 0.2, true), 0.0);
}

// A trace at 100 Hz: the error along x follows `error(t)`, the body rate is constant `rate`.
template <typename F>
std::vector<FlightTraceSample> Trace(double duration, const Eigen::Vector3d& goal, F error,
                                     double rate = 0.0) {
  std::vector<FlightTraceSample> out;
  for (int k = 0; k <= static_cast<int>(duration * 100); ++k) {
    FlightTraceSample s;
    s.t_s = k * 0.01;
    s.p_world = goal + Eigen::Vector3d(error(s.t_s), 0, 0);
    s.p_estimate = s.p_world + Eigen::Vector3d(0, 0.003, 0);
    s.omega_body = Eigen::Vector3d(0, 0, rate);
    out.push_back(s);
  }
  return out;
}

FlightTask Disturbance() {
  FlightTask t;
  t.name = std::string("disturbance");
  t.kind = FlightTaskKind::kDisturbance;
  t.duration_s = 65;
  t.goals = {{10, Eigen::Vector3d(0, 0, 1), 0}};
  t.forces = {{Eigen::Vector3d(1, 1, 0), 40, 42}};
  return t;
}

TEST(ContestScoreTest, SettlingAfterTheOnsetThenTheWindow) {
  const FlightTask t = Disturbance();
  // Out to 0.3 m at 40-42.5 s, then 0.01 m: settles at 42.5 s (2.5 s after the onset).
  const auto trace = Trace(
      65, t.goals[0].position, [](double s) { return s >= 40 && s < 42.5 ? 0.3 : 0.01; }, 0.01);
  const TaskScore score = ScoreFlightTask(t, trace, 0);
  ASSERT_EQ(score.goals.size(), 1u);
  const GoalScore& g = score.goals[0];
  EXPECT_TRUE(g.settled);
  EXPECT_NEAR(g.settling_time_s, 2.5, 1e-6);
  EXPECT_NEAR(g.window_start_s, 42.5, 1e-6);
  EXPECT_NEAR(g.rms.position_rms_m, 0.01, 1e-9);
  EXPECT_NEAR(g.rms.angular_rate_rms_radps, 0.01, 1e-9);
  EXPECT_NEAR(g.rms.estimator_rms_m, 0.003, 1e-9);
  EXPECT_EQ(g.settling_points, 3.5);
  EXPECT_EQ(g.position_points, 5.0);
  EXPECT_EQ(g.angular_rate_points, 3.0);
  EXPECT_EQ(score.points, 11.5);
  EXPECT_EQ(score.max_points, 13.0);
}

TEST(ContestScoreTest, NeverLeavingTheBallIsZeroSettlingAndAnExcursionRestartsTheHold) {
  const FlightTask t = Disturbance();
  const TaskScore calm =
      ScoreFlightTask(t, Trace(65, t.goals[0].position, [](double) { return 0.05; }), 0);
  EXPECT_EQ(calm.goals[0].settling_time_s, 0);
  EXPECT_EQ(calm.goals[0].settling_points, 5.0);
  // In the ball from 40 s but a blip out at 42 s: the 3 s hold restarts after it.
  const TaskScore blip = ScoreFlightTask(
      t,
      Trace(65, t.goals[0].position, [](double s) { return s > 41.995 && s < 42.05 ? 0.2 : 0.0; }),
      0);
  EXPECT_NEAR(blip.goals[0].settling_time_s, 2.05, 1e-6);
}

TEST(ContestScoreTest, NeverSettlingScoresNothingAndCountsAs101Percent) {
  const FlightTask t = Disturbance();
  const TaskScore s =
      ScoreFlightTask(t, Trace(65, t.goals[0].position, [](double) { return 0.5; }), 0);
  EXPECT_FALSE(s.all_settled);
  EXPECT_FALSE(s.goals[0].settled);
  EXPECT_NEAR(s.goals[0].settling_time_s, 10.1, 1e-9);
  EXPECT_NEAR(s.goals[0].rms.position_rms_m, 0.202, 1e-9);
  EXPECT_NEAR(s.goals[0].rms.angular_rate_rms_radps, 0.202, 1e-9);
  EXPECT_EQ(s.points, 0);
  // Settling after the 10 s limit is also "never".
  const TaskScore late = ScoreFlightTask(
      t, Trace(65, t.goals[0].position, [](double s) { return s < 50.5 ? 0.5 : 0.0; }), 0);
  EXPECT_FALSE(late.goals[0].settled);
}

TEST(ContestScoreTest, HoverWindowStartsFiveSecondsAfterTheSetPoint) {
  FlightTask t;
  t.name = std::string("hover");
  t.kind = FlightTaskKind::kHover;
  t.duration_s = 30;
  t.goals = {{10, Eigen::Vector3d(0, 0, 1), 0}};
  // 0.5 m off before 15 s, 0.04 m inside the window, 0.5 m again after 25 s.
  const TaskScore s = ScoreFlightTask(
      t, Trace(30, t.goals[0].position, [](double x) { return x >= 15 && x < 25 ? 0.04 : 0.5; }),
      0);
  EXPECT_NEAR(s.goals[0].window_start_s, 15, 1e-9);
  EXPECT_NEAR(s.position_rms_m, 0.04, 1e-9);
  EXPECT_EQ(s.points, 3.5 + 3.0);
  EXPECT_EQ(s.max_points, 8.0);
}

TEST(ContestScoreTest, AnyCollisionScoresZeroAndWaypointLegsAreMeasured) {
  FlightTask t;
  t.name = std::string("waypoints");
  t.kind = FlightTaskKind::kWaypoints;
  t.duration_s = 40;
  t.goals = {{0, Eigen::Vector3d(0, 0, 1), 0}, {10, Eigen::Vector3d(10, 0, 1), 0}};
  // Straight from 0 to 10 m between 11 s and 15 s at 2.5 m/s.
  std::vector<FlightTraceSample> trace;
  for (int k = 0; k <= 4000; ++k) {
    FlightTraceSample s;
    s.t_s = k * 0.01;
    const double x = std::clamp((s.t_s - 11) * 2.5, 0.0, 10.0);
    s.p_world = Eigen::Vector3d(x, 0, 1);
    s.v_world = Eigen::Vector3d(s.t_s > 11 && s.t_s < 15 ? 2.5 : 0, 0, 0);
    s.p_estimate = s.p_world;
    trace.push_back(s);
  }
  const TaskScore clean = ScoreFlightTask(t, trace, 0);
  ASSERT_EQ(clean.goals.size(), 1u);  // the first goal is not scored
  const GoalScore& g = clean.goals[0];
  EXPECT_NEAR(g.settling_time_s, 4.96, 0.02);  // within 0.1 m of 10 m at 14.96 s
  EXPECT_NEAR(g.flight_time_s, 14.96 - 11.04, 0.03);
  EXPECT_NEAR(g.mean_speed_mps, 2.5, 0.05);
  EXPECT_NEAR(g.peak_speed_mps, 2.5, 1e-9);
  EXPECT_GT(clean.points, 0);
  EXPECT_EQ(ScoreFlightTask(t, trace, 1).points, 0);
}

}  // namespace
}  // namespace mav::eval
