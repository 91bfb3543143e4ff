#pragma once
// The simulator's world: a set of analytic primitives (oriented boxes, capped cylinders with an
// arbitrary axis, rectangles) with materials, plus composites built from them (shelves, ladders,
// pipes, tanks, towers, walls, the inside of a room). World frame: z up, gravity along -z, metres.
//
// The world answers three kinds of question, all exactly from the primitives:
//  * ray casting (the renderer, renderer.h),
//  * signed distance to the nearest solid surface (negative inside a solid), which the trajectory
//    generator uses as its clearance function (TrajectoryOptions::clearance),
//  * point and axis-aligned box (voxel) intersection tests for the ground-truth occupancy grid.
//
// Solidity: boxes and cylinders are solid volumes. Rectangles are zero-thickness surfaces; they
// are "decals" (posters, lamps, test patterns) unless added with solid = true, and decals never
// count for occupancy or clearance.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "mav/sim/texture.h"

namespace mav::sim {

enum class PrimitiveType : uint8_t {
  kBox,        // solid, centre + R_world_local + half extents (hx, hy, hz)
  kCylinder,   // solid, axis = local z through the centre, radius = half_size.x(),
               // half length = half_size.z(); capped with flat discs
  kRectangle,  // surface in the local x-y plane, half sizes (hx, hy), normal local +z
};

struct Primitive {
  PrimitiveType type = PrimitiveType::kBox;
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  // Columns are the primitive's local axes expressed in the world frame.
  Eigen::Matrix3d R_world_local = Eigen::Matrix3d::Identity();
  Eigen::Vector3d half_size = Eigen::Vector3d::Zero();
  int material = 0;
  bool solid = true;
  // Offset of the surface texture coordinates (metres), so equal materials do not repeat
  // identically on neighbouring primitives.
  Eigen::Vector2d uv_offset = Eigen::Vector2d::Zero();

  // True if R_world_local is a signed permutation (axes aligned with the world's).
  bool IsAxisAligned() const;
  // Tight world-frame bounding box.
  Eigen::AlignedBox3d Bounds() const;
  // Signed Euclidean distance (exact) from p_world to the primitive's surface; negative inside.
  // Rectangles: unsigned distance to the rectangle.
  double SignedDistance(const Eigen::Vector3d& p_world) const;
  // Does the half-open voxel/box `box` intersect the primitive? Boxes: exact separating-axis test
  // (15 axes); the interiors must overlap by more than 1e-9 m, so a voxel that only touches a
  // face is not occupied. Cylinders with an axis along x, y or z: exact (disc-rectangle distance
  // times axial interval overlap). Tilted cylinders: conservative, the voxel is counted if the
  // cylinder's signed distance at its centre is below the voxel's half diagonal (may over-mark
  // one shell of voxels; the presets use axis-aligned cylinders only). Rectangles: closed test
  // (touching counts).
  bool IntersectsBox(const Eigen::AlignedBox3d& box) const;
  // Ray hit distance along a unit direction in (t_min, t_max), if any.
  std::optional<double> Intersect(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                                  double t_min, double t_max) const;
};

// A full ray-hit record (used by tests and tools; the renderer has its own fast path).
struct RayHit {
  double t = 0;
  int primitive = -1;
  Eigen::Vector3d p_world = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal_world = Eigen::Vector3d::Zero();  // faces the ray origin
  Eigen::Vector2d uv = Eigen::Vector2d::Zero();            // metric surface coordinates
};

// Simple, shadowless lighting: radiance = albedo * (ambient + diffuse * (0.5 + 0.5 n.l)) +
// emission, a "hemisphere" light that never leaves a face completely dark.
struct Lighting {
  Eigen::Vector3d direction_to_light = Eigen::Vector3d(0.3, 0.45, 1.0).normalized();
  double ambient = 0.25;
  double diffuse = 0.75;
  // Radiance of rays that hit nothing (sky above the plant, never seen inside a room).
  double background = 0.85;
};

class World {
 public:
  World() = default;

  // ---- materials ----
  int AddMaterial(const Material& material);
  const std::vector<Material>& materials() const { return materials_; }

  // ---- primitives ----
  int AddBox(const Eigen::Vector3d& center, const Eigen::Matrix3d& R_world_local,
             const Eigen::Vector3d& half_extents, int material);
  // Axis-aligned box from corners.
  int AddAlignedBox(const Eigen::Vector3d& min_corner, const Eigen::Vector3d& max_corner,
                    int material);
  // Capped cylinder between the centres of its end discs.
  int AddCylinder(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, double radius,
                  int material);
  // Rectangle with local x = R.col(0), y = R.col(1) and normal R.col(2).
  int AddRectangle(const Eigen::Vector3d& center, const Eigen::Matrix3d& R_world_local,
                   const Eigen::Vector2d& half_size, int material, bool solid = false);
  int AddPrimitive(const Primitive& primitive);
  const std::vector<Primitive>& primitives() const { return primitives_; }

  // ---- composites (all return nothing; they add primitives) ----
  // The inside of an axis-aligned room: floor, ceiling and four walls as slabs of `thickness`
  // outside `interior`.
  void AddRoomShell(const Eigen::AlignedBox3d& interior, double thickness, int floor_material,
                    int wall_material, int ceiling_material);
  // A straight wall segment on the ground from a to b (z of a/b ignored), height h, thickness d.
  void AddWall(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double z0, double height,
               double thickness, int material);
  // Shelf: footprint centre (x, y) on z0, yaw, width (along local x), depth, height, levels.
  void AddShelf(const Eigen::Vector3d& base_center, double yaw, double width, double depth,
                double height, int levels, int frame_material, int board_material);
  // Ladder from base (two rails) to top, rails `width` apart (perpendicular to the ladder and
  // horizontal), round rungs every `rung_spacing`.
  void AddLadder(const Eigen::Vector3d& base_center, const Eigen::Vector3d& top_center,
                 double width, double rung_spacing, int material);
  // Pipe through the polyline `points` (cylinder segments with small joint spheres
  // approximated by short cylinders); thin pipes (radius ~1-2 cm) are the fine structures.
  void AddPipe(const std::vector<Eigen::Vector3d>& points, double radius, int material);
  // Vertical tank: cylinder with a flat roof on z0.
  void AddTank(const Eigen::Vector3d& base_center, double radius, double height, int material);
  // Lattice tower: four vertical legs at the corners of a square, horizontal braces.
  void AddTower(const Eigen::Vector3d& base_center, double width, double height, double leg_radius,
                int material);

  Lighting& lighting() { return lighting_; }
  const Lighting& lighting() const { return lighting_; }

  // ---- bounds ----
  // The world's extent: occupancy is free inside, unknown outside. Defaults to the union of
  // the primitive bounds.
  void SetBounds(const Eigen::AlignedBox3d& bounds) { bounds_ = bounds; }
  Eigen::AlignedBox3d bounds() const;

  // ---- queries ----
  // Signed distance from p to the nearest solid surface (negative inside a solid); +infinity
  // for a world without solids. Exact (min over the primitives' exact distances).
  double SignedDistance(const Eigen::Vector3d& p_world) const;
  bool IsInsideSolid(const Eigen::Vector3d& p_world) const { return SignedDistance(p_world) < 0; }
  // Nearest hit of a ray (unit direction) with any primitive (solid or decal).
  std::optional<RayHit> CastRay(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                                double t_max = 1e9) const;
  // Surface normal (outward) and metric texture coordinates of primitive `i` at a surface
  // point p_world.
  void SurfaceAt(int i, const Eigen::Vector3d& p_world, Eigen::Vector3d* normal_world,
                 Eigen::Vector2d* uv) const;

  // ---- textures ----
  // Generates every material's texture pyramid, deterministically from the seed. Must be
  // called (again) after materials are added and before rendering.
  void BuildTextures(uint64_t seed);
  // Texture of material m (nullptr before BuildTextures()).
  const Texture* texture(int material) const;

 private:
  std::vector<Material> materials_;
  std::vector<Primitive> primitives_;
  std::vector<std::shared_ptr<const Texture>> textures_;
  std::optional<Eigen::AlignedBox3d> bounds_;
  Lighting lighting_;
};

}  // namespace mav::sim
