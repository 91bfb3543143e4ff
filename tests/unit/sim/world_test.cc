// World tests: exact signed distances, ray casting against hand-computed hits, composites.

#include <cmath>

#include <gtest/gtest.h>

#include "mav/sim/presets.h"
#include "mav/sim/world.h"

namespace mav::sim {
namespace {

using Eigen::Vector3d;

World SimpleWorld(int* box, int* cyl) {
  World w;
  const int m = w.AddMaterial(Material());
  *box = w.AddAlignedBox(Vector3d(0, 0, 0), Vector3d(2, 1, 1), m);
  *cyl = w.AddCylinder(Vector3d(5, 0, 0), Vector3d(5, 0, 2), 0.5, m);
  return w;
}

TEST(WorldTest, SignedDistanceIsExact) {
  int box, cyl;
  const World w = SimpleWorld(&box, &cyl);
  EXPECT_NEAR(w.SignedDistance(Vector3d(1, 0.5, 2)), 1.0, 1e-12);             // above the box
  EXPECT_NEAR(w.SignedDistance(Vector3d(1, 0.5, 0.5)), -0.5, 1e-12);          // inside, centre
  EXPECT_NEAR(w.SignedDistance(Vector3d(3, 2, 2)), std::sqrt(3.0), 1e-12);    // corner
  EXPECT_NEAR(w.SignedDistance(Vector3d(5, 1.5, 1)), 1.0, 1e-12);             // beside the cylinder
  EXPECT_NEAR(w.SignedDistance(Vector3d(5, 0, 3)), 1.0, 1e-12);               // above its cap
  EXPECT_NEAR(w.SignedDistance(Vector3d(5, 0.2, 1)), -0.3, 1e-12);            // inside
  EXPECT_NEAR(w.SignedDistance(Vector3d(5, 1.5, 3)), std::sqrt(2.0), 1e-12);  // rim
  EXPECT_TRUE(w.IsInsideSolid(Vector3d(0.1, 0.1, 0.1)));
  EXPECT_FALSE(w.IsInsideSolid(Vector3d(3.5, 0, 0.5)));
}

TEST(WorldTest, DecalsDoNotCountAsSolid) {
  World w;
  const int m = w.AddMaterial(Material());
  w.AddRectangle(Vector3d::Zero(), Eigen::Matrix3d::Identity(), Eigen::Vector2d(1, 1), m);
  EXPECT_TRUE(std::isinf(w.SignedDistance(Vector3d(0, 0, 1))));
  w.AddRectangle(Vector3d::Zero(), Eigen::Matrix3d::Identity(), Eigen::Vector2d(1, 1), m, true);
  EXPECT_NEAR(w.SignedDistance(Vector3d(0, 0, 1)), 1.0, 1e-12);
}

TEST(WorldTest, RayHitsAreExact) {
  int box, cyl;
  const World w = SimpleWorld(&box, &cyl);
  // Along +x at height 0.5 from x = -1: hits the box face x = 0.
  auto hit = w.CastRay(Vector3d(-1, 0.5, 0.5), Vector3d(1, 0, 0));
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->primitive, box);
  EXPECT_NEAR(hit->t, 1.0, 1e-12);
  EXPECT_TRUE(hit->normal_world.isApprox(Vector3d(-1, 0, 0)));
  // From between box and cylinder towards the cylinder: side at x = 4.5.
  hit = w.CastRay(Vector3d(3, 0, 1), Vector3d(1, 0, 0));
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->primitive, cyl);
  EXPECT_NEAR(hit->t, 1.5, 1e-12);
  // Down onto the cylinder cap from above.
  hit = w.CastRay(Vector3d(5.2, 0.1, 4), Vector3d(0, 0, -1));
  ASSERT_TRUE(hit.has_value());
  EXPECT_NEAR(hit->t, 2.0, 1e-12);
  EXPECT_TRUE(hit->normal_world.isApprox(Vector3d(0, 0, 1)));
  // Oblique ray onto the side: x^2 + y^2 = 0.25 around (5, 0).
  const Vector3d d = Vector3d(1, 1, 0).normalized();
  hit = w.CastRay(Vector3d(4, -1, 1), d);
  ASSERT_TRUE(hit.has_value());
  const Vector3d p = Vector3d(4, -1, 1) + hit->t * d;
  EXPECT_NEAR(std::hypot(p.x() - 5, p.y()), 0.5, 1e-9);
  // Misses.
  EXPECT_FALSE(w.CastRay(Vector3d(-1, 5, 0.5), Vector3d(1, 0, 0)).has_value());
}

TEST(WorldTest, BoundsOfRotatedPrimitivesAreTight) {
  World w;
  const int m = w.AddMaterial(Material());
  const int c = w.AddCylinder(Vector3d(0, 0, 0), Vector3d(3, 4, 0), 1.0, m);
  const Eigen::AlignedBox3d b = w.primitives()[c].Bounds();
  // Axis direction (0.6, 0.8, 0): extent along x = 0 .. 3 plus r * sqrt(1 - 0.36) = 0.8.
  EXPECT_NEAR(b.min().x(), -0.8, 1e-12);
  EXPECT_NEAR(b.max().x(), 3.8, 1e-12);
  EXPECT_NEAR(b.min().y(), -0.6, 1e-12);
  EXPECT_NEAR(b.max().y(), 4.6, 1e-12);
  EXPECT_NEAR(b.max().z(), 1.0, 1e-12);
}

TEST(WorldTest, PresetWorldsLeaveRoomToFly) {
  for (const std::string& name : PresetNames()) {
    Result<Preset> p = MakePreset(name);
    ASSERT_TRUE(p.ok());
    const World& w = *p->world;
    EXPECT_GT(w.primitives().size(), 20u) << name;
    // The centre of the flight box's bottom layer near look_at is reachable: some point of the
    // flight box has the required clearance.
    int clear = 0, total = 0;
    const Eigen::AlignedBox3d& fb = p->flight_bounds;
    for (double fx = 0.05; fx < 1; fx += 0.1) {
      for (double fy = 0.05; fy < 1; fy += 0.1) {
        const Vector3d q = fb.min() + (fb.sizes().array() * Eigen::Array3d(fx, fy, 0.5)).matrix();
        clear += w.SignedDistance(q) >= p->min_clearance;
        ++total;
      }
    }
    EXPECT_GT(clear, total / 2) << name;
    // Everything solid lies inside the world's bounds.
    for (const Primitive& prim : w.primitives()) {
      EXPECT_TRUE(w.bounds().contains(prim.Bounds())) << name;
    }
  }
}

}  // namespace
}  // namespace mav::sim
