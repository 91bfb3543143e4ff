#include "mav/sim/collision_world.h"

#include <cstdio>
#include <random>

#include <gtest/gtest.h>
#include <octomap/OcTree.h>

#include "mav/sim/world.h"

namespace mav::sim {
namespace {

TEST(CollisionWorldTest, OctomapClearanceIsTheExactDistanceToTheNearestOccupiedVoxel) {
  octomap::OcTree tree(0.25);
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(-5, 5);
  std::vector<Eigen::Vector3d> centres;
  for (int i = 0; i < 40; ++i) {
    // One draw per statement: the order of arguments' evaluation is unspecified.
    const float x = static_cast<float>(u(rng));
    const float y = static_cast<float>(u(rng));
    const float z = static_cast<float>(u(rng));
    const octomap::point3d p(x, y, z);
    octomap::OcTreeNode* n = tree.updateNode(p, true);
    tree.updateNode(p, true);
    ASSERT_NE(n, nullptr);
  }
  tree.updateNode(octomap::point3d(0.1f, 0.1f, 0.1f), false);  // a free leaf must not count
  for (auto it = tree.begin_leafs(); it != tree.end_leafs(); ++it) {
    if (tree.isNodeOccupied(*it)) centres.emplace_back(it.getX(), it.getY(), it.getZ());
  }
  const std::string path = ::testing::TempDir() + "/collision_world_test.bt";
  ASSERT_TRUE(tree.writeBinary(path));
  const auto world = LoadOctomapCollisionWorld(path);
  ASSERT_TRUE(world.ok()) << world.status().ToString();
  for (int k = 0; k < 200; ++k) {
    const Eigen::Vector3d p(u(rng), u(rng), u(rng));
    double brute = 1e9;
    for (const Eigen::Vector3d& c : centres) {
      const Eigen::Vector3d d = ((p - c).cwiseAbs().array() - 0.125).max(0.0).matrix();
      brute = std::min(brute, d.norm());
    }
    EXPECT_NEAR((*world)->Clearance(p, 20.0), brute, 1e-5) << p.transpose();
    EXPECT_NEAR((*world)->Clearance(p, 0.5), std::min(brute, 0.5), 1e-5);
  }
  EXPECT_NE((*world)->Describe().find("collision_world_test.bt"), std::string::npos);
  std::remove(path.c_str());
  EXPECT_EQ(LoadOctomapCollisionWorld("/nonexistent.bt").status().code(), StatusCode::kNotFound);
}

TEST(CollisionWorldTest, PrimitivesUseTheExactSignedDistance) {
  auto world = std::make_shared<World>();
  world->AddAlignedBox(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 1, 1),
                       world->AddMaterial(Material()));
  const auto cw = MakePrimitiveCollisionWorld(world);
  EXPECT_NEAR(cw->Clearance(Eigen::Vector3d(0.5, 0.5, 3), 10), 2.0, 1e-12);
  EXPECT_NEAR(cw->Clearance(Eigen::Vector3d(0.5, 0.5, 0.5), 10), -0.5, 1e-12);
  EXPECT_EQ(cw->Clearance(Eigen::Vector3d(0.5, 0.5, 30), 10), 10);
}

}  // namespace
}  // namespace mav::sim
