#include "mav/sim/renderer.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <opencv2/core.hpp>

#include "intersect.h"
#include "mav/common/check.h"
#include "random.h"

namespace mav::sim {
namespace {

constexpr int kTile = 16;       // pixels per tile side
constexpr int kSuper = 4;       // tiles per super-tile side (64 x 64 pixels)
constexpr float kTMin = 1e-3f;  // metres

struct Cone {
  float ax = 0, ay = 0, az = 1;
  float cos_half = 1, sin_half = 0;
  bool empty = true;
};

// A bounding sphere of (part of) a primitive for culling.
struct Proxy {
  Eigen::Vector3d center;
  double radius;
  int primitive;
};

// Per-frame data of one primitive, all in float, relative to its centre.
struct PrimFrame {
  float o[3];      // camera centre in the primitive's local frame
  float m[9];      // R_local_cam (row-major): d_local = m * d_cam
  float h[3];      // half sizes
  float light[3];  // direction to light in the local frame
  PrimitiveType type;
  bool visible;
};

bool ConeHitsSphere(const Cone& cone, float cx, float cy, float cz, float r) {
  const float d2 = cx * cx + cy * cy + cz * cz;
  if (d2 <= r * r) return true;
  const float d = std::sqrt(d2);
  const float sin_b = r / d;
  const float cos_b = std::sqrt(std::max(0.0f, 1.0f - sin_b * sin_b));
  const float cos_ac = (cone.ax * cx + cone.ay * cy + cone.az * cz) / d;
  // angle(axis, c) <= half + beta  <=>  cos_ac >= cos(half + beta) (both angles < pi here).
  const float cos_sum = cone.cos_half * cos_b - cone.sin_half * sin_b;
  if (cone.cos_half < 0 && cos_b < 0) return true;
  return cos_ac >= cos_sum;
}

Cone MakeCone(const std::vector<Eigen::Vector3f>& rays) {
  Cone cone;
  Eigen::Vector3f sum = Eigen::Vector3f::Zero();
  for (const auto& r : rays) sum += r;
  if (rays.empty() || sum.norm() < 1e-6f) return cone;
  const Eigen::Vector3f axis = sum.normalized();
  float cos_min = 1;
  for (const auto& r : rays) cos_min = std::min(cos_min, axis.dot(r));
  // Margin against float round-off in the per-frame tests.
  const float half = std::acos(std::clamp(cos_min, -1.0f, 1.0f)) + 2e-3f;
  cone.ax = axis.x();
  cone.ay = axis.y();
  cone.az = axis.z();
  cone.cos_half = std::cos(half);
  cone.sin_half = std::sin(half);
  cone.empty = false;
  return cone;
}

std::vector<Proxy> MakeProxies(const World& world) {
  std::vector<Proxy> proxies;
  const auto& prims = world.primitives();
  for (size_t i = 0; i < prims.size(); ++i) {
    const Primitive& p = prims[i];
    Eigen::Vector3d h = p.half_size;
    if (p.type == PrimitiveType::kRectangle) h.z() = 0;
    if (p.type == PrimitiveType::kCylinder) h.y() = h.x();
    Eigen::Vector3d sorted = h;
    std::sort(sorted.data(), sorted.data() + 3);
    const double max_piece = std::max(1.5, 2 * sorted[2] / 16);
    const double piece = std::clamp(2 * sorted[1], 0.5, max_piece);
    Eigen::Vector3i n;
    for (int k = 0; k < 3; ++k) n[k] = std::max(1, static_cast<int>(std::ceil(2 * h[k] / piece)));
    const Eigen::Vector3d step(2 * h.x() / n.x(), 2 * h.y() / n.y(), 2 * h.z() / n.z());
    const double radius = 0.5 * step.norm() + 1e-3;
    for (int a = 0; a < n.x(); ++a) {
      for (int b = 0; b < n.y(); ++b) {
        for (int c = 0; c < n.z(); ++c) {
          const Eigen::Vector3d local(-h.x() + (a + 0.5) * step.x(), -h.y() + (b + 0.5) * step.y(),
                                      -h.z() + (c + 0.5) * step.z());
          proxies.push_back({p.center + p.R_world_local * local, radius, static_cast<int>(i)});
        }
      }
    }
  }
  return proxies;
}

}  // namespace

struct CameraRenderer::Impl {
  std::shared_ptr<const World> world;
  camera::PinholeRadTan camera;
  int width = 0, height = 0;
  int tiles_x = 0, tiles_y = 0, supers_x = 0, supers_y = 0;
  // Ray LUT (camera frame, unit length; zero for pixels without a valid ray), SoA.
  std::vector<float> rx, ry, rz;
  std::vector<float> pixel_angle;  // angular size of each pixel (radians)
  std::vector<Cone> tile_cones, super_cones;
  std::vector<Proxy> proxies;
  std::vector<const Texture*> textures;  // per material

  void Render(const geometry::SE3& T_world_cam, float* radiance, float* range) const;

  // Intersects the rays of one tile with one primitive (kernel: local direction -> t) and keeps
  // the nearest hit per pixel. One primitive type per call keeps the pixel loop branch-light.
  template <typename Kernel>
  void IntersectTile(const PrimFrame& f, int prim, int u0, int u1, int v0, int v1, float* t_best,
                     int* id_best, Kernel kernel) const {
    const float* m = f.m;
    const int tw = u1 - u0;
    for (int v = v0; v < v1; ++v) {
      const size_t row = static_cast<size_t>(v) * width;
      const float* x = rx.data() + row;
      const float* y = ry.data() + row;
      const float* z = rz.data() + row;
      float* tb = t_best + (v - v0) * tw;
      int* ib = id_best + (v - v0) * tw;
      for (int u = u0; u < u1; ++u) {
        const float cx = x[u], cy = y[u], cz = z[u];
        const float t = kernel(m[0] * cx + m[1] * cy + m[2] * cz, m[3] * cx + m[4] * cy + m[5] * cz,
                               m[6] * cx + m[7] * cy + m[8] * cz);
        const int k = u - u0;
        if (t < tb[k]) {
          tb[k] = t;
          ib[k] = prim;
        }
      }
    }
  }
};

CameraRenderer::CameraRenderer(std::shared_ptr<const World> world,
                               const camera::PinholeRadTan& camera)
    : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  MAV_CHECK(world != nullptr);
  std::string why;
  MAV_CHECK(camera.IsValid(&why)) << why;
  s.world = std::move(world);
  s.camera = camera;
  s.width = camera.width;
  s.height = camera.height;
  const size_t n = static_cast<size_t>(s.width) * s.height;
  s.rx.assign(n, 0);
  s.ry.assign(n, 0);
  s.rz.assign(n, 0);
  s.pixel_angle.assign(n, static_cast<float>(1.0 / camera.fx));
  for (int v = 0; v < s.height; ++v) {
    for (int u = 0; u < s.width; ++u) {
      const std::optional<Eigen::Vector3d> ray = camera.Unproject(Eigen::Vector2d(u, v));
      if (!ray) continue;
      const size_t i = static_cast<size_t>(v) * s.width + u;
      const Eigen::Vector3d r = ray->normalized();
      s.rx[i] = static_cast<float>(r.x());
      s.ry[i] = static_cast<float>(r.y());
      s.rz[i] = static_cast<float>(r.z());
      const std::optional<Eigen::Vector3d> next = camera.Unproject(Eigen::Vector2d(u + 1, v));
      if (next) s.pixel_angle[i] = static_cast<float>((next->normalized() - r).norm());
    }
  }
  s.tiles_x = (s.width + kTile - 1) / kTile;
  s.tiles_y = (s.height + kTile - 1) / kTile;
  s.supers_x = (s.tiles_x + kSuper - 1) / kSuper;
  s.supers_y = (s.tiles_y + kSuper - 1) / kSuper;
  auto cone_of = [&](int u0, int v0, int size) {
    std::vector<Eigen::Vector3f> rays;
    for (int v = v0; v < std::min(v0 + size, s.height); ++v) {
      for (int u = u0; u < std::min(u0 + size, s.width); ++u) {
        const size_t i = static_cast<size_t>(v) * s.width + u;
        if (s.rx[i] == 0 && s.ry[i] == 0 && s.rz[i] == 0) continue;
        rays.emplace_back(s.rx[i], s.ry[i], s.rz[i]);
      }
    }
    return MakeCone(rays);
  };
  for (int ty = 0; ty < s.tiles_y; ++ty) {
    for (int tx = 0; tx < s.tiles_x; ++tx)
      s.tile_cones.push_back(cone_of(tx * kTile, ty * kTile, kTile));
  }
  for (int sy = 0; sy < s.supers_y; ++sy) {
    for (int sx = 0; sx < s.supers_x; ++sx) {
      s.super_cones.push_back(cone_of(sx * kTile * kSuper, sy * kTile * kSuper, kTile * kSuper));
    }
  }
  s.proxies = MakeProxies(*s.world);
  for (size_t m = 0; m < s.world->materials().size(); ++m) {
    const Texture* t = s.world->texture(static_cast<int>(m));
    MAV_CHECK(t != nullptr) << "World::BuildTextures() must be called before rendering";
    s.textures.push_back(t);
  }
}

CameraRenderer::~CameraRenderer() = default;
CameraRenderer::CameraRenderer(CameraRenderer&&) noexcept = default;
CameraRenderer& CameraRenderer::operator=(CameraRenderer&&) noexcept = default;

const camera::PinholeRadTan& CameraRenderer::camera() const { return impl_->camera; }
int CameraRenderer::width() const { return impl_->width; }
int CameraRenderer::height() const { return impl_->height; }

void CameraRenderer::RenderRadiance(const geometry::SE3& T_world_cam, std::vector<float>* radiance,
                                    std::vector<float>* range) const {
  MAV_CHECK(radiance != nullptr);
  const size_t n = static_cast<size_t>(impl_->width) * impl_->height;
  radiance->resize(n);
  if (range) range->resize(n);
  impl_->Render(T_world_cam, radiance->data(), range ? range->data() : nullptr);
}

void CameraRenderer::RenderIntegrated(const std::vector<geometry::SE3>& T_world_cam_samples,
                                      std::vector<float>* radiance) const {
  MAV_CHECK(radiance != nullptr && !T_world_cam_samples.empty());
  const size_t n = static_cast<size_t>(impl_->width) * impl_->height;
  if (T_world_cam_samples.size() == 1) {
    RenderRadiance(T_world_cam_samples[0], radiance);
    return;
  }
  radiance->assign(n, 0.0f);
  std::vector<float> sub(n);
  for (const geometry::SE3& T : T_world_cam_samples) {
    impl_->Render(T, sub.data(), nullptr);
    for (size_t i = 0; i < n; ++i) (*radiance)[i] += sub[i];
  }
  const float inv = 1.0f / static_cast<float>(T_world_cam_samples.size());
  for (float& v : *radiance) v *= inv;
}

void CameraRenderer::BlurByReprojection(const std::vector<float>& sharp,
                                        const std::vector<float>& range,
                                        const geometry::SE3& T_world_cam_mid,
                                        const geometry::SE3& T_world_cam_open,
                                        const geometry::SE3& T_world_cam_close, int max_samples,
                                        std::vector<float>* blurred) const {
  const Impl& s = *impl_;
  const int w = s.width, h = s.height;
  const size_t n = static_cast<size_t>(w) * h;
  MAV_CHECK(sharp.size() == n && range.size() == n && blurred != nullptr && max_samples >= 1);
  blurred->resize(n);
  const geometry::SE3 T_open_mid = T_world_cam_open.Inverse() * T_world_cam_mid;
  const geometry::SE3 T_close_mid = T_world_cam_close.Inverse() * T_world_cam_mid;
  float ro[9], to[3], rc[9], tc[3];
  {
    const Eigen::Matrix3d a = T_open_mid.RotationMatrix(), b = T_close_mid.RotationMatrix();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        ro[3 * r + c] = static_cast<float>(a(r, c));
        rc[3 * r + c] = static_cast<float>(b(r, c));
      }
      to[r] = static_cast<float>(T_open_mid.Translation()[r]);
      tc[r] = static_cast<float>(T_close_mid.Translation()[r]);
    }
  }
  const camera::PinholeRadTan& cam = s.camera;
  const float fx = static_cast<float>(cam.fx), fy = static_cast<float>(cam.fy);
  const float cx = static_cast<float>(cam.cx), cy = static_cast<float>(cam.cy);
  const float k1 = static_cast<float>(cam.k1), k2 = static_cast<float>(cam.k2);
  const float p1 = static_cast<float>(cam.p1), p2 = static_cast<float>(cam.p2);
  // Camera model in float (same equations as PinholeRadTan::Project).
  auto project = [&](float X, float Y, float Z, float* u, float* v) {
    const float x = X / Z, y = Y / Z;
    const float r2 = x * x + y * y;
    const float radial = 1.0f + k1 * r2 + k2 * r2 * r2;
    const float xd = x * radial + 2.0f * p1 * x * y + p2 * (r2 + 2.0f * x * x);
    const float yd = y * radial + p1 * (r2 + 2.0f * y * y) + 2.0f * p2 * x * y;
    *u = fx * xd + cx;
    *v = fy * yd + cy;
  };
  auto bilinear = [&](float u, float v) {
    u = std::clamp(u, 0.0f, static_cast<float>(w - 1));
    v = std::clamp(v, 0.0f, static_cast<float>(h - 1));
    const int iu = std::min(static_cast<int>(u), w - 2), iv = std::min(static_cast<int>(v), h - 2);
    const float au = u - static_cast<float>(iu), av = v - static_cast<float>(iv);
    const float* r0 = sharp.data() + static_cast<size_t>(iv) * w + iu;
    const float* r1 = r0 + w;
    const float top = r0[0] + au * (r0[1] - r0[0]);
    const float bottom = r1[0] + au * (r1[1] - r1[0]);
    return top + av * (bottom - top);
  };
  constexpr float kFar = 1e4f;  // sky: a point far away
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const size_t i = static_cast<size_t>(v) * w + u;
      float& out = (*blurred)[i];
      out = sharp[i];
      const float t = std::min(range[i], kFar);
      const float X = s.rx[i] * t, Y = s.ry[i] * t, Z = s.rz[i] * t;
      const float Xo = ro[0] * X + ro[1] * Y + ro[2] * Z + to[0];
      const float Yo = ro[3] * X + ro[4] * Y + ro[5] * Z + to[1];
      const float Zo = ro[6] * X + ro[7] * Y + ro[8] * Z + to[2];
      const float Xc = rc[0] * X + rc[1] * Y + rc[2] * Z + tc[0];
      const float Yc = rc[3] * X + rc[4] * Y + rc[5] * Z + tc[1];
      const float Zc = rc[6] * X + rc[7] * Y + rc[8] * Z + tc[2];
      if (!(Z > 1e-3f) || !(Zo > 1e-3f) || !(Zc > 1e-3f)) continue;
      // The mid-shutter projection is the pixel itself (its ray came from the same model).
      const float um = static_cast<float>(u), vm = static_cast<float>(v);
      float uo, vo, uc, vc;
      project(Xo, Yo, Zo, &uo, &vo);
      project(Xc, Yc, Zc, &uc, &vc);
      // At shutter time tau the pixel sees the point that sits at p - flow(tau) mid-shutter.
      const float ao = uo - um, bo = vo - vm, ac = uc - um, bc = vc - vm;
      const float du = ac - ao, dv = bc - bo;
      const float length = std::sqrt(du * du + dv * dv);
      if (length < 0.05f && std::abs(ao + ac) < 0.05f && std::abs(bo + bc) < 0.05f) continue;
      const int samples = std::clamp(static_cast<int>(length) + 1, 1, max_samples);
      float sum = 0;
      for (int k = 0; k < samples; ++k) {
        const float tau = (static_cast<float>(k) + 0.5f) / static_cast<float>(samples);
        const float fu = ao + tau * du, fv = bo + tau * dv;
        sum += bilinear(static_cast<float>(u) - fu, static_cast<float>(v) - fv);
      }
      out = sum / static_cast<float>(samples);
    }
  }
}

void CameraRenderer::Impl::Render(const geometry::SE3& T_world_cam, float* radiance,
                                  float* range) const {
  const auto& prims = world->primitives();
  const auto& materials = world->materials();
  const Lighting& lighting = world->lighting();
  const Eigen::Matrix3d R_wc = T_world_cam.RotationMatrix();
  const Eigen::Vector3d o_w = T_world_cam.Translation();

  std::vector<PrimFrame> frames(prims.size());
  for (size_t i = 0; i < prims.size(); ++i) {
    const Primitive& p = prims[i];
    PrimFrame& f = frames[i];
    const Eigen::Matrix3d R_lw = p.R_world_local.transpose();
    const Eigen::Vector3d o = R_lw * (o_w - p.center);
    const Eigen::Matrix3d m = R_lw * R_wc;
    const Eigen::Vector3d l = R_lw * lighting.direction_to_light;
    for (int k = 0; k < 3; ++k) {
      f.o[k] = static_cast<float>(o[k]);
      f.h[k] = static_cast<float>(p.half_size[k]);
      f.light[k] = static_cast<float>(l[k]);
      for (int j = 0; j < 3; ++j) f.m[3 * k + j] = static_cast<float>(m(k, j));
    }
    f.type = p.type;
  }
  // Proxy spheres in the camera frame.
  const Eigen::Matrix3d R_cw = R_wc.transpose();
  const size_t np = proxies.size();
  std::vector<float> pc(4 * np);
  for (size_t i = 0; i < np; ++i) {
    const Eigen::Vector3d c = R_cw * (proxies[i].center - o_w);
    pc[4 * i] = static_cast<float>(c.x());
    pc[4 * i + 1] = static_cast<float>(c.y());
    pc[4 * i + 2] = static_cast<float>(c.z());
    pc[4 * i + 3] = static_cast<float>(proxies[i].radius);
  }

  std::vector<int> super_list, tile_list;
  super_list.reserve(np);
  tile_list.reserve(prims.size());
  std::vector<int> stamp(prims.size(), -1);
  float t_best[kTile * kTile];
  int id_best[kTile * kTile];
  const float background = static_cast<float>(lighting.background);
  const float ambient = static_cast<float>(lighting.ambient);
  const float diffuse = static_cast<float>(lighting.diffuse);

  for (int sy = 0; sy < supers_y; ++sy) {
    for (int sx = 0; sx < supers_x; ++sx) {
      const Cone& sc = super_cones[sy * supers_x + sx];
      super_list.clear();
      if (!sc.empty) {
        for (size_t i = 0; i < np; ++i) {
          if (ConeHitsSphere(sc, pc[4 * i], pc[4 * i + 1], pc[4 * i + 2], pc[4 * i + 3])) {
            super_list.push_back(static_cast<int>(i));
          }
        }
      }
      for (int ty = sy * kSuper; ty < std::min((sy + 1) * kSuper, tiles_y); ++ty) {
        for (int tx = sx * kSuper; tx < std::min((sx + 1) * kSuper, tiles_x); ++tx) {
          const int tile_index = ty * tiles_x + tx;
          const Cone& tc = tile_cones[tile_index];
          tile_list.clear();
          if (!tc.empty) {
            for (int pi : super_list) {
              const int prim = proxies[pi].primitive;
              if (stamp[prim] == tile_index) continue;
              if (ConeHitsSphere(tc, pc[4 * pi], pc[4 * pi + 1], pc[4 * pi + 2], pc[4 * pi + 3])) {
                stamp[prim] = tile_index;
                tile_list.push_back(prim);
              }
            }
          }
          const int u0 = tx * kTile, v0 = ty * kTile;
          const int u1 = std::min(u0 + kTile, width), v1 = std::min(v0 + kTile, height);
          const int tw = u1 - u0;
          const int count = tw * (v1 - v0);
          for (int k = 0; k < count; ++k) {
            t_best[k] = std::numeric_limits<float>::infinity();
            id_best[k] = -1;
          }
          // Intersection: primitive-major so the inner loop is a coherent run over pixels.
          for (int prim : tile_list) {
            const PrimFrame& f = frames[prim];
            switch (f.type) {
              case PrimitiveType::kBox:
                IntersectTile(f, prim, u0, u1, v0, v1, t_best, id_best,
                              [&f](float dx, float dy, float dz) {
                                return internal::RayBoxLocal(f.o[0], f.o[1], f.o[2], dx, dy, dz,
                                                             f.h[0], f.h[1], f.h[2], kTMin);
                              });
                break;
              case PrimitiveType::kCylinder:
                IntersectTile(f, prim, u0, u1, v0, v1, t_best, id_best,
                              [&f](float dx, float dy, float dz) {
                                return internal::RayCylinderLocal(f.o[0], f.o[1], f.o[2], dx, dy,
                                                                  dz, f.h[0], f.h[2], kTMin);
                              });
                break;
              case PrimitiveType::kRectangle:
                IntersectTile(f, prim, u0, u1, v0, v1, t_best, id_best,
                              [&f](float dx, float dy, float dz) {
                                return internal::RayRectangleLocal(f.o[0], f.o[1], f.o[2], dx, dy,
                                                                   dz, f.h[0], f.h[1], kTMin);
                              });
                break;
            }
          }
          // Shading.
          for (int v = v0; v < v1; ++v) {
            for (int u = u0; u < u1; ++u) {
              const size_t i = static_cast<size_t>(v) * width + u;
              const int k = (v - v0) * tw + (u - u0);
              const int prim = id_best[k];
              if (range) range[i] = t_best[k];
              if (prim < 0) {
                radiance[i] = (rx[i] == 0 && ry[i] == 0 && rz[i] == 0) ? 0.0f : background;
                continue;
              }
              const PrimFrame& f = frames[prim];
              const Primitive& p = prims[prim];
              const float* m = f.m;
              const float cx = rx[i], cy = ry[i], cz = rz[i];
              const float dx = m[0] * cx + m[1] * cy + m[2] * cz;
              const float dy = m[3] * cx + m[4] * cy + m[5] * cz;
              const float dz = m[6] * cx + m[7] * cy + m[8] * cz;
              const float t = t_best[k];
              const float px = f.o[0] + t * dx, py = f.o[1] + t * dy, pz = f.o[2] + t * dz;
              float nx = 0, ny = 0, nz = 1, su = px, sv = py;
              if (f.type == PrimitiveType::kBox) {
                const float ax = std::abs(px) / std::max(f.h[0], 1e-9f);
                const float ay = std::abs(py) / std::max(f.h[1], 1e-9f);
                const float az = std::abs(pz) / std::max(f.h[2], 1e-9f);
                if (ax >= ay && ax >= az) {
                  nx = px > 0 ? 1.0f : -1.0f;
                  nz = 0;
                  su = py;
                  sv = pz;
                } else if (ay >= az) {
                  ny = py > 0 ? 1.0f : -1.0f;
                  nz = 0;
                  su = px;
                  sv = pz;
                } else {
                  nz = pz > 0 ? 1.0f : -1.0f;
                }
              } else if (f.type == PrimitiveType::kCylinder) {
                const float r = f.h[0];
                const float radial2 = px * px + py * py;
                if (std::abs(pz) >= f.h[2] * (1 - 1e-5f) && radial2 < r * r * (1 - 1e-4f)) {
                  nz = pz > 0 ? 1.0f : -1.0f;
                } else {
                  const float inv = 1.0f / std::sqrt(std::max(radial2, 1e-20f));
                  nx = px * inv;
                  ny = py * inv;
                  nz = 0;
                  su = std::atan2(py, px) * r;
                  sv = pz;
                }
              }
              const float cos_inc = std::abs(nx * dx + ny * dy + nz * dz);
              const float n_dot_l = nx * f.light[0] + ny * f.light[1] + nz * f.light[2];
              const float shade = ambient + diffuse * (0.5f + 0.5f * n_dot_l);
              const float footprint = t * pixel_angle[i] / std::max(cos_inc, 0.2f);
              const Material& mat = materials[p.material];
              const float albedo =
                  textures[p.material]->Sample(su + static_cast<float>(p.uv_offset.x()),
                                               sv + static_cast<float>(p.uv_offset.y()), footprint);
              radiance[i] = albedo * shade + mat.emission;
            }
          }
        }
      }
    }
  }
}

void FormImage(const std::vector<float>& radiance, int width, int height, double gain,
               double noise_sigma, uint64_t noise_key, cv::Mat* image) {
  MAV_CHECK(image != nullptr);
  MAV_CHECK(radiance.size() == static_cast<size_t>(width) * height);
  image->create(height, width, CV_8UC1);
  const float scale = static_cast<float>(255.0 * gain);
  // Irwin-Hall with four uniforms: variance 4/12, so scale by sqrt(3) for unit variance.
  const float noise_scale = static_cast<float>(noise_sigma * std::sqrt(3.0) / 65536.0);
  const uint64_t key = internal::Mix64(noise_key);
  for (int v = 0; v < height; ++v) {
    uint8_t* row = image->ptr<uint8_t>(v);
    for (int u = 0; u < width; ++u) {
      const size_t i = static_cast<size_t>(v) * width + u;
      float value = scale * radiance[i];
      if (noise_sigma > 0) {
        const uint64_t h = internal::Mix64(key ^ (i * 0x9e3779b97f4a7c15ULL));
        const float sum = static_cast<float>((h & 0xffff) + ((h >> 16) & 0xffff) +
                                             ((h >> 32) & 0xffff) + (h >> 48)) -
                          2.0f * 65536.0f;
        value += noise_scale * sum;
      }
      // Round half up after clamping (values are non-negative there).
      row[u] = static_cast<uint8_t>(static_cast<int>(std::clamp(value, 0.0f, 255.0f) + 0.5f));
    }
  }
}

}  // namespace mav::sim
