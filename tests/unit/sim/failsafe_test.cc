// The vehicle's own failsafe (mav/sim/failsafe.h) flying sim::Multicopter at 1 kHz: from a
// disturbed state it levels, stops turning, descends at its rate and lands softly, where the
// motors-off it replaces hits the ground at several m/s; on the ground it keeps the motors off.

#include "mav/sim/failsafe.h"

#include <cmath>

#include <gtest/gtest.h>

#include <Eigen/Geometry>

namespace mav::sim {
namespace {

constexpr double kDt = 0.001;

double HoverSpeed(const MulticopterParams& p) {
  return std::sqrt(p.mass_kg * p.gravity_mps2 / (p.rotor_count * p.thrust_constant));
}

// Airborne at `height` m over the ground at z = 0, tilted, turning, drifting and climbing, the
// rotors at hover speed: what a controller that just died leaves behind.
Multicopter Disturbed(const MulticopterParams& p, double height) {
  Multicopter mc(p);
  mc.Reset(Eigen::Vector3d(0, 0, height), 0.4, /*on_ground=*/false, 0.0);
  MulticopterState s = mc.state();
  s.q_world_body = Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ()) *
                   Eigen::AngleAxisd(0.35, Eigen::Vector3d::UnitX()) *  // 20 deg roll
                   Eigen::AngleAxisd(-0.17, Eigen::Vector3d::UnitY());  // 10 deg pitch
  s.omega_body = Eigen::Vector3d(0.5, -0.3, 1.0);
  s.v_world = Eigen::Vector3d(1.0, -0.5, 0.5);
  s.rotor_speeds_radps = RotorVector::Constant(p.rotor_count, HoverSpeed(p));
  mc.SetState(s);
  return mc;
}

double TiltRad(const MulticopterState& s) {
  return std::acos(std::clamp(s.q_world_body.toRotationMatrix()(2, 2), -1.0, 1.0));
}

TEST(DescentFailsafeTest, LevelsDescendsAtItsRateAndLandsSoftly) {
  const MulticopterParams p;
  const DescentFailsafe failsafe = *DescentFailsafe::Create(p);
  Multicopter mc = Disturbed(p, 3.0);
  GroundContact landing;
  double t = 0;
  double max_tilt_after_1s = 0, max_descent_error_after_2s = 0;
  for (; t < 20 && !landing.touched_down; t += kDt) {
    const GroundContact c = mc.Step(failsafe.Command(mc.state()), kDt);
    if (c.touched_down) landing = c;
    if (t > 1.0) max_tilt_after_1s = std::max(max_tilt_after_1s, TiltRad(mc.state()));
    if (t > 2.0 && mc.state().p_world.z() > 0.3) {
      max_descent_error_after_2s =
          std::max(max_descent_error_after_2s, std::abs(mc.state().v_world.z() + 0.4));
    }
  }
  ASSERT_TRUE(landing.touched_down) << "still airborne after 20 s";
  EXPECT_LT(max_tilt_after_1s, 3.0 * M_PI / 180) << "not level a second after taking over";
  EXPECT_LT(std::abs(mc.state().omega_body.z()), 0.1);
  EXPECT_LT(max_descent_error_after_2s, 0.1) << "descent rate not held at 0.4 m/s";
  // A landing, not a collision (FlightSimulationOptions::landing_speed_mps = 0.5).
  EXPECT_LT(landing.impact_speed_mps, 0.5);
  // From 3 m at 0.4 m/s, after stopping the initial 0.5 m/s climb: about 8 s.
  EXPECT_GT(t, 6.5);
  EXPECT_LT(t, 10.0);
  std::printf("failsafe: landed after %.2f s at %.2f m/s, max tilt after 1 s %.2f deg\n", t,
              landing.impact_speed_mps, max_tilt_after_1s * 180 / M_PI);

  // On the ground: motors off, and it stays there.
  for (int k = 0; k < 500; ++k) mc.Step(failsafe.Command(mc.state()), kDt);
  EXPECT_TRUE(mc.state().on_ground);
  EXPECT_EQ(failsafe.Command(mc.state()).norm(), 0.0);
}

TEST(DescentFailsafeTest, MotorsOffHitTheGroundHard) {
  // What the failsafe replaces: the same vehicle with its motors stopped.
  const MulticopterParams p;
  Multicopter mc = Disturbed(p, 3.0);
  GroundContact landing;
  for (double t = 0; t < 5 && !landing.touched_down; t += kDt) {
    const GroundContact c = mc.Step(RotorVector::Zero(p.rotor_count), kDt);
    if (c.touched_down) landing = c;
  }
  ASSERT_TRUE(landing.touched_down);
  EXPECT_GT(landing.impact_speed_mps, 6.0);
}

TEST(DescentFailsafeTest, BadOptionsAreNamed) {
  FailsafeOptions o;
  o.descent_mps = 0;
  Result<DescentFailsafe> bad = DescentFailsafe::Create(MulticopterParams(), o);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("descent_mps"), std::string::npos);
  o = FailsafeOptions();
  o.rate_gain_per_s = std::nan("");
  EXPECT_FALSE(DescentFailsafe::Create(MulticopterParams(), o).ok());
}

}  // namespace
}  // namespace mav::sim
