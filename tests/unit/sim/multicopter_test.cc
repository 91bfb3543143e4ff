#include "mav/sim/multicopter.h"

#include <cmath>

#include <gtest/gtest.h>

#include "mav/sim/flight_simulation.h"
#include "mav/sim/world.h"

namespace mav::sim {
namespace {

MulticopterParams Firefly() { return MulticopterParams(); }

double HoverSpeed(const MulticopterParams& p) {
  return std::sqrt(p.mass_kg * p.gravity_mps2 / (p.rotor_count * p.thrust_constant));
}

TEST(MulticopterTest, FreeFallIsExact) {
  Multicopter mc(Firefly());
  mc.Reset(Eigen::Vector3d(0, 0, 50), 0.3, /*on_ground=*/false, 0);
  const RotorVector off = RotorVector::Zero(6);
  for (int k = 0; k < 100; ++k) mc.Step(off, 0.01);
  EXPECT_NEAR(mc.state().p_world.z(), 50 - 0.5 * 9.81, 1e-9);
  EXPECT_NEAR(mc.state().v_world.z(), -9.81, 1e-9);
  EXPECT_NEAR(mc.state().p_world.head<2>().norm(), 0, 1e-12);
  EXPECT_NEAR(mc.SpecificForceBody().norm(), 0, 1e-12);  // a falling accelerometer reads zero
}

TEST(MulticopterTest, HoverThrustEqualsWeight) {
  const MulticopterParams p = Firefly();
  Multicopter mc(p);
  mc.Reset(Eigen::Vector3d(0, 0, 5), 0, false, 0);
  MulticopterState s = mc.state();
  s.rotor_speeds_radps = RotorVector::Constant(6, HoverSpeed(p));
  mc.SetState(s);
  const RotorVector hover = RotorVector::Constant(6, HoverSpeed(p));
  for (int k = 0; k < 500; ++k) mc.Step(hover, 0.01);
  EXPECT_NEAR(mc.RotorWrench()[0], p.mass_kg * p.gravity_mps2, 1e-9);
  // Alternating spin directions cancel the reactive yaw torques; the symmetric arms the rest.
  EXPECT_LT(mc.RotorWrench().tail<3>().norm(), 1e-12);
  EXPECT_LT(mc.state().v_world.norm(), 1e-9);
  EXPECT_LT(mc.state().omega_body.norm(), 1e-12);
  EXPECT_NEAR(mc.state().p_world.z(), 5, 1e-9);
  EXPECT_NEAR(mc.SpecificForceBody().z(), 9.81, 1e-9);
}

TEST(MulticopterTest, TorqueFreeSpinConservesAngularMomentumAndEnergy) {
  Multicopter mc(Firefly());
  mc.Reset(Eigen::Vector3d(0, 0, 100), 0, false, 0);
  MulticopterState s = mc.state();
  s.omega_body = Eigen::Vector3d(1.0, -0.5, 2.0);
  mc.SetState(s);
  const Eigen::Vector3d J = Firefly().inertia_kgm2;
  auto momentum = [&] {
    return Eigen::Vector3d(mc.state().q_world_body * J.cwiseProduct(mc.state().omega_body));
  };
  auto energy = [&] {
    return 0.5 * mc.state().omega_body.dot(J.cwiseProduct(mc.state().omega_body));
  };
  const Eigen::Vector3d L0 = momentum();
  const double E0 = energy();
  for (int k = 0; k < 300; ++k) mc.Step(RotorVector::Zero(6), 0.01);
  EXPECT_LT((momentum() - L0).norm() / L0.norm(), 1e-8);
  EXPECT_NEAR(energy(), E0, 1e-8 * E0);
  // The body really tumbles (the rates change direction), so the check is not vacuous.
  EXPECT_GT((mc.state().omega_body - Eigen::Vector3d(1.0, -0.5, 2.0)).norm(), 0.1);
}

TEST(MulticopterTest, MotorLagIsFirstOrderWithUpAndDownConstants) {
  const MulticopterParams p = Firefly();
  Multicopter mc(p);
  mc.Reset(Eigen::Vector3d(0, 0, 100), 0, false, 0);
  mc.Step(RotorVector::Constant(6, 500), p.motor_time_constant_up_s);
  EXPECT_NEAR(mc.state().rotor_speeds_radps[0], 500 * (1 - std::exp(-1.0)), 0.5);
  for (int k = 0; k < 100; ++k) mc.Step(RotorVector::Constant(6, 500), 0.01);
  mc.Step(RotorVector::Constant(6, 0), p.motor_time_constant_down_s);
  EXPECT_NEAR(mc.state().rotor_speeds_radps[0], 500 * std::exp(-1.0), 0.5);
  // Commands beyond the limit are clamped.
  for (int k = 0; k < 100; ++k) mc.Step(RotorVector::Constant(6, 5000), 0.01);
  EXPECT_NEAR(mc.state().rotor_speeds_radps[0], p.max_rotor_speed_radps, 1e-6);
}

TEST(MulticopterTest, RestsOnTheGroundUntilItLiftsOffAndReportsTouchdown) {
  const MulticopterParams p = Firefly();
  Multicopter mc(p);
  mc.Reset(Eigen::Vector3d(1, 2, 0.5), 0.2, /*on_ground=*/true, /*ground_z=*/0.1);
  EXPECT_NEAR(mc.state().p_world.z(), 0.1 + p.rest_height_m, 1e-12);
  for (int k = 0; k < 200; ++k) mc.Step(RotorVector::Constant(6, 0.95 * HoverSpeed(p)), 0.01);
  EXPECT_TRUE(mc.state().on_ground);
  EXPECT_NEAR(mc.state().p_world.z(), 0.1 + p.rest_height_m, 1e-12);
  EXPECT_NEAR(mc.SpecificForceBody().z(), 9.81, 1e-9);  // the ground holds it up
  for (int k = 0; k < 100; ++k) mc.Step(RotorVector::Constant(6, 1.1 * HoverSpeed(p)), 0.01);
  EXPECT_FALSE(mc.state().on_ground);
  EXPECT_GT(mc.state().p_world.z(), 0.3);
  GroundContact contact;
  for (int k = 0; k < 300 && !contact.touched_down; ++k)
    contact = mc.Step(RotorVector::Zero(6), 0.01);
  EXPECT_TRUE(contact.touched_down);
  EXPECT_GT(contact.impact_speed_mps, 1.0);
  EXPECT_TRUE(mc.state().on_ground);
  EXPECT_EQ(mc.state().v_world.norm(), 0);
}

dataset::FlightTask FallingTask() {
  dataset::FlightTask t;
  t.name = "fall";
  t.duration_s = 3;
  t.spawn_position = Eigen::Vector3d(0, 0, 3);  // in the air: it falls
  t.goals = {dataset::FlightGoal{0, Eigen::Vector3d(0, 0, 3), 0}};
  return t;
}

TEST(FlightSimulationTest, ReportsCollisionsWithTheWorldAndTheGround) {
  auto world = std::make_shared<World>();
  const int m = world->AddMaterial(Material());
  world->AddAlignedBox(Eigen::Vector3d(-1, -1, 0), Eigen::Vector3d(1, 1, 1.5), m);
  FlightSimulation sim = *FlightSimulation::Create(
      FallingTask(), 1, {}, MakePrimitiveCollisionWorld(std::shared_ptr<const World>(world)));
  const RotorVector off = RotorVector::Zero(6);
  while (!sim.done()) sim.Step(off);
  ASSERT_GE(sim.collisions().size(), 1u);
  const Collision& c = sim.collisions().front();
  // Contact when the 0.35 m sphere reaches the box top at 1.5 m: origin at 1.85 m, ~0.34 s in.
  EXPECT_NEAR(c.p_world.z(), 1.85, 0.1);
  EXPECT_NEAR(c.t_ns * 1e-9, std::sqrt(2 * (3 - 1.85) / 9.81), 0.02);
  EXPECT_NE(c.what.find("primitives"), std::string::npos);
  EXPECT_LT(sim.min_clearance_m(), 0.35);

  // Without a world the hard landing on the ground is the collision.
  FlightSimulation bare = *FlightSimulation::Create(FallingTask(), 1);
  while (!bare.done()) bare.Step(off);
  ASSERT_EQ(bare.collisions().size(), 1u);
  EXPECT_NE(bare.collisions()[0].what.find("ground"), std::string::npos);
}

TEST(FlightSimulationTest, ForcesAndGoalsFollowTheTaskSchedule) {
  dataset::FlightTask t = FallingTask();
  t.spawn_position = Eigen::Vector3d(0, 0, 0.08);      // resting on the ground
  t.forces = {{Eigen::Vector3d(0, 0, 20), 1.0, 1.5}};  // lifts the 1.5 kg vehicle for 0.5 s
  t.goals = {dataset::FlightGoal{0, Eigen::Vector3d(0, 0, 1), 0},
             dataset::FlightGoal{2, Eigen::Vector3d(1, 0, 1), 0}};
  FlightSimulation sim = *FlightSimulation::Create(t, 1);
  EXPECT_EQ(sim.Initial().goal_index, 0);
  double max_z = 0;
  bool published = false;
  while (!sim.done()) {
    const FlightStep& out = sim.Step(RotorVector::Zero(6));
    const double ts = out.t_ns * 1e-9;
    if (ts > 1.0 + 1e-6 && ts <= 1.5 + 1e-6) {
      EXPECT_NEAR(out.force_world_n.z(), 20, 1e-12) << ts;
    } else {
      EXPECT_EQ(out.force_world_n.z(), 0) << ts;
    }
    if (out.goal_published) {
      EXPECT_EQ(out.goal_index, 1);
      EXPECT_NEAR(ts, 2.0, 1e-9);
      published = true;
    }
    max_z = std::max(max_z, out.truth.p_world.z());
  }
  EXPECT_TRUE(published);
  // (20 - 14.715) / 1.5 = 3.52 m/s^2 for 0.5 s: up about 0.44 m before falling back.
  EXPECT_NEAR(max_z - 0.08, 0.5 * 3.5233 * 0.25 + 0.5 * (3.5233 * 0.5) * (3.5233 * 0.5) / 9.81,
              0.02);
  EXPECT_TRUE(sim.lifted_off());
}

}  // namespace
}  // namespace mav::sim
