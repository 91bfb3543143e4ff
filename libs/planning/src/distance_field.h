#pragma once
// Distance transforms over a dense obstacle mask (internal to libs/planning). See planning_map.h
// for the maths; the mask is indexed x fastest: index = i + nx * (j + ny * k).

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "mav/common/status.h"
#include "mav/common/termination.h"

namespace mav::planning::internal {

// Exact distance (m) from every cell centre to the union of the obstacle cubes (mask != 0), cells
// of size `cell_m`, saturated at `saturation_m`. Three separable passes of the Felzenszwalb-
// Huttenlocher lower-envelope transform on the half-cell lattice, rows split over `threads`.
Status ExactCubeDistance(const Eigen::Vector3i& size, const std::vector<uint8_t>& mask,
                         double cell_m, double saturation_m, int threads, const Termination& stop,
                         const ProgressCallback& progress, std::vector<float>* distance_m);

// DynamicEDT3D's centre-to-centre distance d (m), saturated at `saturation_m`, turned into the
// lower bound max(0, d - cell_m * sqrt(3) / 2) of the distance from the centre to the nearest
// cube. The baseline of the benchmark (single-threaded; the library cannot be stopped midway, so
// `stop` is polled before and after).
Status DynamicEdt3dDistance(const Eigen::Vector3i& size, const std::vector<uint8_t>& mask,
                            double cell_m, double saturation_m, const Termination& stop,
                            std::vector<float>* distance_m);

// Peak bytes per cell each method needs on top of the mask (for MemoryEstimate).
constexpr uint64_t kExactBytesPerCell = sizeof(float);
// DynamicEDT3D's dataCell (24 B) + its bool grid (1 B) + the result (4 B) + queue slack.
constexpr uint64_t kDynamicEdt3dBytesPerCell = 24 + 1 + sizeof(float) + 3;

}  // namespace mav::planning::internal
