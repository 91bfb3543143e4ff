#include "mav/sim/collision_world.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include <octomap/OcTree.h>

#include "mav/common/file.h"
#include "mav/dataset/octomap_bt.h"
#include "mav/sim/world.h"

namespace mav::sim {
namespace {

class PrimitiveCollisionWorld : public CollisionWorld {
 public:
  explicit PrimitiveCollisionWorld(std::shared_ptr<const World> world) : world_(std::move(world)) {}
  double Clearance(const Eigen::Vector3d& p, double max_range_m) const override {
    return std::min(world_->SignedDistance(p), max_range_m);
  }
  std::string Describe() const override {
    return "primitives (" + std::to_string(world_->primitives().size()) + ")";
  }

 private:
  std::shared_ptr<const World> world_;
};

class AboveGroundCollisionWorld : public CollisionWorld {
 public:
  AboveGroundCollisionWorld(World world, size_t dropped)
      : world_(std::move(world)), dropped_(dropped) {}
  double Clearance(const Eigen::Vector3d& p, double max_range_m) const override {
    return std::min(world_.SignedDistance(p), max_range_m);
  }
  std::string Describe() const override {
    return "primitives (" + std::to_string(world_.primitives().size()) + ", " +
           std::to_string(dropped_) + " ground primitives left to the ground plane)";
  }

 private:
  World world_;
  size_t dropped_;
};

class OctomapCollisionWorld : public CollisionWorld {
 public:
  OctomapCollisionWorld(std::unique_ptr<octomap::OcTree> tree, std::string name)
      : tree_(std::move(tree)), name_(std::move(name)) {}

  double Clearance(const Eigen::Vector3d& p, double max_range_m) const override {
    // Search growing boxes: a voxel found within half-size r is at most r * sqrt(3) away, and
    // every voxel nearer than r lies in the box, so the answer is final once best <= r.
    double r = std::max(tree_->getResolution(), 0.25);
    double best = max_range_m;
    while (true) {
      const double reach = std::min(r, max_range_m);
      const octomap::point3d lo(static_cast<float>(p.x() - reach),
                                static_cast<float>(p.y() - reach),
                                static_cast<float>(p.z() - reach));
      const octomap::point3d hi(static_cast<float>(p.x() + reach),
                                static_cast<float>(p.y() + reach),
                                static_cast<float>(p.z() + reach));
      for (auto it = tree_->begin_leafs_bbx(lo, hi), end = tree_->end_leafs_bbx(); it != end;
           ++it) {
        if (!tree_->isNodeOccupied(*it)) continue;
        const double half = 0.5 * it.getSize();
        const Eigen::Vector3d c(it.getX(), it.getY(), it.getZ());
        const Eigen::Vector3d d = ((p - c).cwiseAbs().array() - half).max(0.0).matrix();
        best = std::min(best, d.norm());
      }
      if (best <= reach || reach >= max_range_m) return best;
      r *= 2;
    }
  }
  std::string Describe() const override { return "octomap " + name_; }

 private:
  std::unique_ptr<octomap::OcTree> tree_;
  std::string name_;
};

}  // namespace

std::unique_ptr<CollisionWorld> MakePrimitiveCollisionWorld(std::shared_ptr<const World> world) {
  return std::make_unique<PrimitiveCollisionWorld>(std::move(world));
}

std::unique_ptr<CollisionWorld> MakePrimitiveCollisionWorldAboveGround(const World& world,
                                                                       double ground_z_m) {
  World above;
  for (const Material& m : world.materials()) above.AddMaterial(m);
  size_t dropped = 0;
  for (const Primitive& p : world.primitives()) {
    if (p.solid && p.Bounds().max().z() <= ground_z_m + 1e-9) {
      ++dropped;
      continue;
    }
    above.AddPrimitive(p);
  }
  return std::make_unique<AboveGroundCollisionWorld>(std::move(above), dropped);
}

Result<std::unique_ptr<CollisionWorld>> LoadOctomapCollisionWorld(const std::string& path) {
  if (!PathExists(path)) return Status::NotFound(path + ": no such OctoMap file");
  // Validated before OctoMap reads it (mav/dataset/octomap_bt.h).
  MAV_ASSIGN_OR_RETURN(const std::string bytes, ReadFileToString(path));
  Result<std::unique_ptr<octomap::OcTree>> read = dataset::ReadOctomapBinary(bytes, path);
  if (!read.ok()) {
    return read.status().code() == StatusCode::kInvalidArgument
               ? Status::DataLoss(read.status().message() +
                                  " (not a readable OctoMap binary file, .bt)")
               : read.status();
  }
  std::unique_ptr<octomap::OcTree> tree = std::move(*read);
  if (tree->size() == 0) return Status::DataLoss(path + ": the OctoMap has no nodes");
  std::unique_ptr<CollisionWorld> world = std::make_unique<OctomapCollisionWorld>(
      std::move(tree), std::filesystem::path(path).filename().string());
  return world;
}

}  // namespace mav::sim
