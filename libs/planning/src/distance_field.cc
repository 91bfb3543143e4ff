#include "distance_field.h"

#include <dynamicEDT3D/dynamicEDT3D.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <functional>

#include "mav/common/parallel.h"

namespace mav::planning::internal {
namespace {

constexpr float kInf = 1e30f;

// Work buffers of one thread for rows of up to n cells (2n + 1 lattice positions).
struct RowScratch {
  std::vector<float> in, out;
  std::vector<int> v;     // lattice positions of the parabolas of the lower envelope
  std::vector<double> f;  // their values
  std::vector<double> z;  // where each parabola starts to be the lowest
  explicit RowScratch(int n) : in(n), out(n), v(2 * n + 2), f(2 * n + 2), z(2 * n + 3) {}
};

// out[i] = min over lattice positions X in [0, 2n] of (2i + 1 - X)^2 + V(X), where V(X) is the
// smallest input of the cells whose cube has X on its boundary or centre: X = 2i + 1 is the centre
// of cell i, X = 2i the face between cells i - 1 and i. Units: half cells. The lower envelope of
// parabolas (Felzenszwalb & Huttenlocher 2012, Sec. 3) in O(n).
void HalfLatticeTransform(int n, RowScratch* s) {
  const float* g = s->in.data();
  int k = -1;
  for (int x = 0; x <= 2 * n; ++x) {
    float value;
    if (x & 1) {
      value = g[x >> 1];
    } else {
      const int i = x >> 1;
      value = std::min(i > 0 ? g[i - 1] : kInf, i < n ? g[i] : kInf);
    }
    if (value >= kInf) continue;
    const double fx = value;
    if (k < 0) {
      k = 0;
      s->v[0] = x;
      s->f[0] = fx;
      s->z[0] = -1e300;
      s->z[1] = 1e300;
      continue;
    }
    // z[0] = -inf, so the loop ends at k = 0 at the latest.
    double cross;
    while (true) {
      const int vk = s->v[k];
      cross = ((fx + double(x) * x) - (s->f[k] + double(vk) * vk)) / (2.0 * (x - vk));
      if (cross > s->z[k]) break;
      --k;
    }
    ++k;
    s->v[k] = x;
    s->f[k] = fx;
    s->z[k] = cross;
    s->z[k + 1] = 1e300;
  }
  if (k < 0) {
    std::fill(s->out.begin(), s->out.begin() + n, kInf);
    return;
  }
  int j = 0;
  for (int i = 0; i < n; ++i) {
    const double q = 2 * i + 1;
    while (s->z[j + 1] < q) ++j;
    const double d = q - s->v[j];
    s->out[i] = static_cast<float>(d * d + s->f[j]);
  }
}

// Runs `row(index, scratch)` for index in [0, count) on `threads` threads; stops early when
// `stop` fires (polled every 256 rows).
Status ForRows(int64_t count, int n_max, int threads, const Termination& stop,
               const std::function<void(int64_t, RowScratch*)>& row) {
  std::atomic<bool> stopped{false};
  ParallelFor(threads, count, [&](int, int64_t begin, int64_t end) {
    RowScratch scratch(n_max);
    for (int64_t r = begin; r < end; ++r) {
      if ((r & 255) == 0 && (stopped.load(std::memory_order_relaxed) || stop.ShouldStop())) {
        stopped = true;
        return;
      }
      row(r, &scratch);
    }
  });
  if (stopped) return stop.Check("distance map");
  return Status::Ok();
}

}  // namespace

Status ExactCubeDistance(const Eigen::Vector3i& size, const std::vector<uint8_t>& mask,
                         double cell_m, double saturation_m, int threads, const Termination& stop,
                         const ProgressCallback& progress, std::vector<float>* distance_m) {
  const int64_t nx = size.x(), ny = size.y(), nz = size.z();
  MAV_CHECK(static_cast<int64_t>(mask.size()) == nx * ny * nz) << "mask size";
  std::vector<float>& d = *distance_m;
  d.assign(mask.size(), kInf);
  const int n_max = static_cast<int>(std::max({nx, ny, nz}));
  threads = std::max(1, threads);

  // Pass 1 along z: from the mask (0 inside an obstacle cube, none elsewhere).
  MAV_RETURN_IF_ERROR(ForRows(nx * ny, n_max, threads, stop, [&](int64_t c, RowScratch* s) {
    for (int64_t k = 0; k < nz; ++k) s->in[k] = mask[c + nx * ny * k] ? 0.0f : kInf;
    HalfLatticeTransform(static_cast<int>(nz), s);
    for (int64_t k = 0; k < nz; ++k) d[c + nx * ny * k] = s->out[k];
  }));
  if (progress) progress("distance map", 1.0 / 3);
  // Pass 2 along y.
  MAV_RETURN_IF_ERROR(ForRows(nx * nz, n_max, threads, stop, [&](int64_t r, RowScratch* s) {
    const int64_t i = r % nx, k = r / nx;
    const int64_t base = i + nx * ny * k;
    for (int64_t j = 0; j < ny; ++j) s->in[j] = d[base + nx * j];
    HalfLatticeTransform(static_cast<int>(ny), s);
    for (int64_t j = 0; j < ny; ++j) d[base + nx * j] = s->out[j];
  }));
  if (progress) progress("distance map", 2.0 / 3);
  // Pass 3 along x, then from squared half cells to metres.
  const double half = 0.5 * cell_m;
  const float saturation = static_cast<float>(saturation_m);
  MAV_RETURN_IF_ERROR(ForRows(ny * nz, n_max, threads, stop, [&](int64_t r, RowScratch* s) {
    float* row = d.data() + nx * r;
    std::copy(row, row + nx, s->in.begin());
    HalfLatticeTransform(static_cast<int>(nx), s);
    for (int64_t i = 0; i < nx; ++i) {
      const float v = s->out[i];
      row[i] = v >= kInf ? saturation
                         : std::min(saturation, static_cast<float>(std::sqrt(double(v)) * half));
    }
  }));
  if (progress) progress("distance map", 1.0);
  return Status::Ok();
}

Status DynamicEdt3dDistance(const Eigen::Vector3i& size, const std::vector<uint8_t>& mask,
                            double cell_m, double saturation_m, const Termination& stop,
                            std::vector<float>* distance_m) {
  MAV_RETURN_IF_ERROR(stop.Check("distance map"));
  const int nx = size.x(), ny = size.y(), nz = size.z();
  const double half_diagonal = 0.5 * std::sqrt(3.0) * cell_m;
  // DynamicEDT3D saturates at sqrt(max_sq) cells: beyond the saturation plus the diagonal the
  // lower bound below would be above the saturation anyway.
  const double max_cells = (saturation_m + half_diagonal) / cell_m + 1;
  const int max_sq = static_cast<int>(std::ceil(max_cells * max_cells));
  DynamicEDT3D edt(max_sq);
  // DynamicEDT3D takes ownership of the bool grid (it deletes it with new[]'s layout).
  bool*** grid = new bool**[nx];
  for (int x = 0; x < nx; ++x) {
    grid[x] = new bool*[ny];
    for (int y = 0; y < ny; ++y) {
      grid[x][y] = new bool[nz];
      for (int z = 0; z < nz; ++z) {
        grid[x][y][z] = mask[x + static_cast<int64_t>(nx) * (y + static_cast<int64_t>(ny) * z)];
      }
    }
  }
  edt.initializeMap(nx, ny, nz, grid);
  edt.update(true);
  MAV_RETURN_IF_ERROR(stop.Check("distance map"));
  std::vector<float>& d = *distance_m;
  d.resize(mask.size());
  const float saturation = static_cast<float>(saturation_m);
  for (int z = 0; z < nz; ++z) {
    for (int y = 0; y < ny; ++y) {
      for (int x = 0; x < nx; ++x) {
        const double centres_m = edt.getDistance(x, y, z) * cell_m;
        d[x + static_cast<int64_t>(nx) * (y + static_cast<int64_t>(ny) * z)] =
            std::min(saturation, static_cast<float>(std::max(0.0, centres_m - half_diagonal)));
      }
    }
  }
  return Status::Ok();
}

}  // namespace mav::planning::internal
