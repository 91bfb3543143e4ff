#include "mav/mapping/collision_analysis.h"

#include <algorithm>
#include <cstdlib>

namespace mav::mapping {
namespace {

// One row: the truth dilated (steps > 0) or eroded (steps < 0) by |steps| voxels along `axes`
// ("xyz", "xy", "z").
SensitivityRow MorphologyRow(const char* name, const char* what, int steps, bool full,
                             const std::string& axes) {
  SensitivityRow r;
  r.name = name;
  r.what = what;
  r.change = steps > 0 ? SensitivityRow::Change::kDilate : SensitivityRow::Change::kErode;
  r.morphology.steps = std::abs(steps);
  r.morphology.full_neighbourhood = full;
  r.morphology.along_x = axes.find('x') != std::string::npos;
  r.morphology.along_y = axes.find('y') != std::string::npos;
  r.morphology.along_z = axes.find('z') != std::string::npos;
  return r;
}

// A wrong voxel with its distance class (1..kFar + 1), height quarter (0..3) and kind.
struct WrongVoxel {
  int64_t v;
  int distance;
  int quarter;
  bool false_block;  // blocked in the map, free in the truth (else: a miss)
};

constexpr int kFar = 3;  // steps; farther wrong voxels form one class

bool Blocked(VoxelState v) { return v != VoxelState::kFree; }

Result<std::vector<WrongVoxel>> WrongVoxels(const OccupancyGrid& truth, const OccupancyGrid& map,
                                            const CollisionEvalOptions& eval) {
  MorphologyOptions steps_options;
  steps_options.steps = kFar;
  steps_options.full_neighbourhood = true;
  MAV_ASSIGN_OR_RETURN(const std::vector<uint8_t> steps, StepsToOccupied(truth, steps_options));
  const int z_lo = eval.region_min.z(), height = std::max(1, eval.region_max.z() - z_lo);
  const int64_t nxy = static_cast<int64_t>(truth.size().x()) * truth.size().y();
  std::vector<WrongVoxel> wrong;
  for (int64_t v = 0; v < map.num_voxels(); ++v) {
    if (Blocked(map[v]) == Blocked(truth[v])) continue;
    const int k = static_cast<int>(v / nxy);
    wrong.push_back({v, steps[static_cast<size_t>(v)], std::clamp(4 * (k - z_lo) / height, 0, 3),
                     Blocked(map[v])});
  }
  return wrong;
}

// The classes: a name, a description, and a test of one wrong voxel.
enum class By { kDistance, kQuarter, kAllBlocked, kAllMissed };
struct ErrorClass {
  std::string name, what;
  By by;
  int value;

  bool Contains(const WrongVoxel& w) const {
    switch (by) {
      case By::kDistance:
        return w.false_block && w.distance == value;
      case By::kQuarter:
        return w.false_block && w.quarter == value;
      case By::kAllBlocked:
        return w.false_block;
      case By::kAllMissed:
        return !w.false_block;
    }
    return false;
  }
};

std::vector<ErrorClass> ErrorClasses() {
  std::vector<ErrorClass> classes;
  for (int d = 1; d <= kFar + 1; ++d) {
    classes.push_back(
        {d <= kFar ? "blocked_at_" + std::to_string(d) : "blocked_beyond_" + std::to_string(kFar),
         d <= kFar
             ? "map blocked, truth free: " + std::to_string(d) + (d == 1 ? " step" : " steps") +
                   " from the surface"
             : "map blocked, truth free: > " + std::to_string(kFar) + " steps from the surface",
         By::kDistance, d});
  }
  const char* quarter_names[4] = {"bottom", "second", "third", "top"};
  for (int q = 0; q < 4; ++q) {
    classes.push_back(
        {std::string("blocked_") + quarter_names[q] + "_quarter",
         std::string("map blocked, truth free: ") + quarter_names[q] + " quarter of the height",
         By::kQuarter, q});
  }
  classes.push_back({"blocked_all", "map blocked, truth free: all", By::kAllBlocked, 0});
  classes.push_back({"free_all", "map free, truth blocked (the misses): all", By::kAllMissed, 0});
  return classes;
}

}  // namespace

bool KnownRegion(const OccupancyGrid& truth, Eigen::Vector3i* region_min,
                 Eigen::Vector3i* region_max) {
  *region_min = truth.size();
  *region_max = Eigen::Vector3i::Zero();
  const Eigen::Vector3i& n = truth.size();
  for (int k = 0; k < n.z(); ++k) {
    for (int j = 0; j < n.y(); ++j) {
      for (int i = 0; i < n.x(); ++i) {
        if (truth[truth.Linear(i, j, k)] == VoxelState::kUnknown) continue;
        *region_min = region_min->cwiseMin(Eigen::Vector3i(i, j, k));
        *region_max = region_max->cwiseMax(Eigen::Vector3i(i + 1, j + 1, k + 1));
      }
    }
  }
  return (region_max->array() > region_min->array()).all();
}

std::vector<SensitivityRow> ProtocolSensitivityRows() {
  std::vector<SensitivityRow> rows = {
      MorphologyRow("dilated_1", "1 voxel thicker (6 face neighbours)", 1, false, "xyz"),
      MorphologyRow("dilated_1_full", "1 voxel thicker (26 neighbours)", 1, true, "xyz"),
      MorphologyRow("dilated_1_xy", "1 voxel thicker in x and y only", 1, false, "xy"),
      MorphologyRow("dilated_1_z", "1 voxel thicker in z only", 1, false, "z"),
      MorphologyRow("dilated_2", "2 voxels thicker (6 face neighbours)", 2, false, "xyz"),
      MorphologyRow("eroded_1", "1 voxel thinner (6 face neighbours)", -1, false, "xyz")};
  SensitivityRow& hidden = rows.emplace_back();
  hidden.name = "unobservable_unknown";
  hidden.what = "free space no keyframe could see unknown";
  hidden.change = SensitivityRow::Change::kHideUnobservable;
  return rows;
}

Result<OccupancyGrid> ChangedTruth(const OccupancyGrid& truth, const SensitivityRow& row,
                                   const std::vector<uint8_t>& observable) {
  switch (row.change) {
    case SensitivityRow::Change::kDilate:
      return DilateOccupied(truth, row.morphology);
    case SensitivityRow::Change::kErode:
      return ErodeOccupied(truth, row.morphology);
    case SensitivityRow::Change::kHideUnobservable:
      break;
  }
  if (static_cast<int64_t>(observable.size()) != truth.num_voxels()) {
    return Status::InvalidArgument("observable: " + std::to_string(observable.size()) +
                                   " voxels, the truth has " + std::to_string(truth.num_voxels()));
  }
  OccupancyGrid hidden = truth;
  for (int64_t v = 0; v < hidden.num_voxels(); ++v) {
    if (hidden[v] == VoxelState::kFree && !observable[static_cast<size_t>(v)]) {
      hidden[v] = VoxelState::kUnknown;
    }
  }
  return hidden;
}

Result<std::vector<SensitivityRow>> ProtocolSensitivity(const OccupancyGrid& truth,
                                                        const std::vector<uint8_t>& observable,
                                                        const CollisionEvalOptions& eval) {
  std::vector<SensitivityRow> rows = ProtocolSensitivityRows();
  for (SensitivityRow& r : rows) {
    MAV_ASSIGN_OR_RETURN(const OccupancyGrid changed, ChangedTruth(truth, r, observable));
    MAV_ASSIGN_OR_RETURN(r.outcomes, EvaluateCollisions(truth, changed, eval));
  }
  return rows;
}

Result<std::vector<AttributionRow>> AttributeErrors(const OccupancyGrid& truth,
                                                    const OccupancyGrid& map,
                                                    const CollisionEvalOptions& eval) {
  if (map.size() != truth.size()) {
    return Status::InvalidArgument("map: not on the truth's grid");
  }
  MAV_ASSIGN_OR_RETURN(const std::vector<WrongVoxel> wrong, WrongVoxels(truth, map, eval));
  std::vector<AttributionRow> rows;
  for (const ErrorClass& c : ErrorClasses()) {
    OccupancyGrid fixed = map;
    AttributionRow row{c.name, c.what, 0, {}};
    for (const WrongVoxel& w : wrong) {
      if (!c.Contains(w)) continue;
      fixed[w.v] = truth[w.v];
      ++row.voxels;
    }
    MAV_ASSIGN_OR_RETURN(row.outcomes, EvaluateCollisions(truth, fixed, eval));
    rows.push_back(std::move(row));
  }
  return rows;
}

}  // namespace mav::mapping
