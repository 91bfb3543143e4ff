#pragma once
// What a flying vehicle can hit: a clearance query (distance from a point to the nearest
// obstacle surface) over the simulator's analytic world (World::SignedDistance) or an OctoMap
// (occupied leaves, e.g. the contest's power_plant.bt). OctoMap stays behind the interface.

#include <memory>
#include <string>

#include <Eigen/Core>

#include "mav/common/status.h"

namespace mav::sim {

class World;

class CollisionWorld {
 public:
  virtual ~CollisionWorld() = default;
  // Distance (m) from p_world to the nearest obstacle surface; negative inside an obstacle
  // where the representation knows it (the primitives), 0 inside an occupied voxel; max_range_m
  // when nothing is nearer than that.
  virtual double Clearance(const Eigen::Vector3d& p_world, double max_range_m) const = 0;
  // A short description for reports ("octomap power_plant.bt", "primitives").
  virtual std::string Describe() const = 0;
};

// The analytic primitives of `world` (kept alive by the pointer).
std::unique_ptr<CollisionWorld> MakePrimitiveCollisionWorld(std::shared_ptr<const World> world);
// The same without the primitives that lie entirely at or below `ground_z_m` (a room's floor
// slab, a plant's ground): a FlightSimulation models that ground as its ground plane, where a
// touchdown slower than its landing speed is a landing, not a collision.
std::unique_ptr<CollisionWorld> MakePrimitiveCollisionWorldAboveGround(const World& world,
                                                                       double ground_z_m);

// The occupied leaves of an OctoMap binary file (.bt). NotFound / DataLoss naming the file.
// Clearance is the exact distance to the nearest occupied voxel box, found by searching boxes
// of doubling size around the point.
Result<std::unique_ptr<CollisionWorld>> LoadOctomapCollisionWorld(const std::string& path);

}  // namespace mav::sim
