#include "mav/mapping/pipeline.h"

#include <cstdio>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "mav/camera/rectifier.h"
#include "mav/mapping/collision_eval.h"
#include "mav/sim/occupancy.h"
#include "mav/sim/scenario.h"
#include "tests/common/stereo_rig.h"

namespace mav::mapping {
namespace {

using ::mav::test_support::CenteredEurocLikeRig;  // tests/common/stereo_rig.h

TEST(MappingPipelineOptionsTest, NamesNestedFields) {
  std::string why;
  EXPECT_TRUE(MappingPipelineOptions().IsValid(&why)) << why;
  MappingPipelineOptions o;
  o.sparse.max_depth_m = -1;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_EQ(why.rfind("sparse.max_depth_m", 0), 0u) << why;
  o = MappingPipelineOptions();
  o.octomap.num_disparities = 50;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_EQ(why.rfind("octomap.num_disparities", 0), 0u) << why;
  o = MappingPipelineOptions();
  o.keyframes.min_translation_m = 0;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_EQ(why.rfind("keyframes.", 0), 0u) << why;
  o = MappingPipelineOptions();
  o.run_octomap = o.run_sparse_mesh = false;
  EXPECT_FALSE(o.IsValid(&why));
  auto p = MappingPipeline::Create(CenteredEurocLikeRig(), o);
  ASSERT_FALSE(p.ok());
  EXPECT_EQ(p.status().message().rfind("options.run_sparse_mesh", 0), 0u);
}

// The default options are the safety preference; a preference sets the mesher's weights, the grid
// rule and the point choice together, for the pipeline and for one build.
TEST(MappingPipelineOptionsTest, MapPreferenceSetsMeshingGridAndPoints) {
  const MappingPipelineOptions defaults;
  MappingPipelineOptions mcc;
  ApplyMapPreference(MapPreference::kMcc, &mcc);
  EXPECT_GT(defaults.meshing.weak_surface_weight, 0.0);
  EXPECT_TRUE(defaults.mesh_to_grid.occupy_surface_voxels);
  EXPECT_FALSE(defaults.sparse.keep_unchecked_points);
  EXPECT_EQ(mcc.meshing.weak_surface_weight, 0.0);
  EXPECT_FALSE(mcc.mesh_to_grid.occupy_surface_voxels);
  EXPECT_TRUE(mcc.sparse.keep_unchecked_points);
  // The grid rules the preference does not touch stay the pipeline's.
  EXPECT_TRUE(mcc.mesh_to_grid.free_requires_traversal);
  EXPECT_EQ(mcc.mesh_to_grid.carve_radius_voxels, defaults.mesh_to_grid.carve_radius_voxels);
  MappingPipelineOptions safety = mcc;
  ApplyMapPreference(MapPreference::kSafety, &safety);
  EXPECT_EQ(safety.meshing.weak_surface_weight, defaults.meshing.weak_surface_weight);
  EXPECT_EQ(safety.mesh_to_grid.occupy_surface_voxels, defaults.mesh_to_grid.occupy_surface_voxels);
  EXPECT_EQ(safety.sparse.keep_unchecked_points, defaults.sparse.keep_unchecked_points);
  EXPECT_TRUE(defaults.occlusion_check.enabled);
  EXPECT_FALSE(mcc.occlusion_check.enabled);
  EXPECT_TRUE(safety.occlusion_check.enabled);

  const BuildOptions build = BuildOptions::For(MapPreference::kMcc);
  ASSERT_TRUE(build.meshing && build.mesh_to_grid && build.keep_unchecked_points &&
              build.occlusion_check);
  EXPECT_EQ(build.meshing->weak_surface_weight, 0.0);
  EXPECT_FALSE(build.mesh_to_grid->occupy_surface_voxels);
  EXPECT_TRUE(*build.keep_unchecked_points);
  EXPECT_FALSE(build.occlusion_check->enabled);
  ASSERT_TRUE(BuildOptions::For(MapPreference::kSafety).occlusion_check);
  EXPECT_TRUE(BuildOptions::For(MapPreference::kSafety).occlusion_check->enabled);
  std::string why;
  EXPECT_TRUE(build.IsValid(&why)) << why;
  BuildOptions bad = build;
  bad.mesh_to_grid->carve_radius_voxels = -1;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_EQ(why.rfind("mesh_to_grid.carve_radius_voxels", 0), 0u) << why;
  bad = build;
  bad.occlusion_check->min_range_m = 0.0;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_EQ(why.rfind("occlusion_check.min_range_m", 0), 0u) << why;
  MappingPipelineOptions bad_pipeline;
  bad_pipeline.occlusion_check.margin_m = -0.1;
  EXPECT_FALSE(bad_pipeline.IsValid(&why));
  EXPECT_EQ(why.rfind("occlusion_check.margin_m", 0), 0u) << why;
}

TEST(MappingPipelineTest, BadInputIsRejectedAndNothingChanges) {
  auto p = MappingPipeline::Create(CenteredEurocLikeRig());
  ASSERT_TRUE(p.ok()) << p.status().ToString();
  cv::Mat good(480, 752, CV_8UC1, cv::Scalar(100)), empty, wide(480, 800, CV_8UC1),
      colour(480, 752, CV_8UC3);
  Status s = p->InsertKeyframe(empty, good, geometry::SE3());
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(s.message().rfind("left: empty", 0), 0u) << s.message();
  s = p->InsertKeyframe(good, wide, geometry::SE3());
  EXPECT_EQ(s.message().rfind("right: size 800x480", 0), 0u) << s.message();
  s = p->InsertKeyframe(good, colour, geometry::SE3());
  EXPECT_EQ(s.message().rfind("right: expected CV_8UC1", 0), 0u) << s.message();
  const geometry::SE3 nan_pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, std::nan(""), 0));
  s = p->InsertKeyframe(good, good, nan_pose);
  EXPECT_EQ(s.message().rfind("T_world_cam", 0), 0u) << s.message();
  EXPECT_FALSE(p->ConsiderFrame(nan_pose).ok());
  EXPECT_EQ(p->num_keyframes(), 0);
  EXPECT_EQ(p->octomap_mapper()->num_keyframes(), 0);
  EXPECT_TRUE(p->sparse_points()->keyframes().empty());
  GridGeometry g;
  g.size = Eigen::Vector3i(10, 10, 10);
  auto out = p->Finish(g);
  ASSERT_FALSE(out.ok());
  EXPECT_EQ(out.status().code(), StatusCode::kFailedPrecondition);
  g.resolution = -1;
  EXPECT_EQ(p->Finish(g).status().code(), StatusCode::kInvalidArgument);
}

TEST(MappingPipelineTest, SelectsKeyframesFromThePoseStream) {
  MappingPipelineOptions options;
  options.keyframes.min_translation_m = 0.25;
  auto p = MappingPipeline::Create(CenteredEurocLikeRig(), options);
  ASSERT_TRUE(p.ok());
  int keyframes = 0;
  for (int i = 0; i < 100; ++i) {
    auto k = p->ConsiderFrame(geometry::SE3(Eigen::Matrix3d::Identity(),
                                            Eigen::Vector3d(0.01 * i, 0, 0)));  // 1 cm per frame
    ASSERT_TRUE(k.ok());
    keyframes += *k ? 1 : 0;
  }
  EXPECT_EQ(keyframes, 4);  // at 0, 0.25, 0.50, 0.75 m
  EXPECT_EQ(p->num_frames(), 100);
}

// End to end on a short rendered room data set: both mappers on the same keyframes, scored with
// the paper's collision-check protocol against the exact ground truth. The mesh mapper must beat
// the OctoMap + dense-stereo baseline with either map preference; the default (safety) map must
// miss fewer collisions than the best-MCC map, which must reach a decent MCC.
TEST(MappingPipelineTest, ShortRoomPresetMeshBeatsOctomapBaseline) {
  sim::ScenarioOptions so;
  so.preset = "room-easy";
  so.frames = 320;
  so.seed = 1;
  so.rectified = false;
  auto scenario = sim::Scenario::Create(so);
  ASSERT_TRUE(scenario.ok()) << scenario.status().ToString();
  auto rectifier = camera::StereoRectifier::Create(scenario->calibration());
  ASSERT_TRUE(rectifier.ok()) << rectifier.status().ToString();
  const geometry::SE3 T_body_cam = rectifier->T_body_rect0();

  auto pipeline = MappingPipeline::Create(rectifier->rectified());
  ASSERT_TRUE(pipeline.ok()) << pipeline.status().ToString();
  std::vector<int64_t> keyframes;
  std::vector<geometry::SE3> poses;
  for (int64_t k = 0; k < scenario->num_frames(); ++k) {
    const geometry::SE3 T_world_cam =
        scenario->StateAt(scenario->FrameTimeNs(k)).T_world_body * T_body_cam;
    auto is_keyframe = pipeline->ConsiderFrame(T_world_cam);
    ASSERT_TRUE(is_keyframe.ok());
    if (*is_keyframe) {
      keyframes.push_back(k);
      poses.push_back(T_world_cam);
    }
  }
  ASSERT_GE(keyframes.size(), 10u);
  // Render the keyframes on two threads, then insert in order.
  std::vector<cv::Mat> left(keyframes.size()), right(keyframes.size());
  auto render = [&](size_t first) {
    for (size_t i = first; i < keyframes.size(); i += 2) {
      cv::Mat raw_left, raw_right;
      scenario->RenderStereo(keyframes[i], &raw_left, &raw_right);
      ASSERT_TRUE(rectifier->Rectify(raw_left, raw_right, &left[i], &right[i]).ok());
    }
  };
  std::thread worker(render, 1);
  render(0);
  worker.join();
  for (size_t i = 0; i < keyframes.size(); ++i) {
    ASSERT_TRUE(pipeline->InsertKeyframe(left[i], right[i], poses[i]).ok());
  }

  const OccupancyGrid truth = scenario->ComputeOccupancy(0.05);
  auto out = pipeline->Finish(truth.geometry());
  ASSERT_TRUE(out.ok()) << out.status().ToString();
  EXPECT_EQ(out->keyframes, static_cast<int64_t>(keyframes.size()));
  EXPECT_EQ(out->frames, 320);
  ASSERT_TRUE(out->has_sparse_mesh && out->has_octomap);
  // ~100 points per keyframe, a good share of them seen from more than one keyframe.
  const double per_keyframe =
      static_cast<double>(out->sparse_stats.TotalSelected()) / static_cast<double>(out->keyframes);
  EXPECT_GT(per_keyframe, 90.0);
  EXPECT_LE(per_keyframe, 100.0);
  int64_t multi_view = 0;
  for (const MapPoint& p : out->points) multi_view += p.keyframes.size() > 1 ? 1 : 0;
  EXPECT_GT(multi_view, static_cast<int64_t>(out->points.size()) / 5);
  EXPECT_FALSE(out->meshing.mesh.empty());

  CollisionEvalOptions eval;  // unknown counts as occupied in both, as in the paper
  auto ours = EvaluateCollisions(truth, out->sparse_mesh_grid, eval);
  auto baseline = EvaluateCollisions(truth, out->octomap_grid, eval);
  ASSERT_TRUE(ours.ok() && baseline.ok());
  std::printf(
      "keyframes %lld, points %zu (multi-view %lld); MCC sparse-mesh %.3f (%.2f s), octomap %.3f "
      "(%.2f s); false-collision %.2f%% vs %.2f%%, missed %.2f%% vs %.2f%%\n",
      static_cast<long long>(out->keyframes), out->points.size(),
      static_cast<long long>(multi_view), ours->Mcc(), out->sparse_mesh_timing.total_s,
      baseline->Mcc(), out->octomap_timing.total_s, ours->Percent(ours->false_collision),
      baseline->Percent(baseline->false_collision), ours->Percent(ours->missed_collision),
      baseline->Percent(baseline->missed_collision));
  // Measured (seed 1, 320 frames, 26 keyframes), the default safety map: MCC 0.479 (OctoMap
  // 0.397), missed 0.39 % (0.471 / 0.50 % without the occlusion check). The clang build of the
  // sanitizer pass renders slightly different images (769 points instead of 751): MCC 0.432
  // (OctoMap 0.398), missed 0.32 % (0.441 / 0.33 % without the check). Most of the room is never
  // seen in 16 s of flight and counts as occupied for both methods, hence the modest absolute
  // values.
  EXPECT_GT(ours->Mcc(), baseline->Mcc() + 0.02);
  EXPECT_LT(ours->Percent(ours->missed_collision), 0.6);

  // The best-MCC map of the same keyframes (MapPreference::kMcc): measured MCC 0.543, missed
  // 1.00 %.
  auto mcc_map = pipeline->Build(MappingMethod::kSparseMesh, truth.geometry(),
                                 BuildOptions::For(MapPreference::kMcc));
  ASSERT_TRUE(mcc_map.ok()) << mcc_map.status().ToString();
  auto best = EvaluateCollisions(truth, mcc_map->grid, eval);
  ASSERT_TRUE(best.ok());
  std::printf("--prefer mcc: MCC %.3f, false-collision %.2f%%, missed %.2f%%\n", best->Mcc(),
              best->Percent(best->false_collision), best->Percent(best->missed_collision));
  EXPECT_GT(best->Mcc(), 0.48);
  EXPECT_GT(best->Mcc(), baseline->Mcc() + 0.08);
  EXPECT_GT(best->Mcc(), ours->Mcc());
  EXPECT_LT(ours->Percent(ours->missed_collision), best->Percent(best->missed_collision));
  EXPECT_GT(out->sparse_mesh_timing.total_s, 0.0);
  EXPECT_GT(out->octomap_timing.total_s, 0.0);

  // The occlusion check of the safety map: the far single-view points it left out are exactly the
  // difference to the same build without it, and the first pass took time.
  std::printf(
      "occlusion check: %lld far single-view points checked, %lld seen through a "
      "surface (%.2f s)\n",
      static_cast<long long>(out->occlusion_checked_points),
      static_cast<long long>(out->occluded_points), out->sparse_mesh_timing.occlusion_check_s);
  EXPECT_GT(out->occlusion_checked_points, 0);
  EXPECT_GT(out->occluded_points, 0);
  EXPECT_LT(out->occluded_points, out->occlusion_checked_points);
  EXPECT_GT(out->sparse_mesh_timing.occlusion_check_s, 0.0);
  BuildOptions unchecked = BuildOptions::For(MapPreference::kSafety);
  unchecked.occlusion_check->enabled = false;
  auto all_points = pipeline->Build(MappingMethod::kSparseMesh, truth.geometry(), unchecked);
  ASSERT_TRUE(all_points.ok()) << all_points.status().ToString();
  EXPECT_EQ(all_points->occlusion_checked_points, 0);
  EXPECT_EQ(all_points->points.size(), out->points.size() + out->occluded_points);
  auto without = EvaluateCollisions(truth, all_points->grid, eval);
  ASSERT_TRUE(without.ok());
  std::printf("without the occlusion check: MCC %.3f, false-collision %.2f%%, missed %.2f%%\n",
              without->Mcc(), without->Percent(without->false_collision),
              without->Percent(without->missed_collision));
  // The check is there for the misses: it must not add any.
  EXPECT_LE(ours->missed_collision, without->missed_collision);

  // The unknown voxels as the mapping service's BuildMap asks for them: counted, or made occupied
  // or free before counting.
  auto kept = pipeline->Build(MappingMethod::kOctomap, truth.geometry());
  ASSERT_TRUE(kept.ok()) << kept.status().ToString();
  EXPECT_GT(kept->unknown_voxels, 0);
  EXPECT_EQ(kept->unknown_voxels, kept->grid.Count(VoxelState::kUnknown));
  EXPECT_EQ(kept->occupied_voxels + kept->free_voxels + kept->unknown_voxels,
            kept->grid.num_voxels());
  BuildOptions unknown_options;
  unknown_options.unknown = UnknownHandling::kAsOccupied;
  auto as_occupied = pipeline->Build(MappingMethod::kOctomap, truth.geometry(), unknown_options);
  ASSERT_TRUE(as_occupied.ok()) << as_occupied.status().ToString();
  EXPECT_EQ(as_occupied->unknown_voxels, 0);
  EXPECT_EQ(as_occupied->grid.Count(VoxelState::kUnknown), 0);
  EXPECT_EQ(as_occupied->occupied_voxels, kept->occupied_voxels + kept->unknown_voxels);
  EXPECT_EQ(as_occupied->free_voxels, kept->free_voxels);
  unknown_options.unknown = UnknownHandling::kAsFree;
  auto as_free = pipeline->Build(MappingMethod::kOctomap, truth.geometry(), unknown_options);
  ASSERT_TRUE(as_free.ok()) << as_free.status().ToString();
  EXPECT_EQ(as_free->unknown_voxels, 0);
  EXPECT_EQ(as_free->free_voxels, kept->free_voxels + kept->unknown_voxels);
  EXPECT_EQ(as_free->occupied_voxels, kept->occupied_voxels);
}

}  // namespace
}  // namespace mav::mapping
