// The autopilot's mode logic, closed-loop with the simulated vehicle (libs/sim).

#include "mav/control/autopilot.h"

#include <gtest/gtest.h>

#include <iostream>

#include "mav/common/time.h"
#include "mav/eval/flight_mission.h"
#include "mav/sim/failsafe.h"
#include "mav/sim/flight_simulation.h"
#include "mav/sim/flight_task.h"

namespace mav::control {
namespace {

// Lock-steps a simulation and an autopilot; `each_step` may command the autopilot.
struct Loop {
  sim::FlightSimulation sim;
  Autopilot ap;
  bool feed_poses = true;
  bool feed_imu = true;
  // Set: the vehicle's own failsafe flies it while the autopilot is disarmed (the simulator's
  // real-time mode after its controller died).
  const sim::DescentFailsafe* failsafe = nullptr;
  double min_z = 1e9;  // lowest true height since the last reset

  static Loop Make(const std::string& task, uint64_t seed = 11) {
    const dataset::FlightTask t = *sim::BuiltinFlightTask(task);
    return Loop{*sim::FlightSimulation::Create(t, seed),
                *Autopilot::Create(eval::AutopilotOptionsForTask(t, ControllerType::kPaper))};
  }
  // Runs until t_s; returns the last ground truth.
  const sim::FlightStep& RunUntil(double t_s) {
    const sim::FlightStep* out = &sim.Initial();
    static thread_local sim::RotorVector cmd;
    while (NsToSeconds(sim.t_ns()) < t_s - 1e-9) {
      out = &Next();
    }
    return *out;
  }
  const sim::FlightStep& Next() {
    const sim::FlightStep& out = last_ ? *last_ : sim.Initial();
    if (feed_poses) {
      for (const sim::PoseSample& p : out.poses) {
        (void)ap.FeedPose(PoseMeasurement{p.t_ns, p.sensor, p.T_world_sensor});
      }
    }
    RotorVector command = RotorVector::Zero(6);
    if (feed_imu) {
      command = ap.FeedImu(ImuMeasurement{out.imu.t_ns, out.imu.gyro, out.imu.accel});
    } else {
      ap.CheckImuTimeout(out.t_ns, &command);
      if (!ap.status().armed) command = RotorVector::Zero(6);
    }
    sim::RotorVector c(6);
    for (int i = 0; i < 6; ++i) c[i] = command[i];
    if (failsafe && !ap.armed()) c = failsafe->Command(sim.vehicle().state());
    last_ = &sim.Step(c);
    min_z = std::min(min_z, last_->truth.p_world.z());
    return *last_;
  }
  const sim::FlightStep* last_ = nullptr;
};

TEST(AutopilotTest, ArmsOnlyOnceTheEstimatorConverged) {
  Loop loop = Loop::Make("t3_1");
  EXPECT_EQ(loop.ap.Arm().code(), StatusCode::kFailedPrecondition);  // nothing yet
  EXPECT_EQ(loop.ap.Hover(Eigen::Vector3d(0, 0, 1), 0).code(), StatusCode::kFailedPrecondition);
  loop.RunUntil(1.0);
  EXPECT_FALSE(loop.ap.estimator().converged());
  EXPECT_EQ(loop.ap.Arm().code(), StatusCode::kFailedPrecondition);
  loop.RunUntil(6.0);
  ASSERT_TRUE(loop.ap.estimator().converged());
  ASSERT_TRUE(loop.ap.Arm().ok());
  EXPECT_EQ(loop.ap.Arm().code(), StatusCode::kFailedPrecondition);  // already armed
  EXPECT_EQ(loop.ap.status().mode, FlightMode::kHover);
  // Take off and hover at 1 m.
  ASSERT_TRUE(loop.ap.Hover(Eigen::Vector3d(0, 0, 1), 0).ok());
  const sim::FlightStep& out = loop.RunUntil(14.0);
  EXPECT_LT((out.truth.p_world - Eigen::Vector3d(0, 0, 1)).norm(), 0.08);
  EXPECT_EQ(loop.ap.status().mode, FlightMode::kHover);
  EXPECT_GT(loop.ap.status().commands, 500u);
  EXPECT_LT(loop.ap.status().position_rms_m, 0.3);
  EXPECT_EQ(loop.ap.Hover(Eigen::Vector3d(0, NAN, 1), 0).code(), StatusCode::kInvalidArgument);
}

TEST(AutopilotTest, TrajectoryThenHoverAtItsEnd) {
  Loop loop = Loop::Make("t3_1");
  loop.RunUntil(6.0);
  ASSERT_TRUE(loop.ap.Arm().ok());
  ASSERT_TRUE(loop.ap.Hover(Eigen::Vector3d(0, 0, 1), 0).ok());
  loop.RunUntil(10.0);
  geometry::TrajectoryPoint from = loop.ap.state().reference;
  GoToLimits limits;
  const geometry::PolynomialTrajectory t =
      *MakeGoToTrajectory(from, Eigen::Vector3d(2, 1, 1.5), 0.5, limits);
  EXPECT_EQ(loop.ap.SetTrajectory(t, 0, Eigen::Vector3d(5, 0, 0), false).code(),
            StatusCode::kInvalidArgument);  // starts 5 m away
  ASSERT_TRUE(loop.ap.SetTrajectory(t, 0, Eigen::Vector3d::Zero(), false).ok());
  EXPECT_EQ(loop.ap.status().mode, FlightMode::kTrajectory);
  const sim::FlightStep& out = loop.RunUntil(10.0 + t.duration_s() + 4.0);
  EXPECT_EQ(loop.ap.status().mode, FlightMode::kHover);
  EXPECT_LT((out.truth.p_world - Eigen::Vector3d(2, 1, 1.5)).norm(), 0.08);
  const Eigen::Matrix3d R = out.truth.q_world_body.toRotationMatrix();
  EXPECT_NEAR(std::atan2(R(1, 0), R(0, 0)), 0.5, 0.05);
}

TEST(AutopilotTest, SetGainsWhileFlyingKeepsTheIntegral) {
  Loop loop = Loop::Make("t3_2");  // wind from 40 s: the integral and observer carry it
  loop.RunUntil(6.0);
  ASSERT_TRUE(loop.ap.Arm().ok());
  ASSERT_TRUE(loop.ap.Hover(Eigen::Vector3d(0, 0, 1), 0).ok());
  loop.RunUntil(50.0);
  const Eigen::Vector3d before = loop.ap.state().integral;
  PaperControllerGains g;
  g.attitude_omega_radps = 10;
  ASSERT_TRUE(loop.ap.SetPaperGains(g).ok());
  EXPECT_EQ(loop.ap.state().integral, before);
  g.attitude_zeta = 5;
  const Status bad = loop.ap.SetPaperGains(g);
  EXPECT_EQ(bad.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(bad.message().find("attitude_zeta"), std::string::npos);
  const sim::FlightStep& out = loop.RunUntil(60.0);
  EXPECT_LT((out.truth.p_world - Eigen::Vector3d(0, 0, 1)).norm(), 0.1);
}

TEST(AutopilotTest, PoseLossMeansFailsafeDescentAndImuLossMeansMotorsOff) {
  Loop loop = Loop::Make("t3_1");
  loop.RunUntil(6.0);
  ASSERT_TRUE(loop.ap.Arm().ok());
  ASSERT_TRUE(loop.ap.Hover(Eigen::Vector3d(0, 0, 2), 0).ok());
  loop.RunUntil(12.0);
  loop.feed_poses = false;
  loop.RunUntil(12.9);
  EXPECT_EQ(loop.ap.status().mode, FlightMode::kHover);  // 0.9 s without a pose: still fine
  const sim::FlightStep& at = loop.RunUntil(13.2);
  EXPECT_EQ(loop.ap.status().mode, FlightMode::kFailsafe);
  EXPECT_EQ(loop.ap.status().pose_timeouts, 1u);
  const double z0 = at.truth.p_world.z();
  const sim::FlightStep& later = loop.RunUntil(16.2);
  // Descending at about 0.3 m/s, level.
  EXPECT_NEAR(z0 - later.truth.p_world.z(), 0.9, 0.3);
  EXPECT_LT(later.truth.omega_body.norm(), 0.2);
  // Hover is refused until poses come back.
  EXPECT_EQ(loop.ap.Hover(Eigen::Vector3d(0, 0, 2), 0).code(), StatusCode::kFailedPrecondition);
  loop.feed_poses = true;
  loop.RunUntil(16.5);
  EXPECT_TRUE(loop.ap.Hover(Eigen::Vector3d(0, 0, 2), 0).ok());
  loop.RunUntil(17.0);
  // IMU silence for 0.1 s: the default policy stops the motors.
  loop.feed_imu = false;
  loop.RunUntil(17.05);
  EXPECT_TRUE(loop.ap.status().armed);
  loop.RunUntil(17.15);
  EXPECT_FALSE(loop.ap.status().armed);
  EXPECT_EQ(loop.ap.status().imu_timeouts, 1u);
}

// A controller restarted mid-flight (issue: a killed mav-control): a fresh autopilot, fed from the
// moment the old one died while the vehicle's own failsafe descends it at 0.4 m/s, arms in the
// air once its estimate settled and holds the vehicle where it is.
TEST(AutopilotTest, AFreshAutopilotTakesOverAVehicleInTheAir) {
  Loop loop = Loop::Make("t3_1");
  const dataset::FlightTask task = *sim::BuiltinFlightTask("t3_1");
  AutopilotOptions options = eval::AutopilotOptionsForTask(task, ControllerType::kPaper);
  EXPECT_EQ(loop.ap.ArmInAir().code(), StatusCode::kFailedPrecondition) << "rest_z_m unset";
  loop.RunUntil(6.0);
  ASSERT_TRUE(loop.ap.Arm().ok());
  ASSERT_TRUE(loop.ap.Hover(Eigen::Vector3d(0, 0, 2), 0).ok());
  loop.RunUntil(12.0);
  // The controller dies: the failsafe flies; 1 s later a new one starts and is fed.
  const sim::DescentFailsafe failsafe = *sim::DescentFailsafe::Create(loop.sim.vehicle().params());
  loop.failsafe = &failsafe;
  loop.ap.Disarm();
  loop.RunUntil(13.0);
  options.rest_z_m = task.spawn_position.z();
  loop.ap = *Autopilot::Create(options);
  loop.min_z = 1e9;
  loop.RunUntil(13.2);
  EXPECT_FALSE(loop.ap.ReadyForTakeover());
  const Status early = loop.ap.ArmInAir();
  EXPECT_EQ(early.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(early.message().find("0.5"), std::string::npos) << early.message();
  double t_s = 13.2;
  while (!loop.ap.ReadyForTakeover() && t_s < 15.0) loop.RunUntil(t_s += 0.005);
  const double armed_at_s = t_s;
  ASSERT_TRUE(loop.ap.ArmInAir().ok());
  EXPECT_LT(armed_at_s, 13.7) << "0.5 s of poses after the first one";
  EXPECT_EQ(loop.ap.mode(), FlightMode::kHover);
  const Eigen::Vector3d armed_at = loop.ap.estimator().state().p_world;
  const sim::FlightStep& out = loop.RunUntil(16.0);  // 3 s after the restart
  const Eigen::Vector3d hold = loop.ap.state().reference.position;
  EXPECT_FALSE(loop.ap.moving());
  EXPECT_LT((hold - armed_at).norm(), 1e-9) << "holds where it took over";
  EXPECT_GT(loop.min_z, 1.0) << "never near the ground";
  EXPECT_LT(out.truth.v_world.norm(), 0.1) << "hovering again";
  EXPECT_LT((out.truth.p_world - hold).norm(), 0.1);
  EXPECT_GT(hold.z(), 1.2);
  EXPECT_EQ(loop.ap.status().pose_timeouts, 0u);
  std::cout << "takeover: armed in the air " << armed_at_s - 13.0 << " s after the restart at "
            << armed_at.z() << " m, stopped at " << hold.z() << " m; lowest " << loop.min_z
            << " m; 3 s after the restart " << (out.truth.p_world - hold).norm()
            << " m from the hold, speed " << out.truth.v_world.norm() << " m/s\n";
}

// On the ground a takeover is refused (the failsafe landed it, or it never flew): Arm is the way.
TEST(AutopilotTest, TakeoverIsRefusedOnTheGround) {
  const dataset::FlightTask task = *sim::BuiltinFlightTask("t3_1");
  Loop loop = Loop::Make("t3_1");
  AutopilotOptions options = eval::AutopilotOptionsForTask(task, ControllerType::kPaper);
  options.rest_z_m = task.spawn_position.z();
  loop.ap = *Autopilot::Create(options);
  loop.RunUntil(1.0);
  ASSERT_TRUE(loop.ap.ReadyForTakeover());
  const Status refused = loop.ap.ArmInAir();
  EXPECT_EQ(refused.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(refused.message().find("not airborne"), std::string::npos) << refused.message();
  EXPECT_FALSE(loop.ap.armed());
  options.takeover_settle_s = -1;
  EXPECT_NE(Autopilot::Create(options).status().message().find("takeover_settle_s"),
            std::string::npos);
}

TEST(AutopilotTest, OptionsNameTheBadField) {
  AutopilotOptions o;
  o.estimator.pose_sources[0].rate_hz = -1;
  const auto r = Autopilot::Create(o);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("estimator.pose_sources[0].rate_hz"), std::string::npos);
  o = AutopilotOptions();
  o.pose_timeout_s = 0;
  EXPECT_NE(Autopilot::Create(o).status().message().find("pose_timeout_s"), std::string::npos);
}

}  // namespace
}  // namespace mav::control
