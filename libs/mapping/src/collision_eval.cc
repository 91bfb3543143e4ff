#include "mav/mapping/collision_eval.h"

#include <algorithm>
#include <cmath>

namespace mav::mapping {

bool CollisionEvalOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!box_size.allFinite() || (box_size.array() <= 0.0).any()) {
    return fail("box_size must be positive and finite on every axis [m]");
  }
  if (step_voxels < 1) return fail("step_voxels must be >= 1");
  if ((region_min.array() < 0).any()) return fail("region_min must be >= 0");
  return true;
}

double CollisionOutcomes::Percent(int64_t count) const {
  const int64_t n = total();
  return n == 0 ? 0.0 : 100.0 * static_cast<double>(count) / static_cast<double>(n);
}

double CollisionOutcomes::Mcc() const {
  return MatthewsCorrelation(correct_collision, missed_collision, correct_free, false_collision);
}

double MatthewsCorrelation(int64_t tp, int64_t fn, int64_t tn, int64_t fp) {
  const double a = static_cast<double>(tp + fp);
  const double b = static_cast<double>(tp + fn);
  const double c = static_cast<double>(tn + fp);
  const double d = static_cast<double>(tn + fn);
  if (a == 0.0 || b == 0.0 || c == 0.0 || d == 0.0) return 0.0;
  const double numerator = static_cast<double>(tp) * static_cast<double>(tn) -
                           static_cast<double>(fp) * static_cast<double>(fn);
  // sqrt of each factor separately: the product overflows nothing but loses no precision either.
  return numerator / (std::sqrt(a) * std::sqrt(b) * std::sqrt(c) * std::sqrt(d));
}

// ---------------------------------------------------------------------------------------------
// BoxQuery

namespace {

// Prefix sums of the voxels for which counted(linear index) holds.
template <typename Counted>
void BuildTable(const OccupancyGrid& grid, Counted&& counted, std::vector<int32_t>* table) {
  const Eigen::Vector3i& n = grid.size();
  const int64_t sx = n.x() + 1, sy = n.y() + 1;
  table->assign(static_cast<size_t>(sx * sy * (n.z() + 1)), 0);
  auto at = [&](int i, int j, int k) -> int32_t& { return (*table)[(k * sy + j) * sx + i]; };
  for (int k = 1; k <= n.z(); ++k) {
    for (int j = 1; j <= n.y(); ++j) {
      int32_t row = 0;
      for (int i = 1; i <= n.x(); ++i) {
        row += counted(grid.Linear(i - 1, j - 1, k - 1)) ? 1 : 0;
        // S(i,j,k) = row(i,j,k) + S(i,j-1,k) + S(i,j,k-1) - S(i,j-1,k-1), with row the running
        // sum along x: the 2D recurrence in (j, k) over per-row prefix sums.
        at(i, j, k) = row + at(i, j - 1, k) + at(i, j, k - 1) - at(i, j - 1, k - 1);
      }
    }
  }
}

// Count in the voxel box [min, max) (clamped to the grid of `size`) from a BuildTable table.
int64_t TableSum(const std::vector<int32_t>& table, const Eigen::Vector3i& size,
                 const Eigen::Vector3i& min, const Eigen::Vector3i& max) {
  const Eigen::Vector3i lo = min.cwiseMax(0).cwiseMin(size);
  const Eigen::Vector3i hi = max.cwiseMax(lo).cwiseMin(size);
  const int64_t sx = size.x() + 1, sy = size.y() + 1;
  auto s = [&](int i, int j, int k) -> int64_t { return table[(k * sy + j) * sx + i]; };
  return s(hi.x(), hi.y(), hi.z()) - s(lo.x(), hi.y(), hi.z()) - s(hi.x(), lo.y(), hi.z()) -
         s(hi.x(), hi.y(), lo.z()) + s(lo.x(), lo.y(), hi.z()) + s(lo.x(), hi.y(), lo.z()) +
         s(hi.x(), lo.y(), lo.z()) - s(lo.x(), lo.y(), lo.z());
}

}  // namespace

BoxQuery::BoxQuery(const OccupancyGrid& grid) : geometry_(grid.geometry()) {
  BuildTable(
      grid, [&](int64_t i) { return grid[i] == VoxelState::kOccupied; }, &occupied_);
  BuildTable(
      grid, [&](int64_t i) { return grid[i] == VoxelState::kUnknown; }, &unknown_);
}

int64_t BoxQuery::Sum(const std::vector<int32_t>& table, const Eigen::Vector3i& min,
                      const Eigen::Vector3i& max) const {
  return TableSum(table, geometry_.size, min, max);
}

int64_t BoxQuery::Occupied(const Eigen::Vector3i& min, const Eigen::Vector3i& max) const {
  return Sum(occupied_, min, max);
}

int64_t BoxQuery::Unknown(const Eigen::Vector3i& min, const Eigen::Vector3i& max) const {
  const Eigen::Vector3i lo = min.cwiseMax(0).cwiseMin(geometry_.size);
  const Eigen::Vector3i hi = max.cwiseMax(lo).cwiseMin(geometry_.size);
  const Eigen::Vector3i ext = (max - min).cwiseMax(0);
  const int64_t requested = static_cast<int64_t>(ext.x()) * ext.y() * ext.z();
  const Eigen::Vector3i in = hi - lo;
  const int64_t inside = static_cast<int64_t>(in.x()) * in.y() * in.z();
  return Sum(unknown_, min, max) + (requested - inside);
}

BoxQuery::Answer BoxQuery::Query(const Eigen::Vector3d& min_world,
                                 const Eigen::Vector3d& max_world) const {
  Eigen::Vector3i lo, hi;
  for (int a = 0; a < 3; ++a) {
    lo[a] =
        static_cast<int>(std::floor((min_world[a] - geometry_.origin[a]) / geometry_.resolution));
    hi[a] =
        static_cast<int>(std::floor((max_world[a] - geometry_.origin[a]) / geometry_.resolution)) +
        1;
  }
  if (Occupied(lo, hi) > 0) return Answer::kCollision;
  if (Unknown(lo, hi) > 0) return Answer::kUnknown;
  return Answer::kFree;
}

// ---------------------------------------------------------------------------------------------
// EvaluateCollisions

Result<CollisionOutcomes> EvaluateCollisions(const OccupancyGrid& truth,
                                             const OccupancyGrid& computed,
                                             const CollisionEvalOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument("CollisionEvalOptions: " + why);
  if (truth.num_voxels() == 0) return Status::InvalidArgument("truth: empty grid");
  if (!truth.geometry().SameAs(computed.geometry())) {
    return Status::InvalidArgument(
        "computed: grid geometry (origin, resolution, size) differs from the truth grid's");
  }
  const Eigen::Vector3i& n = truth.size();
  Eigen::Vector3i lo = options.region_min, hi = options.region_max;
  if ((hi.array() <= lo.array()).any()) {
    lo.setZero();
    hi = n;
  }
  hi = hi.cwiseMin(n);
  Eigen::Vector3i box;
  for (int a = 0; a < 3; ++a) {
    box[a] =
        std::max(1, static_cast<int>(std::ceil(options.box_size[a] / truth.resolution() - 1e-9)));
  }
  if (((hi - lo).array() < box.array()).any()) {
    return Status::InvalidArgument("CollisionEvalOptions.box_size: the box (" +
                                   std::to_string(box.x()) + "x" + std::to_string(box.y()) + "x" +
                                   std::to_string(box.z()) +
                                   " voxels) does not fit in the evaluation region");
  }
  if (options.observable != nullptr &&
      static_cast<int64_t>(options.observable->size()) != truth.num_voxels()) {
    return Status::InvalidArgument(
        "CollisionEvalOptions.observable: " + std::to_string(options.observable->size()) +
        " bytes for a truth grid of " + std::to_string(truth.num_voxels()) + " voxels");
  }
  // One table per grid of the voxels that block a box (occupied, or unknown when unknown counts
  // as occupied): every position lies inside the grid, so a box collides iff its count is > 0.
  auto blocked_table = [](const OccupancyGrid& grid, bool unknown_blocks) {
    std::vector<int32_t> table;
    BuildTable(
        grid,
        [&](int64_t i) {
          return grid[i] == VoxelState::kOccupied ||
                 (unknown_blocks && grid[i] == VoxelState::kUnknown);
        },
        &table);
    return table;
  };
  const std::vector<int32_t> truth_blocked =
      blocked_table(truth, options.truth_unknown_is_occupied);
  const std::vector<int32_t> computed_blocked =
      blocked_table(computed, options.computed_unknown_is_occupied);
  // Truth-free voxels no camera could observe; a position covering one is not counted.
  std::vector<int32_t> unobserved;
  if (options.observable != nullptr) {
    const std::vector<uint8_t>& seen = *options.observable;
    BuildTable(
        truth,
        [&](int64_t i) {
          return truth[i] == VoxelState::kFree && seen[static_cast<size_t>(i)] == 0;
        },
        &unobserved);
  }
  // The box's count from a table entry p = its min corner: the eight corners as linear offsets
  // of the (n + 1)^3 table, so the loop below runs on plain integers.
  const int64_t sx = n.x() + 1, sxy = sx * (n.y() + 1);
  const int64_t dx = box.x(), dy = box.y() * sx, dz = box.z() * sxy;
  auto count = [&](const std::vector<int32_t>& t, int64_t p) {
    const int32_t* c = t.data() + p;
    return static_cast<int64_t>(c[dx + dy + dz]) - c[dy + dz] - c[dx + dz] - c[dx + dy] + c[dz] +
           c[dy] + c[dx] - c[0];
  };
  CollisionOutcomes out;
  const int step = options.step_voxels;
  for (int k = lo.z(); k + box.z() <= hi.z(); k += step) {
    for (int j = lo.y(); j + box.y() <= hi.y(); j += step) {
      for (int i = lo.x(); i + box.x() <= hi.x(); i += step) {
        const int64_t p = k * sxy + j * sx + i;
        if (!unobserved.empty() && count(unobserved, p) > 0) continue;
        const bool truth_hit = count(truth_blocked, p) > 0;
        const bool computed_hit = count(computed_blocked, p) > 0;
        if (truth_hit) {
          ++(computed_hit ? out.correct_collision : out.missed_collision);
        } else {
          ++(computed_hit ? out.false_collision : out.correct_free);
        }
      }
    }
  }
  return out;
}

}  // namespace mav::mapping
