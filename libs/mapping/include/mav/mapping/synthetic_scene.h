#pragma once
// Synthetic scenes with exact ground truth for tests, benchmarks and service contract tests of
// the mapping library (no renderer needed): an axis-aligned room whose walls, floor and ceiling
// are solid beyond its interior, with axis-aligned boxes inside; lines of sight are cast
// analytically, so point positions and visibility are exact up to the added noise.

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "mav/mapping/types.h"

namespace mav::mapping {

struct SyntheticScene {
  struct Box {
    Eigen::Vector3d min, max;
  };
  Eigen::Vector3d room_min = Eigen::Vector3d(0, 0, 0);  // free interior; outside it is solid
  Eigen::Vector3d room_max = Eigen::Vector3d(8, 6, 3);
  std::vector<Box> boxes;  // solid obstacles inside the room

  // Distance [m] along the unit direction to the first solid surface (infinity if none).
  double RayCast(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir) const;
  // Exact ground truth: kOccupied where the voxel cube overlaps solid with positive volume,
  // kFree elsewhere.
  OccupancyGrid TruthGrid(const GridGeometry& geometry) const;
};

// An 8 x 6 x 3 m room with a table, a cabinet, a pillar and a crate.
SyntheticScene MakeRoomScene();

struct SyntheticObservationOptions {
  int num_keyframes = 300;
  int points_per_keyframe = 100;
  int views_per_point = 4;     // the keyframe that found it plus up to 3 later ones that see it
  double noise_sigma = 0.01;   // [m], isotropic Gaussian noise on the points
  double half_fov_deg = 40.0;  // sampling cone half-angle around the viewing direction
  uint64_t seed = 1;
};

// Keyframes on an elliptic loop through the room looking obliquely at the walls; each samples
// points where random rays in its view cone hit the scene.
void SampleRoomObservations(const SyntheticScene& scene, const SyntheticObservationOptions& options,
                            std::vector<MapPoint>* points, std::vector<KeyframeView>* keyframes);

}  // namespace mav::mapping
