#pragma once
// Collision-check evaluation of an occupancy grid against ground truth, the protocol of
// Holzmann et al., "Performance Evaluation of Vision-Based Algorithms for MAVs" (OAGM 2015),
// Section 2.2 / Tables 3-4:
//
//   A bounding box the size of the MAV is shifted through the ground-truth grid and the computed
//   grid together over the evaluation volume. At every position both grids are collision-checked;
//   the pair of answers is one of four outcomes (positive class = collision):
//     correct-collision (TP), missed-collision (FN), correct-free (TN), false-collision (FP),
//   reported in percent of all positions, and summarised by the Matthews correlation coefficient
//     MCC = (TP*TN - FP*FN) / sqrt((TP+FP)(TP+FN)(TN+FP)(TN+FN))  in [-1, 1].
//   MCC is undefined when any factor under the root is zero (e.g. the truth has no collision at
//   all); we define it as 0 then ("no better than chance"), the usual convention.
//
// Box: default 0.6 x 0.6 x 0.2 m, the AscTec Firefly hexacopter with propellers (about
// 0.61 x 0.67 x 0.17 m), rounded up to whole voxels. It is placed at every voxel offset
// `step_voxels` apart whose box lies fully inside the evaluation region. A box collides if any
// voxel it covers is occupied, or unknown when unknown counts as occupied for that grid. Each check
// is O(1) with a 3D summed-area table (integral volume) of the blocked voxels.

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mav/common/status.h"
#include "mav/mapping/types.h"

namespace mav::mapping {

struct CollisionEvalOptions {
  Eigen::Vector3d box_size = Eigen::Vector3d(0.6, 0.6, 0.2);  // [m], x y z
  int step_voxels = 1;                                        // box offset between positions
  bool truth_unknown_is_occupied = true;
  bool computed_unknown_is_occupied = true;  // the paper's choice for OctoMap
  // Evaluation region in voxel indices [min, max) of the grids; empty (max <= min) = whole grid.
  Eigen::Vector3i region_min = Eigen::Vector3i::Zero();
  Eigen::Vector3i region_max = Eigen::Vector3i::Zero();
  // Optional, not owned: one byte per truth voxel (x fastest), nonzero where some keyframe could
  // observe it (ObservableVoxels, observability.h). When set, a box position counts only if
  // every truth-free voxel it covers is observable: the evaluation "over the observable volume"
  // of docs/mapping.md, which leaves out the free space no camera ever saw.
  const std::vector<uint8_t>* observable = nullptr;

  bool IsValid(std::string* why) const;
};

struct CollisionOutcomes {
  int64_t correct_collision = 0;  // TP
  int64_t missed_collision = 0;   // FN
  int64_t correct_free = 0;       // TN
  int64_t false_collision = 0;    // FP

  int64_t total() const {
    return correct_collision + missed_collision + correct_free + false_collision;
  }
  // 100 * count / total; 0 when total == 0.
  double Percent(int64_t count) const;
  double Mcc() const;
};

// MCC from the four counts; 0 when undefined (see the header comment).
double MatthewsCorrelation(int64_t tp, int64_t fn, int64_t tn, int64_t fp);

// INVALID_ARGUMENT when the grids' geometries differ, the options are invalid, the observable
// mask's size differs from the truth's, or the box does not fit in the region (the message names
// the field).
Result<CollisionOutcomes> EvaluateCollisions(const OccupancyGrid& truth,
                                             const OccupancyGrid& computed,
                                             const CollisionEvalOptions& options = {});

// O(1) box queries on one grid (summed-area tables of occupied and of unknown voxels), for the
// evaluation and for collision queries by the mapping service.
class BoxQuery {
 public:
  explicit BoxQuery(const OccupancyGrid& grid);

  // Counts in the voxel box [min, max) (clamped to the grid; voxels outside the grid count as
  // unknown).
  int64_t Occupied(const Eigen::Vector3i& min, const Eigen::Vector3i& max) const;
  int64_t Unknown(const Eigen::Vector3i& min, const Eigen::Vector3i& max) const;

  enum class Answer { kFree, kCollision, kUnknown };
  // World-frame axis-aligned box [min_world, max_world]: kCollision if it touches an occupied
  // voxel, else kUnknown if it touches an unknown voxel (or leaves the grid), else kFree.
  Answer Query(const Eigen::Vector3d& min_world, const Eigen::Vector3d& max_world) const;

 private:
  int64_t Sum(const std::vector<int32_t>& table, const Eigen::Vector3i& min,
              const Eigen::Vector3i& max) const;
  GridGeometry geometry_;
  std::vector<int32_t> occupied_;  // (nx+1)(ny+1)(nz+1) prefix sums
  std::vector<int32_t> unknown_;
};

}  // namespace mav::mapping
