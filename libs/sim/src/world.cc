#include "mav/sim/world.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "intersect.h"
#include "mav/common/check.h"
#include "random.h"

namespace mav::sim {
namespace {

constexpr double kTouchEps = 1e-9;  // metres: overlap below this is "touching", not intersecting

// Rotation about z by yaw, exact for multiples of 90 degrees (keeps walls axis-aligned).
Eigen::Matrix3d RotZ(double yaw) {
  const double quarter = yaw / (M_PI / 2);
  double c = std::cos(yaw), s = std::sin(yaw);
  if (std::abs(quarter - std::round(quarter)) < 1e-12) {
    const int q = ((static_cast<int>(std::lround(quarter)) % 4) + 4) % 4;
    const int cs[4] = {1, 0, -1, 0}, ss[4] = {0, 1, 0, -1};
    c = cs[q];
    s = ss[q];
  }
  Eigen::Matrix3d r;
  r << c, -s, 0, s, c, 0, 0, 0, 1;
  return r;
}

// A right-handed frame whose third column is `axis` (unit); exact for coordinate axes.
Eigen::Matrix3d FrameWithZ(const Eigen::Vector3d& axis) {
  Eigen::Vector3d z = axis.normalized();
  for (int k = 0; k < 3; ++k) {
    if (std::abs(std::abs(z[k]) - 1.0) < 1e-12) {
      z = Eigen::Vector3d::Zero();
      z[k] = axis[k] > 0 ? 1 : -1;
      Eigen::Vector3d x = Eigen::Vector3d::Zero();
      x[(k + 1) % 3] = 1;
      Eigen::Matrix3d r;
      r.col(0) = x;
      r.col(1) = z.cross(x);
      r.col(2) = z;
      return r;
    }
  }
  const Eigen::Vector3d helper =
      std::abs(z.z()) < 0.9 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitX();
  const Eigen::Vector3d x = helper.cross(z).normalized();
  Eigen::Matrix3d r;
  r.col(0) = x;
  r.col(1) = z.cross(x);
  r.col(2) = z;
  return r;
}

// Separating-axis test between an axis-aligned box (centre cv, half extents e) and an oriented
// box (centre c, axes R columns, half extents h). `strict`: interiors must overlap by more than
// kTouchEps along every axis; otherwise touching counts as intersecting.
bool SatAabbObb(const Eigen::Vector3d& cv, const Eigen::Vector3d& e, const Eigen::Vector3d& c,
                const Eigen::Matrix3d& R, const Eigen::Vector3d& h, bool strict) {
  const Eigen::Vector3d t = c - cv;
  auto separated = [&](const Eigen::Vector3d& axis) {
    const double n = axis.norm();
    if (n < 1e-9) return false;  // parallel edges: the axis is degenerate, skip it
    const Eigen::Vector3d l = axis / n;
    const double ra = e.x() * std::abs(l.x()) + e.y() * std::abs(l.y()) + e.z() * std::abs(l.z());
    const double rb = h.x() * std::abs(l.dot(R.col(0))) + h.y() * std::abs(l.dot(R.col(1))) +
                      h.z() * std::abs(l.dot(R.col(2)));
    const double overlap = ra + rb - std::abs(t.dot(l));
    return strict ? overlap <= kTouchEps : overlap < -kTouchEps;
  };
  for (int i = 0; i < 3; ++i) {
    if (separated(Eigen::Vector3d::Unit(i))) return false;
    if (separated(R.col(i))) return false;
  }
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      if (separated(Eigen::Vector3d::Unit(i).cross(R.col(j)))) return false;
    }
  }
  return true;
}

double BoxSdfLocal(const Eigen::Vector3d& p, const Eigen::Vector3d& h) {
  const Eigen::Vector3d q = p.cwiseAbs() - h;
  return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0);
}

double CylinderSdfLocal(const Eigen::Vector3d& p, double r, double h) {
  const double dr = std::hypot(p.x(), p.y()) - r;
  const double dz = std::abs(p.z()) - h;
  return std::min(std::max(dr, dz), 0.0) + std::hypot(std::max(dr, 0.0), std::max(dz, 0.0));
}

}  // namespace

bool Primitive::IsAxisAligned() const {
  for (int j = 0; j < 3; ++j) {
    int ones = 0;
    for (int i = 0; i < 3; ++i) {
      const double a = std::abs(R_world_local(i, j));
      if (std::abs(a - 1.0) < 1e-12) {
        ++ones;
      } else if (a > 1e-12) {
        return false;
      }
    }
    if (ones != 1) return false;
  }
  return true;
}

Eigen::AlignedBox3d Primitive::Bounds() const {
  Eigen::Vector3d ext;
  const Eigen::Matrix3d& R = R_world_local;
  if (type == PrimitiveType::kCylinder) {
    const double r = half_size.x(), h = half_size.z();
    for (int i = 0; i < 3; ++i) {
      const double a = R(i, 2);
      ext[i] = std::abs(a) * h + r * std::sqrt(std::max(0.0, 1.0 - a * a));
    }
  } else {
    const double hz = type == PrimitiveType::kRectangle ? 0.0 : half_size.z();
    ext = R.cwiseAbs() * Eigen::Vector3d(half_size.x(), half_size.y(), hz);
  }
  return Eigen::AlignedBox3d(center - ext, center + ext);
}

double Primitive::SignedDistance(const Eigen::Vector3d& p_world) const {
  const Eigen::Vector3d p = R_world_local.transpose() * (p_world - center);
  switch (type) {
    case PrimitiveType::kBox:
      return BoxSdfLocal(p, half_size);
    case PrimitiveType::kCylinder:
      return CylinderSdfLocal(p, half_size.x(), half_size.z());
    case PrimitiveType::kRectangle:
      return BoxSdfLocal(p, Eigen::Vector3d(half_size.x(), half_size.y(), 0.0));
  }
  return std::numeric_limits<double>::infinity();
}

bool Primitive::IntersectsBox(const Eigen::AlignedBox3d& box) const {
  const Eigen::Vector3d cv = box.center();
  const Eigen::Vector3d e = box.sizes() / 2;
  switch (type) {
    case PrimitiveType::kBox:
      if (IsAxisAligned()) {
        const Eigen::Vector3d ext = R_world_local.cwiseAbs() * half_size;
        for (int i = 0; i < 3; ++i) {
          if (e[i] + ext[i] - std::abs(center[i] - cv[i]) <= kTouchEps) return false;
        }
        return true;
      }
      return SatAabbObb(cv, e, center, R_world_local, half_size, /*strict=*/true);
    case PrimitiveType::kRectangle:
      return SatAabbObb(cv, e, center, R_world_local,
                        Eigen::Vector3d(half_size.x(), half_size.y(), 0.0), /*strict=*/false);
    case PrimitiveType::kCylinder: {
      const double r = half_size.x(), h = half_size.z();
      int k = -1;
      for (int i = 0; i < 3; ++i) {
        if (std::abs(std::abs(R_world_local(i, 2)) - 1.0) < 1e-12) k = i;
      }
      if (k < 0) {
        // Tilted axis: conservative (documented in world.h).
        return SignedDistance(cv) < e.norm();
      }
      // Disc x interval: the axial intervals must overlap, and the disc must reach into the
      // voxel's rectangle in the two other coordinates (closest-point distance < r).
      if (e[k] + h - std::abs(center[k] - cv[k]) <= kTouchEps) return false;
      double d2 = 0;
      for (int i = 0; i < 3; ++i) {
        if (i == k) continue;
        const double gap = std::abs(center[i] - cv[i]) - e[i];
        if (gap > 0) d2 += gap * gap;
      }
      return std::sqrt(d2) < r - kTouchEps;
    }
  }
  return false;
}

std::optional<double> Primitive::Intersect(const Eigen::Vector3d& origin,
                                           const Eigen::Vector3d& dir, double t_min,
                                           double t_max) const {
  const Eigen::Vector3d o = R_world_local.transpose() * (origin - center);
  const Eigen::Vector3d d = R_world_local.transpose() * dir;
  double t = internal::Inf<double>();
  switch (type) {
    case PrimitiveType::kBox:
      t = internal::RayBoxLocal(o.x(), o.y(), o.z(), d.x(), d.y(), d.z(), half_size.x(),
                                half_size.y(), half_size.z(), t_min);
      break;
    case PrimitiveType::kCylinder:
      t = internal::RayCylinderLocal(o.x(), o.y(), o.z(), d.x(), d.y(), d.z(), half_size.x(),
                                     half_size.z(), t_min);
      break;
    case PrimitiveType::kRectangle:
      t = internal::RayRectangleLocal(o.x(), o.y(), o.z(), d.x(), d.y(), d.z(), half_size.x(),
                                      half_size.y(), t_min);
      break;
  }
  if (t < t_max) return t;
  return std::nullopt;
}

int World::AddMaterial(const Material& material) {
  materials_.push_back(material);
  return static_cast<int>(materials_.size()) - 1;
}

int World::AddPrimitive(const Primitive& primitive) {
  MAV_CHECK(primitive.material >= 0 && primitive.material < static_cast<int>(materials_.size()))
      << "unknown material " << primitive.material;
  MAV_CHECK((primitive.half_size.array() >= 0).all());
  Primitive p = primitive;
  if (p.uv_offset.isZero() && materials_[p.material].pattern != TexturePattern::kChecker) {
    // Deterministic per-primitive texture offset so neighbours do not repeat each other
    // (checkerboards keep their corners at multiples of the square size).
    internal::Rng rng(primitives_.size() * 0x51ed27ULL + 17);
    p.uv_offset = Eigen::Vector2d(rng.Uniform(0, 50), rng.Uniform(0, 50));
  }
  primitives_.push_back(p);
  return static_cast<int>(primitives_.size()) - 1;
}

int World::AddBox(const Eigen::Vector3d& center, const Eigen::Matrix3d& R_world_local,
                  const Eigen::Vector3d& half_extents, int material) {
  Primitive p;
  p.type = PrimitiveType::kBox;
  p.center = center;
  p.R_world_local = R_world_local;
  p.half_size = half_extents;
  p.material = material;
  return AddPrimitive(p);
}

int World::AddAlignedBox(const Eigen::Vector3d& min_corner, const Eigen::Vector3d& max_corner,
                         int material) {
  return AddBox((min_corner + max_corner) / 2, Eigen::Matrix3d::Identity(),
                (max_corner - min_corner).cwiseAbs() / 2, material);
}

int World::AddCylinder(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, double radius,
                       int material) {
  const Eigen::Vector3d axis = p1 - p0;
  MAV_CHECK(axis.norm() > 0 && radius > 0);
  Primitive p;
  p.type = PrimitiveType::kCylinder;
  p.center = (p0 + p1) / 2;
  p.R_world_local = FrameWithZ(axis);
  p.half_size = Eigen::Vector3d(radius, radius, axis.norm() / 2);
  p.material = material;
  return AddPrimitive(p);
}

int World::AddRectangle(const Eigen::Vector3d& center, const Eigen::Matrix3d& R_world_local,
                        const Eigen::Vector2d& half_size, int material, bool solid) {
  Primitive p;
  p.type = PrimitiveType::kRectangle;
  p.center = center;
  p.R_world_local = R_world_local;
  p.half_size = Eigen::Vector3d(half_size.x(), half_size.y(), 0);
  p.material = material;
  p.solid = solid;
  return AddPrimitive(p);
}

void World::AddRoomShell(const Eigen::AlignedBox3d& in, double t, int floor_material,
                         int wall_material, int ceiling_material) {
  const Eigen::Vector3d& lo = in.min();
  const Eigen::Vector3d& hi = in.max();
  const Eigen::Vector3d tt(t, t, 0);
  AddAlignedBox(Eigen::Vector3d(lo.x() - t, lo.y() - t, lo.z() - t),
                Eigen::Vector3d(hi.x() + t, hi.y() + t, lo.z()), floor_material);
  AddAlignedBox(Eigen::Vector3d(lo.x() - t, lo.y() - t, hi.z()),
                Eigen::Vector3d(hi.x() + t, hi.y() + t, hi.z() + t), ceiling_material);
  AddAlignedBox(Eigen::Vector3d(lo.x() - t, lo.y() - t, lo.z()),
                Eigen::Vector3d(lo.x(), hi.y() + t, hi.z()), wall_material);
  AddAlignedBox(Eigen::Vector3d(hi.x(), lo.y() - t, lo.z()),
                Eigen::Vector3d(hi.x() + t, hi.y() + t, hi.z()), wall_material);
  AddAlignedBox(Eigen::Vector3d(lo.x(), lo.y() - t, lo.z()),
                Eigen::Vector3d(hi.x(), lo.y(), hi.z()), wall_material);
  AddAlignedBox(Eigen::Vector3d(lo.x(), hi.y(), lo.z()),
                Eigen::Vector3d(hi.x(), hi.y() + t, hi.z()), wall_material);
}

void World::AddWall(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double z0, double height,
                    double thickness, int material) {
  const Eigen::Vector2d d = b - a;
  const Eigen::Vector2d m = (a + b) / 2;
  AddBox(Eigen::Vector3d(m.x(), m.y(), z0 + height / 2), RotZ(std::atan2(d.y(), d.x())),
         Eigen::Vector3d(d.norm() / 2, thickness / 2, height / 2), material);
}

void World::AddShelf(const Eigen::Vector3d& base_center, double yaw, double width, double depth,
                     double height, int levels, int frame_material, int board_material) {
  const Eigen::Matrix3d R = RotZ(yaw);
  constexpr double kPost = 0.04, kBoard = 0.025;
  for (int sx = -1; sx <= 1; sx += 2) {
    for (int sy = -1; sy <= 1; sy += 2) {
      const Eigen::Vector3d local(sx * (width / 2 - kPost / 2), sy * (depth / 2 - kPost / 2),
                                  height / 2);
      AddBox(base_center + R * local, R, Eigen::Vector3d(kPost / 2, kPost / 2, height / 2),
             frame_material);
    }
  }
  for (int l = 0; l < levels; ++l) {
    const double z = 0.12 + (height - 0.12 - kBoard / 2) * l / std::max(1, levels - 1);
    AddBox(base_center + R * Eigen::Vector3d(0, 0, z), R,
           Eigen::Vector3d(width / 2 - kPost, depth / 2 - 0.005, kBoard / 2), board_material);
  }
}

void World::AddLadder(const Eigen::Vector3d& base_center, const Eigen::Vector3d& top_center,
                      double width, double rung_spacing, int material) {
  const Eigen::Vector3d axis = top_center - base_center;
  const double length = axis.norm();
  MAV_CHECK(length > 0 && width > 0 && rung_spacing > 0);
  const Eigen::Vector3d z = axis / length;
  Eigen::Vector3d side = z.cross(Eigen::Vector3d::UnitZ());
  if (side.norm() < 1e-9) side = Eigen::Vector3d::UnitX();
  side.normalize();
  // Snap nearly axis-aligned rung directions so that rung occupancy stays exact.
  for (int k = 0; k < 3; ++k) {
    if (std::abs(std::abs(side[k]) - 1) < 1e-9) {
      const double s = side[k] > 0 ? 1 : -1;
      side.setZero();
      side[k] = s;
    }
  }
  Eigen::Matrix3d R;
  R.col(0) = side;
  R.col(1) = z.cross(side);
  R.col(2) = z;
  const Eigen::Vector3d rail_half(0.02, 0.035, length / 2);
  for (int s = -1; s <= 1; s += 2) {
    AddBox((base_center + top_center) / 2 + s * (width / 2) * side, R, rail_half, material);
  }
  for (double d = rung_spacing; d < length - 0.05; d += rung_spacing) {
    const Eigen::Vector3d c = base_center + d * z;
    AddCylinder(c - (width / 2 - 0.02) * side, c + (width / 2 - 0.02) * side, 0.016, material);
  }
}

void World::AddPipe(const std::vector<Eigen::Vector3d>& points, double radius, int material) {
  MAV_CHECK(points.size() >= 2);
  for (size_t i = 0; i + 1 < points.size(); ++i) {
    const Eigen::Vector3d dir = (points[i + 1] - points[i]).normalized();
    // Interior joints are extended by the radius so that segments overlap at bends.
    const Eigen::Vector3d a = points[i] - (i > 0 ? radius : 0.0) * dir;
    const Eigen::Vector3d b = points[i + 1] + (i + 2 < points.size() ? radius : 0.0) * dir;
    AddCylinder(a, b, radius, material);
  }
}

void World::AddTank(const Eigen::Vector3d& base_center, double radius, double height,
                    int material) {
  AddCylinder(base_center, base_center + Eigen::Vector3d(0, 0, height), radius, material);
  AddCylinder(base_center + Eigen::Vector3d(0, 0, height),
              base_center + Eigen::Vector3d(0, 0, height + 0.15 * radius), 0.7 * radius, material);
}

void World::AddTower(const Eigen::Vector3d& base_center, double width, double height,
                     double leg_radius, int material) {
  const double hw = width / 2;
  for (int sx = -1; sx <= 1; sx += 2) {
    for (int sy = -1; sy <= 1; sy += 2) {
      const Eigen::Vector3d p = base_center + Eigen::Vector3d(sx * hw, sy * hw, 0);
      AddCylinder(p, p + Eigen::Vector3d(0, 0, height), leg_radius, material);
    }
  }
  for (double z = 3.0; z < height - 0.5; z += 3.0) {
    for (int s = -1; s <= 1; s += 2) {
      AddAlignedBox(base_center + Eigen::Vector3d(-hw, s * hw - 0.05, z - 0.05),
                    base_center + Eigen::Vector3d(hw, s * hw + 0.05, z + 0.05), material);
      AddAlignedBox(base_center + Eigen::Vector3d(s * hw - 0.05, -hw, z - 0.05),
                    base_center + Eigen::Vector3d(s * hw + 0.05, hw, z + 0.05), material);
    }
  }
  AddAlignedBox(base_center + Eigen::Vector3d(-hw - 0.3, -hw - 0.3, height),
                base_center + Eigen::Vector3d(hw + 0.3, hw + 0.3, height + 0.15), material);
}

Eigen::AlignedBox3d World::bounds() const {
  if (bounds_) return *bounds_;
  Eigen::AlignedBox3d b;
  for (const Primitive& p : primitives_) b.extend(p.Bounds());
  return b;
}

double World::SignedDistance(const Eigen::Vector3d& p_world) const {
  double best = std::numeric_limits<double>::infinity();
  for (const Primitive& p : primitives_) {
    if (!p.solid) continue;
    // The distance to the bounding box is a lower bound of the distance to the primitive.
    if (p.Bounds().exteriorDistance(p_world) >= best) continue;
    best = std::min(best, p.SignedDistance(p_world));
  }
  return best;
}

std::optional<RayHit> World::CastRay(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                                     double t_max) const {
  RayHit hit;
  hit.t = t_max;
  for (size_t i = 0; i < primitives_.size(); ++i) {
    const std::optional<double> t = primitives_[i].Intersect(origin, dir, 1e-6, hit.t);
    if (t) {
      hit.t = *t;
      hit.primitive = static_cast<int>(i);
    }
  }
  if (hit.primitive < 0) return std::nullopt;
  hit.p_world = origin + hit.t * dir;
  SurfaceAt(hit.primitive, hit.p_world, &hit.normal_world, &hit.uv);
  if (hit.normal_world.dot(dir) > 0) hit.normal_world = -hit.normal_world;
  return hit;
}

void World::SurfaceAt(int i, const Eigen::Vector3d& p_world, Eigen::Vector3d* normal_world,
                      Eigen::Vector2d* uv) const {
  const Primitive& prim = primitives_.at(i);
  const Eigen::Vector3d p = prim.R_world_local.transpose() * (p_world - prim.center);
  Eigen::Vector3d n = Eigen::Vector3d::UnitZ();
  Eigen::Vector2d st(p.x(), p.y());
  if (prim.type == PrimitiveType::kBox) {
    int k = 0;
    double best = -1;
    for (int a = 0; a < 3; ++a) {
      const double r = std::abs(p[a]) / std::max(prim.half_size[a], 1e-12);
      if (r > best) {
        best = r;
        k = a;
      }
    }
    n = Eigen::Vector3d::Zero();
    n[k] = p[k] > 0 ? 1 : -1;
    st = k == 0 ? Eigen::Vector2d(p.y(), p.z())
                : (k == 1 ? Eigen::Vector2d(p.x(), p.z()) : Eigen::Vector2d(p.x(), p.y()));
  } else if (prim.type == PrimitiveType::kCylinder) {
    const double r = prim.half_size.x(), h = prim.half_size.z();
    const double radial = std::hypot(p.x(), p.y());
    if (std::abs(std::abs(p.z()) - h) < 1e-6 * std::max(1.0, h) && radial < r * (1 - 1e-6)) {
      n = Eigen::Vector3d(0, 0, p.z() > 0 ? 1 : -1);
    } else {
      n = Eigen::Vector3d(p.x(), p.y(), 0) / std::max(radial, 1e-12);
      st = Eigen::Vector2d(std::atan2(p.y(), p.x()) * r, p.z());
    }
  }
  if (normal_world) *normal_world = prim.R_world_local * n;
  if (uv) *uv = st + prim.uv_offset;
}

void World::BuildTextures(uint64_t seed) {
  textures_.clear();
  for (size_t m = 0; m < materials_.size(); ++m) {
    textures_.push_back(GenerateTexture(materials_[m], internal::HashCombine(seed, m)));
  }
}

const Texture* World::texture(int material) const {
  if (material < 0 || material >= static_cast<int>(textures_.size())) return nullptr;
  return textures_[material].get();
}

}  // namespace mav::sim
