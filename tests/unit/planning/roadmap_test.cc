#include "mav/planning/roadmap.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>

#include "mav/common/file.h"
#include "test_maps.h"
#include "tests/common/build_paths.h"

namespace mav::planning {
namespace {

using testing::LoadMap;
using testing::RoomBytes;

class RoadmapTest : public ::testing::Test {
 protected:
  void SetUp() override { ASSERT_NE(testing::RoomMap(), nullptr); }
  static const PlanningMap& map() { return *testing::RoomMap(); }

  static RoadmapOptions SmallOptions(uint64_t seed) {
    RoadmapOptions options;
    options.max_milestones = 500;
    options.seed = seed;
    options.time_budget_s = 60;
    return options;
  }
};

TEST_F(RoadmapTest, MilestonesAndEdgesKeepTheClearanceAtEveryPoint) {
  auto roadmap = Roadmap::Build(map(), SmallOptions(1));
  ASSERT_TRUE(roadmap.ok()) << roadmap.status().ToString();
  const Roadmap& r = **roadmap;
  EXPECT_EQ(r.num_milestones(), 500u);
  EXPECT_GT(r.edges().size(), 2000u);
  EXPECT_GT(r.info().largest_component, 400u);
  const double required = map().robot_radius() + r.info().clearance_margin_m;
  for (size_t i = 0; i < r.num_milestones(); ++i) {
    ASSERT_TRUE(map().IsValid(r.milestone(i), required)) << r.milestone(i).transpose();
  }
  // Every edge, checked exactly every 5 mm: never closer than the tolerance allows (half the
  // validity resolution), i.e. no corner of the wall or of the single voxel is cut.
  double worst = 1e9;
  for (const RoadmapEdge& e : r.edges()) {
    const Eigen::Vector3d a = r.milestone(e.a), b = r.milestone(e.b);
    const int n = static_cast<int>(std::ceil((b - a).norm() / 0.005));
    for (int k = 0; k <= n; ++k) {
      worst = std::min(worst, map().ClearanceUpTo(a + (b - a) * k / n, required));
    }
    EXPECT_NEAR(e.length_m, (b - a).norm(), 1e-5);
    EXPECT_NEAR(e.climb_m, std::abs(b.z() - a.z()), 1e-5);
    EXPECT_GE(e.proximity, 0.0f);
  }
  EXPECT_GE(worst, required - 0.5 * r.info().validity_resolution_m - 1e-9);
}

TEST_F(RoadmapTest, SameSeedSameRoadmap) {
  auto a = Roadmap::Build(map(), SmallOptions(5));
  auto b = Roadmap::Build(map(), SmallOptions(5));
  auto c = Roadmap::Build(map(), SmallOptions(6));
  ASSERT_TRUE(a.ok() && b.ok() && c.ok());
  ASSERT_EQ((*a)->num_milestones(), (*b)->num_milestones());
  ASSERT_EQ((*a)->edges().size(), (*b)->edges().size());
  for (size_t i = 0; i < (*a)->num_milestones(); ++i) {
    ASSERT_EQ((*a)->milestone(i), (*b)->milestone(i)) << i;
  }
  for (size_t i = 0; i < (*a)->edges().size(); ++i) {
    ASSERT_EQ((*a)->edges()[i].a, (*b)->edges()[i].a);
    ASSERT_EQ((*a)->edges()[i].b, (*b)->edges()[i].b);
  }
  EXPECT_NE((*a)->milestone(0), (*c)->milestone(0));
}

TEST_F(RoadmapTest, NearestMatchesBruteForce) {
  auto roadmap = Roadmap::Build(map(), SmallOptions(2));
  ASSERT_TRUE(roadmap.ok());
  const Roadmap& r = **roadmap;
  for (const Eigen::Vector3d& p : {Eigen::Vector3d(1, 1, 1), Eigen::Vector3d(7, 9, 4),
                                   Eigen::Vector3d(5, 8.5, 2.5), Eigen::Vector3d(-3, 4, 2)}) {
    std::vector<std::pair<double, uint32_t>> all;
    for (uint32_t i = 0; i < r.num_milestones(); ++i) {
      all.emplace_back((r.milestone(i) - p).squaredNorm(), i);
    }
    std::sort(all.begin(), all.end());
    const std::vector<uint32_t> near = r.Nearest(p, 12);
    ASSERT_EQ(near.size(), 12u);
    for (size_t k = 0; k < near.size(); ++k) EXPECT_EQ(near[k], all[k].second) << k;
  }
}

TEST_F(RoadmapTest, SaveLoadRoundTrip) {
  auto built = Roadmap::Build(map(), SmallOptions(3));
  ASSERT_TRUE(built.ok());
  const std::string path = mav::testing::BinaryDir() + "/roadmap_test.mavprm";
  ASSERT_TRUE((*built)->Save(path).ok());
  auto loaded = Roadmap::Load(path, map());
  ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
  const Roadmap &a = **built, &b = **loaded;
  EXPECT_EQ(b.info().milestones, a.info().milestones);
  EXPECT_EQ(b.info().edges, a.info().edges);
  EXPECT_EQ(b.info().seed, 3u);
  EXPECT_EQ(b.info().largest_component, a.info().largest_component);
  EXPECT_DOUBLE_EQ(b.info().clearance_margin_m, a.info().clearance_margin_m);
  EXPECT_GT(b.info().load_ms, 0.0);
  for (size_t i = 0; i < a.num_milestones(); ++i) ASSERT_EQ(a.milestone(i), b.milestone(i));
  for (size_t i = 0; i < a.edges().size(); ++i) {
    ASSERT_EQ(a.edges()[i].a, b.edges()[i].a);
    ASSERT_EQ(a.edges()[i].proximity, b.edges()[i].proximity);
  }
  EXPECT_EQ(a.Serialize(), b.Serialize());
  // What a caller checks before overwriting a file.
  EXPECT_TRUE(Roadmap::IsRoadmapFile(path));
  const std::string text = mav::testing::BinaryDir() + "/roadmap_test_not_a_roadmap.txt";
  ASSERT_TRUE(WriteStringToFileAtomic(text, "MAVPRM but not the magic bytes").ok());
  EXPECT_FALSE(Roadmap::IsRoadmapFile(text));
  ASSERT_TRUE(WriteStringToFileAtomic(text, "MAV").ok());  // shorter than the magic
  EXPECT_FALSE(Roadmap::IsRoadmapFile(text));
  EXPECT_FALSE(Roadmap::IsRoadmapFile("/nonexistent/r.mavprm"));
}

TEST_F(RoadmapTest, CorruptFilesAreDataLossNamingTheFile) {
  auto built = Roadmap::Build(map(), SmallOptions(4));
  ASSERT_TRUE(built.ok());
  const std::string good = (*built)->Serialize();
  const auto expect_loss = [&](const std::string& bytes, const std::string& what) {
    const std::string path = mav::testing::BinaryDir() + "/roadmap_test_corrupt.mavprm";
    ASSERT_TRUE(WriteStringToFileAtomic(path, bytes).ok());
    auto r = Roadmap::Load(path, map());
    EXPECT_EQ(r.status().code(), StatusCode::kDataLoss) << what;
    EXPECT_NE(r.status().message().find(path), std::string::npos) << r.status().ToString();
    EXPECT_NE(r.status().message().find(what), std::string::npos) << r.status().ToString();
  };
  std::string flipped = good;
  flipped[good.size() / 2] ^= 0x40;
  expect_loss(flipped, "checksum");
  expect_loss(good.substr(0, good.size() - 100), "truncated");
  expect_loss(good.substr(0, 20), "shorter than the header");
  std::string magic = good;
  magic[0] = 'X';
  expect_loss(magic, "bad magic");
  std::string version = good;
  version[8] = 9;
  expect_loss(version, "unknown version");
  expect_loss("", "shorter than the header");

  EXPECT_EQ(Roadmap::Load("/nonexistent/r.mavprm", map()).status().code(), StatusCode::kNotFound);
}

TEST_F(RoadmapTest, ARoadmapOfAnotherMapIsRefused) {
  auto built = Roadmap::Build(map(), SmallOptions(4));
  ASSERT_TRUE(built.ok());
  MapOptions other_radius;
  other_radius.robot_radius_m = 0.4;
  const auto other = LoadMap(RoomBytes(), other_radius);
  ASSERT_NE(other, nullptr);
  auto r = Roadmap::Deserialize((*built)->Serialize(), "roadmap.mavprm", *other);
  EXPECT_EQ(r.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(r.status().message().find("roadmap.mavprm"), std::string::npos);
  EXPECT_NE(r.status().message().find("robot radius"), std::string::npos);
  EXPECT_FALSE((*built)->CheckBelongsTo(*other).ok());
  MapOptions other_policy;
  other_policy.unknown_space = UnknownSpace::kFree;
  const auto open = LoadMap(RoomBytes(), other_policy);
  ASSERT_NE(open, nullptr);
  r = Roadmap::Deserialize((*built)->Serialize(), "roadmap.mavprm", *open);
  EXPECT_EQ(r.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(r.status().message().find("another map"), std::string::npos);
  EXPECT_TRUE((*built)->CheckBelongsTo(map()).ok());
}

TEST_F(RoadmapTest, BadOptionsAndTermination) {
  RoadmapOptions options;
  options.time_budget_s = 0;
  auto r = Roadmap::Build(map(), options);
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("time_budget_s"), std::string::npos);
  options = RoadmapOptions{};
  options.validity_resolution_m = 0.5;
  r = Roadmap::Build(map(), options);
  EXPECT_NE(r.status().message().find("coarser than the map resolution"), std::string::npos);

  options = SmallOptions(1);
  options.max_milestones = 0;  // only the budget or the termination stops it
  CancelFlag cancel;
  cancel.Cancel();
  r = Roadmap::Build(map(), options, Termination().WithCancel(cancel));
  EXPECT_EQ(r.status().code(), StatusCode::kCancelled);
  r = Roadmap::Build(map(), options, Termination::AfterMs(50));
  EXPECT_EQ(r.status().code(), StatusCode::kDeadlineExceeded);
  // The time budget is not an error: what was built by then is kept.
  options.time_budget_s = 0.05;
  r = Roadmap::Build(map(), options);
  ASSERT_TRUE(r.ok());
  EXPECT_GT((*r)->num_milestones(), 10u);
}

}  // namespace
}  // namespace mav::planning
