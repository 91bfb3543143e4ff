#include "mav/control/allocation.h"

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
  // A roll request beyond reach: thrust kept, roll/pitch scaled in its direction, no yaw left.
  s = alloc.Allocate(Wrench(20, 10, 5, 0.1), &r);
  EXPECT_NEAR(r.achieved[0], 20, 1e-9);
  EXPECT_LT(r.roll_pitch_scale, 1);
  EXPECT_NEAR(r.achieved[1] / r.achieved[2], 2.0, 1e-9);
  EXPECT_GE(s.minCoeff(), 0);
  // Thrust beyond the rotors' limit is clamped first.
  alloc.Allocate(Wrench(100, 0, 0, 0), &r);
  EXPECT_TRUE(r.thrust_saturated);
  EXPECT_NEAR(r.achieved[0], v.MaxThrust(), 1e-6);
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

}  // namespace
}  // namespace mav::control
