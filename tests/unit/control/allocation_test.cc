#include "mav/control/allocation.h"

#include <string>

#include <gtest/gtest.h>

namespace mav::control {
namespace {

TEST(AllocationTest, InvertsTheMixer) {
  const VehicleParameters v;
  const Allocator alloc(v, AllocationOptions());
  for (const Wrench& w :
       {Wrench(15, 0, 0, 0), Wrench(18, 0.3, -0.2, 0.05), Wrench(12, -0.5, 0.4, -0.1)}) {
    AllocationResult r;
    const RotorVector speeds = alloc.Allocate(w, &r);
    EXPECT_LT((alloc.Mix(speeds) - w).norm(), 1e-9 * w.norm());
    EXPECT_FALSE(r.thrust_saturated);
    EXPECT_EQ(r.roll_pitch_scale, 1);
    EXPECT_EQ(r.yaw_scale, 1);
  }
  // And the mixer inverts the allocation: speeds -> wrench -> the same speeds (the hexacopter's
  // least-squares solution is unique in the span of A^T).
  RotorVector u(6);
  u << 400, 420, 410, 430, 405, 415;
  const RotorVector back = alloc.Allocate(alloc.Mix(u));
  EXPECT_LT((alloc.Mix(back) - alloc.Mix(u)).norm(), 1e-9);
}

TEST(AllocationTest, SaturationKeepsThrustThenRollPitchThenYaw) {
  const VehicleParameters v;
  const Allocator alloc(v, AllocationOptions());
  // A yaw request far beyond reach: thrust and roll/pitch are delivered exactly, yaw scaled.
  AllocationResult r;
  const Wrench w(16, 0.2, -0.1, 5.0);
  RotorVector s = alloc.Allocate(w, &r);
  EXPECT_NEAR(r.achieved[0], 16, 1e-9);
  EXPECT_NEAR(r.achieved[1], 0.2, 1e-9);
  EXPECT_NEAR(r.achieved[2], -0.1, 1e-9);
  EXPECT_LT(r.yaw_scale, 1);
  EXPECT_GT(r.achieved[3], 0);
  EXPECT_NEAR(r.achieved[3], 5.0 * r.yaw_scale, 1e-9);
  EXPECT_LE(s.maxCoeff(), v.max_rotor_speed_radps + 1e-9);
  // A roll request beyond reach below half the range (18 N): thrust kept, roll/pitch scaled in
  // its direction, no yaw left.
  s = alloc.Allocate(Wrench(16, 10, 5, 0.1), &r);
  EXPECT_NEAR(r.achieved[0], 16, 1e-9);
  EXPECT_LT(r.roll_pitch_scale, 1);
  EXPECT_NEAR(r.achieved[1] / r.achieved[2], 2.0, 1e-9);
  EXPECT_GE(s.minCoeff(), 0);
  // Thrust beyond the rotors' limit is clamped first.
  alloc.Allocate(Wrench(100, 0, 0, 0), &r);
  EXPECT_TRUE(r.thrust_saturated);
  EXPECT_NEAR(r.achieved[0], v.MaxThrust(), 1e-6);
}

// Above half the rotors' range the thrust gives way to roll/pitch, down to that thrust at most.
TEST(AllocationTest, AtTheTopRollPitchComesBeforeThrust) {
  const VehicleParameters v;
  const Allocator alloc(v, AllocationOptions());
  const double mid = 0.5 * v.MaxThrust();
  AllocationResult r;
  // 1 N m of roll does not fit beside 30 N (the rotors' room above is ~0.65 N m) but fits lower.
  alloc.Allocate(Wrench(30, 1.0, 0, 0), &r);
  EXPECT_NEAR(r.roll_pitch_scale, 1, 1e-12);
  EXPECT_NEAR(r.achieved[1], 1.0, 1e-9);
  EXPECT_LT(r.achieved[0], 30 - 1);
  EXPECT_GT(r.achieved[0], mid);
  EXPECT_TRUE(r.thrust_saturated);  // the thrust was not delivered: the integrators freeze
  // Out of reach anywhere: the thrust goes down to the middle, roll/pitch keep their direction.
  alloc.Allocate(Wrench(30, 10, 5, 0), &r);
  EXPECT_NEAR(r.achieved[0], mid, 1e-6);
  EXPECT_LT(r.roll_pitch_scale, 1);
  EXPECT_NEAR(r.achieved[1] / r.achieved[2], 2.0, 1e-9);
  // Full thrust with a roll request: strict thrust priority leaves no torque at all.
  AllocationOptions strict;
  strict.roll_pitch_before_thrust_at_top = false;
  Allocator(v, strict).Allocate(Wrench(v.MaxThrust(), 0.5, 0, 0), &r);
  EXPECT_EQ(r.roll_pitch_scale, 0);
  alloc.Allocate(Wrench(v.MaxThrust(), 0.5, 0, 0), &r);
  EXPECT_NEAR(r.roll_pitch_scale, 1, 1e-12);
  // Below the middle nothing changes: thrust first.
  alloc.Allocate(Wrench(10, 3, 0, 0), &r);
  EXPECT_NEAR(r.achieved[0], 10, 1e-9);
  EXPECT_LT(r.roll_pitch_scale, 1);
}

// MaxRollPitchTorque is the reach of Allocate: just below it the torque is delivered in full,
// just above it is scaled.
TEST(AllocationTest, MaxRollPitchTorqueIsTheReachOfAllocate) {
  const VehicleParameters v;
  for (bool top : {true, false}) {
    AllocationOptions o;
    o.roll_pitch_before_thrust_at_top = top;
    o.min_rotor_speed_radps = 100;
    const Allocator alloc(v, o);
    for (double thrust : {3.0, 14.7, 18.0, 25.0, 34.0}) {
      for (const Eigen::Vector2d& d : {Eigen::Vector2d(1, 0), Eigen::Vector2d(0, 1),
                                       Eigen::Vector2d(1, 1), Eigen::Vector2d(-0.3, 0.8)}) {
        const double reach = alloc.MaxRollPitchTorque(thrust, d);
        ASSERT_GT(reach, 0.05) << thrust;
        const Eigen::Vector2d u = d.normalized();
        AllocationResult r;
        alloc.Allocate(Wrench(thrust, 0.999 * reach * u.x(), 0.999 * reach * u.y(), 0), &r);
        EXPECT_EQ(r.roll_pitch_scale, 1) << thrust << " " << d.transpose();
        alloc.Allocate(Wrench(thrust, 1.01 * reach * u.x(), 1.01 * reach * u.y(), 0), &r);
        EXPECT_LT(r.roll_pitch_scale, 1) << thrust << " " << d.transpose();
      }
    }
    // The Firefly at hover thrust: about 1.6 N m of roll, 1.8 N m of pitch.
    EXPECT_NEAR(alloc.MaxRollPitchTorque(1.5 * kGravity, Eigen::Vector2d(1, 0)), 1.6, 0.1);
    EXPECT_NEAR(alloc.MaxRollPitchTorque(1.5 * kGravity, Eigen::Vector2d(0, 1)), 1.8, 0.1);
  }
  EXPECT_EQ(Allocator(v, AllocationOptions()).MaxRollPitchTorque(15, Eigen::Vector2d::Zero()), 0);
}

TEST(AllocationTest, ClipPolicyClampsEachRotor) {
  const VehicleParameters v;
  AllocationOptions o;
  o.saturation = SaturationPolicy::kClip;
  const Allocator alloc(v, o);
  AllocationResult r;
  const RotorVector s = alloc.Allocate(Wrench(16, 0, 0, 5.0), &r);
  EXPECT_LE(s.maxCoeff(), v.max_rotor_speed_radps + 1e-9);
  EXPECT_EQ(s.minCoeff(), 0);                    // the yaw request drives three rotors to zero
  EXPECT_GT(std::abs(r.achieved[0] - 16), 0.5);  // and the thrust is lost with them
}

TEST(VehicleTest, FireflyIsValidAndBadFieldsAreNamed) {
  VehicleParameters v;
  std::string why;
  EXPECT_TRUE(v.IsValid(&why)) << why;
  v.rotor_directions[2] = 0;
  EXPECT_FALSE(v.IsValid(&why));
  EXPECT_NE(why.find("rotor_directions[2]"), std::string::npos);
  v = VehicleParameters();
  v.max_rotor_speed_radps = 300;
  EXPECT_FALSE(v.IsValid(&why));
  EXPECT_NE(why.find("max_rotor_speed_radps"), std::string::npos);
}

TEST(AllocationTest, OptionsNameTheirFieldsAndMustFitTheVehicle) {
  const VehicleParameters firefly;  // the defaults are the Firefly
  AllocationOptions options;
  std::string why;
  EXPECT_TRUE(options.IsValid(&why));
  EXPECT_TRUE(options.FitsVehicle(firefly, &why));
  options.min_rotor_speed_radps = firefly.max_rotor_speed_radps;
  EXPECT_TRUE(options.IsValid(&why));  // valid alone
  EXPECT_FALSE(options.FitsVehicle(firefly, &why));
  EXPECT_EQ(why, "min_rotor_speed_radps: must be below vehicle.max_rotor_speed_radps");
  options.min_rotor_speed_radps = -1;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_EQ(why, "min_rotor_speed_radps: must be >= 0");
}

}  // namespace
}  // namespace mav::control
