#include "mav/mapping/grid_morphology.h"

#include <vector>

#include <Eigen/Core>

namespace mav::mapping {
namespace {

// The neighbour offsets one step may use.
std::vector<Eigen::Vector3i> Offsets(const MorphologyOptions& options) {
  std::vector<Eigen::Vector3i> offsets;
  const bool allowed[3] = {options.along_x, options.along_y, options.along_z};
  for (int dz = -1; dz <= 1; ++dz) {
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        const Eigen::Vector3i d(dx, dy, dz);
        const auto moved = (d.array() != 0).count();
        if (moved == 0 || (!options.full_neighbourhood && moved > 1)) continue;
        bool ok = true;
        for (int a = 0; a < 3; ++a) ok = ok && (d[a] == 0 || allowed[a]);
        if (ok) offsets.push_back(d);
      }
    }
  }
  return offsets;
}

// One step: every voxel in state `from` with a neighbour in state `trigger` becomes `to`; the
// neighbours are read from the grid as it was before the step.
OccupancyGrid Step(const OccupancyGrid& in, const std::vector<Eigen::Vector3i>& offsets,
                   VoxelState from, VoxelState trigger, VoxelState to) {
  OccupancyGrid out = in;
  const Eigen::Vector3i& n = in.size();
  for (int k = 0; k < n.z(); ++k) {
    for (int j = 0; j < n.y(); ++j) {
      for (int i = 0; i < n.x(); ++i) {
        const int64_t v = in.Linear(i, j, k);
        if (in[v] != from) continue;
        for (const Eigen::Vector3i& d : offsets) {
          const Eigen::Vector3i q(i + d.x(), j + d.y(), k + d.z());
          if (!in.InBounds(q)) continue;
          if (in[in.Linear(q.x(), q.y(), q.z())] == trigger) {
            out[v] = to;
            break;
          }
        }
      }
    }
  }
  return out;
}

Result<OccupancyGrid> Apply(const OccupancyGrid& grid, const MorphologyOptions& options,
                            VoxelState from, VoxelState trigger, VoxelState to) {
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument("MorphologyOptions: " + why);
  const std::vector<Eigen::Vector3i> offsets = Offsets(options);
  OccupancyGrid out = grid;
  for (int s = 0; s < options.steps; ++s) out = Step(out, offsets, from, trigger, to);
  return out;
}

}  // namespace

bool MorphologyOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (steps < 0 || steps > kMaxSteps) {
    return fail("steps must be in [0, " + std::to_string(kMaxSteps) + "]");
  }
  if (!along_x && !along_y && !along_z) return fail("along_x, along_y, along_z: none is set");
  return true;
}

Result<OccupancyGrid> DilateOccupied(const OccupancyGrid& grid, const MorphologyOptions& options) {
  return Apply(grid, options, VoxelState::kFree, VoxelState::kOccupied, VoxelState::kOccupied);
}

Result<OccupancyGrid> ErodeOccupied(const OccupancyGrid& grid, const MorphologyOptions& options) {
  return Apply(grid, options, VoxelState::kOccupied, VoxelState::kFree, VoxelState::kFree);
}

Result<std::vector<uint8_t>> StepsToOccupied(const OccupancyGrid& grid,
                                             const MorphologyOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument("MorphologyOptions: " + why);
  const std::vector<Eigen::Vector3i> offsets = Offsets(options);
  const uint8_t far = static_cast<uint8_t>(options.steps + 1);
  std::vector<uint8_t> steps(static_cast<size_t>(grid.num_voxels()), far);
  std::vector<int64_t> front, next;
  for (int64_t v = 0; v < grid.num_voxels(); ++v) {
    if (grid[v] == VoxelState::kOccupied) {
      steps[static_cast<size_t>(v)] = 0;
      front.push_back(v);
    }
  }
  const Eigen::Vector3i& n = grid.size();
  for (int s = 1; s <= options.steps && !front.empty(); ++s) {
    next.clear();
    for (const int64_t v : front) {
      const int i = static_cast<int>(v % n.x());
      const int j = static_cast<int>((v / n.x()) % n.y());
      const int k = static_cast<int>(v / (static_cast<int64_t>(n.x()) * n.y()));
      for (const Eigen::Vector3i& d : offsets) {
        const Eigen::Vector3i q(i + d.x(), j + d.y(), k + d.z());
        if (!grid.InBounds(q)) continue;
        const int64_t w = grid.Linear(q.x(), q.y(), q.z());
        if (steps[static_cast<size_t>(w)] != far) continue;
        steps[static_cast<size_t>(w)] = static_cast<uint8_t>(s);
        next.push_back(w);
      }
    }
    front.swap(next);
  }
  return steps;
}

}  // namespace mav::mapping
