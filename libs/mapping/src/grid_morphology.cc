#include "mav/mapping/grid_morphology.h"

#include <string>
#include <vector>

namespace mav::mapping {
namespace {

// A neighbour one step may move to, as index deltas and as a linear delta in the grid.
struct Neighbour {
  int dx, dy, dz;
  int64_t linear;
};

// The neighbours of `options` in `grid`; INVALID_ARGUMENT when the options are invalid.
Result<std::vector<Neighbour>> NeighboursFor(const OccupancyGrid& grid,
                                             const MorphologyOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument("MorphologyOptions: " + why);
  const bool allowed[3] = {options.along_x, options.along_y, options.along_z};
  const int64_t nx = grid.size().x(), nxy = nx * grid.size().y();
  std::vector<Neighbour> out;
  for (int dz = -1; dz <= 1; ++dz) {
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        const int d[3] = {dx, dy, dz};
        int moved = 0;
        bool ok = true;
        for (int a = 0; a < 3; ++a) {
          moved += d[a] != 0 ? 1 : 0;
          ok = ok && (d[a] == 0 || allowed[a]);
        }
        if (moved == 0 || (!options.full_neighbourhood && moved > 1) || !ok) continue;
        out.push_back({dx, dy, dz, dz * nxy + dy * nx + dx});
      }
    }
  }
  return out;
}

bool InGrid(int i, int j, int k, int nx, int ny, int nz) {
  return i >= 0 && i < nx && j >= 0 && j < ny && k >= 0 && k < nz;
}

// One step: every voxel in state `from` with a neighbour in state `trigger` becomes `to`; the
// neighbours are read from the grid as it was before the step.
OccupancyGrid Step(const OccupancyGrid& in, const std::vector<Neighbour>& neighbours,
                   VoxelState from, VoxelState trigger, VoxelState to) {
  OccupancyGrid out = in;
  const int nx = in.size().x(), ny = in.size().y(), nz = in.size().z();
  const VoxelState* src = in.states().data();
  VoxelState* dst = out.mutable_states().data();
  int64_t v = 0;
  for (int k = 0; k < nz; ++k) {
    for (int j = 0; j < ny; ++j) {
      // Interior voxels of the row need no bounds check.
      const bool row_inside = j > 0 && j + 1 < ny && k > 0 && k + 1 < nz;
      for (int i = 0; i < nx; ++i, ++v) {
        if (src[v] != from) continue;
        const bool inside = row_inside && i > 0 && i + 1 < nx;
        for (const Neighbour& n : neighbours) {
          if (!inside && !InGrid(i + n.dx, j + n.dy, k + n.dz, nx, ny, nz)) continue;
          if (src[v + n.linear] == trigger) {
            dst[v] = to;
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
  auto neighbours = NeighboursFor(grid, options);
  if (!neighbours.ok()) return neighbours.status();
  OccupancyGrid out = grid;
  for (int s = 0; s < options.steps; ++s) out = Step(out, *neighbours, from, trigger, to);
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
  auto neighbours = NeighboursFor(grid, options);
  if (!neighbours.ok()) return neighbours.status();
  const uint8_t far = static_cast<uint8_t>(options.steps + 1);
  std::vector<uint8_t> steps(static_cast<size_t>(grid.num_voxels()), far);
  std::vector<int64_t> front, next;
  for (int64_t v = 0; v < grid.num_voxels(); ++v) {
    if (grid[v] == VoxelState::kOccupied) {
      steps[static_cast<size_t>(v)] = 0;
      front.push_back(v);
    }
  }
  const int nx = grid.size().x(), ny = grid.size().y(), nz = grid.size().z();
  const int64_t nxy = static_cast<int64_t>(nx) * ny;
  for (int s = 1; s <= options.steps && !front.empty(); ++s) {
    next.clear();
    for (const int64_t v : front) {
      const int i = static_cast<int>(v % nx);
      const int j = static_cast<int>((v / nx) % ny);
      const int k = static_cast<int>(v / nxy);
      for (const Neighbour& n : *neighbours) {
        if (!InGrid(i + n.dx, j + n.dy, k + n.dz, nx, ny, nz)) continue;
        uint8_t& w = steps[static_cast<size_t>(v + n.linear)];
        if (w != far) continue;
        w = static_cast<uint8_t>(s);
        next.push_back(v + n.linear);
      }
    }
    front.swap(next);
  }
  return steps;
}

}  // namespace mav::mapping
