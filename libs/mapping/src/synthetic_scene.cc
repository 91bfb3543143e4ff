#include "mav/mapping/synthetic_scene.h"

#include <cmath>

#include <Eigen/Geometry>
#include <limits>
#include <random>

namespace mav::mapping {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Slab test: entry distance of the ray into the box (0 if the origin is inside), or infinity.
double RayBox(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Eigen::Vector3d& lo,
              const Eigen::Vector3d& hi) {
  double t0 = 0.0, t1 = kInf;
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0.0) {
      if (o[a] < lo[a] || o[a] > hi[a]) return kInf;
      continue;
    }
    double ta = (lo[a] - o[a]) / d[a];
    double tb = (hi[a] - o[a]) / d[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 > t1) return kInf;
  }
  return t0;
}

}  // namespace

double SyntheticScene::RayCast(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir) const {
  // Exit distance from the room interior.
  double best = kInf;
  for (int a = 0; a < 3; ++a) {
    if (dir[a] > 0) best = std::min(best, (room_max[a] - origin[a]) / dir[a]);
    if (dir[a] < 0) best = std::min(best, (room_min[a] - origin[a]) / dir[a]);
  }
  for (const Box& b : boxes) best = std::min(best, RayBox(origin, dir, b.min, b.max));
  return std::max(best, 0.0);
}

OccupancyGrid SyntheticScene::TruthGrid(const GridGeometry& g) const {
  OccupancyGrid grid(g, VoxelState::kFree);
  for (int k = 0; k < g.size.z(); ++k) {
    for (int j = 0; j < g.size.y(); ++j) {
      for (int i = 0; i < g.size.x(); ++i) {
        const Eigen::Vector3d lo = g.origin + Eigen::Vector3d(i, j, k) * g.resolution;
        const Eigen::Vector3d hi = lo + Eigen::Vector3d::Constant(g.resolution);
        bool solid = (lo.array() < room_min.array()).any() || (hi.array() > room_max.array()).any();
        for (const Box& b : boxes) {
          if (solid) break;
          solid = (lo.array() < b.max.array()).all() && (hi.array() > b.min.array()).all();
        }
        if (solid) grid[grid.Linear(i, j, k)] = VoxelState::kOccupied;
      }
    }
  }
  return grid;
}

SyntheticScene MakeRoomScene() {
  SyntheticScene s;
  s.room_min = Eigen::Vector3d(0, 0, 0);
  s.room_max = Eigen::Vector3d(8, 6, 3);
  s.boxes.push_back({Eigen::Vector3d(1.0, 1.0, 0.0), Eigen::Vector3d(2.6, 1.9, 0.75)});  // table
  s.boxes.push_back({Eigen::Vector3d(6.6, 0.0, 0.0), Eigen::Vector3d(8.0, 0.6, 2.0)});   // cabinet
  s.boxes.push_back({Eigen::Vector3d(5.2, 3.8, 0.0), Eigen::Vector3d(5.6, 4.2, 3.0)});   // pillar
  s.boxes.push_back({Eigen::Vector3d(2.0, 4.6, 0.0), Eigen::Vector3d(3.0, 5.4, 0.8)});   // crate
  return s;
}

void SampleRoomObservations(const SyntheticScene& scene, const SyntheticObservationOptions& o,
                            std::vector<MapPoint>* points, std::vector<KeyframeView>* keyframes) {
  points->clear();
  keyframes->clear();
  std::mt19937_64 rng(o.seed);
  std::normal_distribution<double> noise(0.0, o.noise_sigma);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const Eigen::Vector3d center = 0.5 * (scene.room_min + scene.room_max);
  const Eigen::Vector3d extent = scene.room_max - scene.room_min;
  std::vector<Eigen::Vector3d> looks;
  for (int k = 0; k < o.num_keyframes; ++k) {
    const double phase = 2.0 * M_PI * k / o.num_keyframes;
    const double angle = 2.0 * phase;  // two loops through the room
    KeyframeView kf;
    kf.id = k;
    kf.center_world = center + Eigen::Vector3d(0.3 * extent.x() * std::cos(angle),
                                               0.25 * extent.y() * std::sin(angle),
                                               0.15 * extent.z() * std::sin(3.0 * phase));
    // Look obliquely outwards, alternating sides per loop, with a slow pitch oscillation.
    const double yaw = angle + (k < o.num_keyframes / 2 ? 1.0 : -1.0) * 0.9;
    const double pitch = 0.35 * std::sin(5.0 * phase);
    looks.emplace_back(std::cos(yaw) * std::cos(pitch), std::sin(yaw) * std::cos(pitch),
                       std::sin(pitch));
    keyframes->push_back(kf);
  }
  const double cos_fov = std::cos(o.half_fov_deg * M_PI / 180.0);
  for (int k = 0; k < o.num_keyframes; ++k) {
    const Eigen::Vector3d look = looks[k];
    const Eigen::Vector3d u = look.unitOrthogonal();
    const Eigen::Vector3d v = look.cross(u);
    const Eigen::Vector3d& c = (*keyframes)[k].center_world;
    for (int n = 0; n < o.points_per_keyframe; ++n) {
      // Uniform direction in the cone.
      const double cos_t = 1.0 - uniform(rng) * (1.0 - cos_fov);
      const double sin_t = std::sqrt(1.0 - cos_t * cos_t);
      const double phi = 2.0 * M_PI * uniform(rng);
      const Eigen::Vector3d dir =
          (cos_t * look + sin_t * (std::cos(phi) * u + std::sin(phi) * v)).normalized();
      const double t = scene.RayCast(c, dir);
      if (!std::isfinite(t) || t < 0.2) continue;
      const Eigen::Vector3d hit = c + t * dir;
      MapPoint p;
      p.p_world = hit + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
      p.keyframes.push_back(k);
      for (int m = k + 1;
           m < o.num_keyframes && static_cast<int>(p.keyframes.size()) < o.views_per_point &&
           m <= k + 3 * o.views_per_point;
           ++m) {
        const Eigen::Vector3d& cm = (*keyframes)[m].center_world;
        const Eigen::Vector3d to = hit - cm;
        const double dist = to.norm();
        if (to.normalized().dot(looks[m]) < cos_fov) continue;
        if (scene.RayCast(cm, to / dist) < dist - 0.01) continue;  // occluded
        p.keyframes.push_back(m);
      }
      points->push_back(std::move(p));
    }
  }
}

}  // namespace mav::mapping
