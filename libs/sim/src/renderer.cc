#include "mav/sim/renderer.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <type_traits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define MAV_SIM_HAVE_AVX2 1
#endif

#include <opencv2/core.hpp>

#include "intersect.h"
#include "mav/common/check.h"
#include "random.h"

namespace mav::sim {
namespace {

constexpr int kTile = 16;       // pixels per tile side
constexpr int kSuper = 4;       // tiles per super-tile side (64 x 64 pixels)
constexpr float kTMin = 1e-3f;  // metres
constexpr int kTileRays = kTile * kTile;
constexpr float kInf = std::numeric_limits<float>::infinity();

// ---- 4-wide float SIMD (GCC/Clang vector extensions: SSE2 on x86-64, the baseline; any other
// target gets whatever the compiler makes of them) ----
typedef float F4 __attribute__((vector_size(16)));
typedef int32_t I4 __attribute__((vector_size(16)));

inline F4 Splat(float x) { return F4{x, x, x, x}; }
inline F4 Load4(const float* p) {
  F4 v;
  std::memcpy(&v, p, sizeof(v));
  return v;
}
inline void Store4(float* p, F4 v) { std::memcpy(p, &v, sizeof(v)); }
// Lane-wise select with a comparison mask (all bits set = a).
inline F4 Select(I4 mask, F4 a, F4 b) {
  // Vector casts reinterpret the bits (no conversion, no memory round trip).
  return (F4)(((I4)a & mask) | ((I4)b & ~mask));
}
// min/max returning the second operand when either is NaN (minps/maxps).
#if defined(__SSE2__)
inline F4 Min4(F4 a, F4 b) { return (F4)_mm_min_ps((__m128)a, (__m128)b); }
inline F4 Max4(F4 a, F4 b) { return (F4)_mm_max_ps((__m128)a, (__m128)b); }
#else
inline F4 Min4(F4 a, F4 b) { return Select(a < b, a, b); }
inline F4 Max4(F4 a, F4 b) { return Select(a > b, a, b); }
#endif
inline F4 Abs4(F4 a) { return (F4)((I4)a & I4{0x7fffffff, 0x7fffffff, 0x7fffffff, 0x7fffffff}); }
inline F4 Sqrt4(F4 a) {
#if defined(__SSE2__)
  return reinterpret_cast<F4>(_mm_sqrt_ps(reinterpret_cast<__m128>(a)));
#else
  return F4{std::sqrt(a[0]), std::sqrt(a[1]), std::sqrt(a[2]), std::sqrt(a[3])};
#endif
}
// Truncation toward zero (cvttps2dq); only used on values well inside the int range.
inline I4 TruncToInt4(F4 a) { return __builtin_convertvector(a, I4); }
inline F4 ToFloat4(I4 a) { return __builtin_convertvector(a, F4); }
inline bool All4(I4 m) {
#if defined(__SSE2__)
  return _mm_movemask_ps(reinterpret_cast<__m128>(m)) == 0xf;
#else
  return (m[0] & m[1] & m[2] & m[3]) != 0;
#endif
}
inline float HMax4(F4 a) { return std::max(std::max(a[0], a[1]), std::max(a[2], a[3])); }

// Bilinear blend of the quads of one level, 4 lanes (in texel units).
inline F4 LevelFetch4(const uint16_t* const q[4], F4 ax, F4 ay) {
#if defined(__SSE2__)
  const __m128i zero = _mm_setzero_si128();
  const __m128i a01 = _mm_unpacklo_epi64(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(q[0])),
                                         _mm_loadl_epi64(reinterpret_cast<const __m128i*>(q[1])));
  const __m128i a23 = _mm_unpacklo_epi64(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(q[2])),
                                         _mm_loadl_epi64(reinterpret_cast<const __m128i*>(q[3])));
  // One lane's quad per register, then transposed to one corner per register.
  __m128 k0 = _mm_cvtepi32_ps(_mm_unpacklo_epi16(a01, zero));
  __m128 k1 = _mm_cvtepi32_ps(_mm_unpackhi_epi16(a01, zero));
  __m128 k2 = _mm_cvtepi32_ps(_mm_unpacklo_epi16(a23, zero));
  __m128 k3 = _mm_cvtepi32_ps(_mm_unpackhi_epi16(a23, zero));
  _MM_TRANSPOSE4_PS(k0, k1, k2, k3);
  const F4 tl = reinterpret_cast<F4>(k0), tr = reinterpret_cast<F4>(k1);
  const F4 bl = reinterpret_cast<F4>(k2), br = reinterpret_cast<F4>(k3);
#else
  const F4 tl = ToFloat4(I4{q[0][0], q[1][0], q[2][0], q[3][0]});
  const F4 tr = ToFloat4(I4{q[0][1], q[1][1], q[2][1], q[3][1]});
  const F4 bl = ToFloat4(I4{q[0][2], q[1][2], q[2][2], q[3][2]});
  const F4 br = ToFloat4(I4{q[0][3], q[1][3], q[2][3], q[3][3]});
#endif
  const F4 top = tl + ax * (tr - tl);
  const F4 bottom = bl + ax * (br - bl);
  return top + ay * (bottom - top);
}

// Bilinear interpolation of a row-major image at 4 positions given by the offsets `idx` of the
// top-left texel and the fractions (ax, ay); rows are `stride` floats apart.
inline F4 Bilinear4(const float* img, const I4& idx, size_t stride, F4 ax, F4 ay) {
#if defined(__SSE2__)
  const float* p0 = img + idx[0];
  const float* p1 = img + idx[1];
  const float* p2 = img + idx[2];
  const float* p3 = img + idx[3];
  const __m128 z = _mm_setzero_ps();
  const __m128 t01 = _mm_loadh_pi(_mm_loadl_pi(z, reinterpret_cast<const __m64*>(p0)),
                                  reinterpret_cast<const __m64*>(p1));
  const __m128 t23 = _mm_loadh_pi(_mm_loadl_pi(z, reinterpret_cast<const __m64*>(p2)),
                                  reinterpret_cast<const __m64*>(p3));
  const __m128 b01 = _mm_loadh_pi(_mm_loadl_pi(z, reinterpret_cast<const __m64*>(p0 + stride)),
                                  reinterpret_cast<const __m64*>(p1 + stride));
  const __m128 b23 = _mm_loadh_pi(_mm_loadl_pi(z, reinterpret_cast<const __m64*>(p2 + stride)),
                                  reinterpret_cast<const __m64*>(p3 + stride));
  const F4 tl = reinterpret_cast<F4>(_mm_shuffle_ps(t01, t23, _MM_SHUFFLE(2, 0, 2, 0)));
  const F4 tr = reinterpret_cast<F4>(_mm_shuffle_ps(t01, t23, _MM_SHUFFLE(3, 1, 3, 1)));
  const F4 bl = reinterpret_cast<F4>(_mm_shuffle_ps(b01, b23, _MM_SHUFFLE(2, 0, 2, 0)));
  const F4 br = reinterpret_cast<F4>(_mm_shuffle_ps(b01, b23, _MM_SHUFFLE(3, 1, 3, 1)));
#else
  F4 tl, tr, bl, br;
  for (int j = 0; j < 4; ++j) {
    const float* q = img + idx[j];
    tl[j] = q[0];
    tr[j] = q[1];
    bl[j] = q[stride];
    br[j] = q[stride + 1];
  }
#endif
  const F4 top = tl + ax * (tr - tl);
  const F4 bottom = bl + ax * (br - bl);
  return top + ay * (bottom - top);
}

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
  float inv_h[3];  // 1 / max(h, 1e-9)
  float light[3];  // direction to light in the local frame
  float uv_offset[2];
  float emission;
  const Texture* texture;
  PrimitiveType type;
};

// Primitive candidates of one tile, nearest first: `near` bounds the hit distance of every tile
// ray on the primitive from below (the nearest point of its culling spheres that meet the tile).
struct Candidate {
  float near;
  int primitive;
};

// A culling sphere as seen from the camera (per frame): direction of its centre, the sine and
// cosine of its angular radius, the distance to its nearest point.
struct SphereView {
  float ux, uy, uz;
  float sin_b, cos_b;
  float near;
  bool contains_camera;
};

SphereView ViewSphere(float cx, float cy, float cz, float r) {
  SphereView s{};
  const float d2 = cx * cx + cy * cy + cz * cz;
  s.contains_camera = d2 <= r * r;
  if (s.contains_camera) return s;
  const float d = std::sqrt(d2);
  s.ux = cx / d;
  s.uy = cy / d;
  s.uz = cz / d;
  s.sin_b = r / d;
  s.cos_b = std::sqrt(std::max(0.0f, 1.0f - s.sin_b * s.sin_b));
  s.near = d - r;
  return s;
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

// What the tile loop needs of one frame (renderer_lanes.inc: RenderTiles).
struct RenderFrame {
  int width, height, tiles_x, tiles_y, supers_x, supers_y;
  const float *tile_rx, *tile_ry, *tile_rz, *tile_t0;  // CameraRenderer::Impl's
  const float* pixel_angle;
  const Cone *tile_cones, *super_cones;
  const Proxy* proxies;
  const SphereView* spheres;  // per proxy
  size_t num_spheres;
  const PrimFrame* frames;  // per primitive
  size_t num_prims;
  float background, ambient, diffuse;
  bool exact_atan2;  // CameraRenderer::SetExactCylinderAngles
};

#define MAV_SIM_INLINE inline __attribute__((always_inline))

// What the blur kernels need of one BlurByReprojection call (renderer_lanes.inc).
struct BlurFrame {
  const float* sharp;
  const float* range;
  const float *rx, *ry, *rz;  // the ray LUT
  size_t n;                   // pixels
  int w, h;
  float ro[9], to[3], rc[9], tc[3];  // open and close camera from the mid camera
  float fx, fy, cx, cy, k1, k2, p1, p2;
  int max_samples;
};
constexpr float kBlurMargin = 0.01f;  // pixels: keeps stepped sample positions inside

// The kernels 4 lanes wide (SSE2: the x86-64 baseline).
namespace lanes4 {
typedef F4 V;
typedef I4 VI;
constexpr int kLanes = 4;
MAV_SIM_INLINE V Splat(float x) { return ::mav::sim::Splat(x); }
MAV_SIM_INLINE V Load(const float* p) { return Load4(p); }
MAV_SIM_INLINE void Store(float* p, V v) { Store4(p, v); }
MAV_SIM_INLINE V Select(VI m, V a, V b) { return ::mav::sim::Select(m, a, b); }
MAV_SIM_INLINE V Min(V a, V b) { return Min4(a, b); }
MAV_SIM_INLINE V Max(V a, V b) { return Max4(a, b); }
MAV_SIM_INLINE V Abs(V a) { return Abs4(a); }
MAV_SIM_INLINE V Sqrt(V a) { return Sqrt4(a); }
MAV_SIM_INLINE VI Trunc(V a) { return TruncToInt4(a); }
MAV_SIM_INLINE V ToFloat(VI a) { return ToFloat4(a); }
MAV_SIM_INLINE bool All(VI m) { return All4(m); }
MAV_SIM_INLINE float HMax(V a) { return HMax4(a); }
MAV_SIM_INLINE V LaneIndex() { return V{0, 1, 2, 3}; }
MAV_SIM_INLINE int Mask(VI m) {  // bit j: lane j's mask set
#if defined(__SSE2__)
  return _mm_movemask_ps(reinterpret_cast<__m128>(m));
#else
  return (m[0] != 0) | (m[1] != 0) << 1 | (m[2] != 0) << 2 | (m[3] != 0) << 3;
#endif
}
MAV_SIM_INLINE V Bilinear(const float* img, const VI& idx, size_t stride, V ax, V ay) {
  return Bilinear4(img, idx, stride, ax, ay);
}
MAV_SIM_INLINE V LevelFetch(const uint16_t* const q[4], V ax, V ay) {
  return LevelFetch4(q, ax, ay);
}
#include "renderer_lanes.inc"

// Row v of the blur from pixel u on (u a multiple of 4): the rows of the 4-lane path, the row
// tails of the wider ones.
MAV_SIM_INLINE void BlurRowFrom(const BlurFrame& b, const BlurConsts& c, int v, int u, float* out) {
  const size_t row = static_cast<size_t>(v) * b.w;
  for (; u < b.w; u += 4) {
    const V r = BlurLanes(b, c, v, u);
    if (u + 4 <= b.w) {
      Store(out + row + u, r);
    } else {
      for (int j = 0; u + j < b.w; ++j) out[row + u + j] = r[j];
    }
  }
}

// Image formation of a row from pixel u on (u a multiple of 4), 4 pixels at a time.
MAV_SIM_INLINE void FormRowFrom(const FormConsts& f, const float* in, size_t row_start, int u,
                                int width, uint8_t* row) {
  for (; u < width; u += 4) {
    const size_t i = row_start + u;
    V r = Splat(0.0f);
    for (int j = 0; j < 4 && u + j < width; ++j) r[j] = in[i + j];
    const VI q = FormLanes(f, r, i);
    for (int j = 0; j < 4 && u + j < width; ++j) row[u + j] = static_cast<uint8_t>(q[j]);
  }
}
}  // namespace lanes4

#if defined(MAV_SIM_HAVE_AVX2)
// The kernels 8 lanes wide, AVX2 (no FMA: the same roundings as the 4 lanes), compiled for
// AVX2 here and run only where the CPU has it (CpuLanes).
#if defined(__clang__)
#pragma clang attribute push(__attribute__((target("avx2"))), apply_to = function)
#else
#pragma GCC push_options
#pragma GCC target("avx2")
#endif
namespace lanes8 {
typedef float V __attribute__((vector_size(32)));
typedef int32_t VI __attribute__((vector_size(32)));
constexpr int kLanes = 8;
MAV_SIM_INLINE V Splat(float x) { return V{x, x, x, x, x, x, x, x}; }
MAV_SIM_INLINE V Load(const float* p) {
  V v;
  std::memcpy(&v, p, sizeof(v));
  return v;
}
MAV_SIM_INLINE void Store(float* p, V v) { std::memcpy(p, &v, sizeof(v)); }
// m: comparison results (all bits set or clear per lane).
MAV_SIM_INLINE V Select(VI m, V a, V b) {
  return (V)_mm256_blendv_ps((__m256)b, (__m256)a, (__m256)m);
}
MAV_SIM_INLINE V Min(V a, V b) { return (V)_mm256_min_ps((__m256)a, (__m256)b); }
MAV_SIM_INLINE V Max(V a, V b) { return (V)_mm256_max_ps((__m256)a, (__m256)b); }
MAV_SIM_INLINE V Abs(V a) { return (V)((VI)a & 0x7fffffff); }
MAV_SIM_INLINE V Sqrt(V a) { return (V)_mm256_sqrt_ps((__m256)a); }
MAV_SIM_INLINE VI Trunc(V a) { return __builtin_convertvector(a, VI); }
MAV_SIM_INLINE V ToFloat(VI a) { return __builtin_convertvector(a, V); }
MAV_SIM_INLINE int Mask(VI m) { return _mm256_movemask_ps((__m256)m); }
MAV_SIM_INLINE bool All(VI m) { return Mask(m) == 0xff; }
MAV_SIM_INLINE float HMax(V a) {
  const __m128 m =
      _mm_max_ps(_mm256_castps256_ps128((__m256)a), _mm256_extractf128_ps((__m256)a, 1));
  return std::max(std::max(m[0], m[1]), std::max(m[2], m[3]));
}
MAV_SIM_INLINE V LaneIndex() { return V{0, 1, 2, 3, 4, 5, 6, 7}; }
MAV_SIM_INLINE V Bilinear(const float* img, const VI& idx, size_t stride, V ax, V ay) {
  V tl, tr, bl, br;
  const int i0 = idx[0];
  if (All(idx == i0 + VI{0, 1, 2, 3, 4, 5, 6, 7})) {  // 8 neighbours in a row: the common case
    const float* p = img + i0;
    tl = Load(p);
    tr = Load(p + 1);
    bl = Load(p + stride);
    br = Load(p + stride + 1);
  } else {
    const __m256i vi = (__m256i)idx;
    tl = (V)_mm256_i32gather_ps(img, vi, 4);
    tr = (V)_mm256_i32gather_ps(img + 1, vi, 4);
    bl = (V)_mm256_i32gather_ps(img + stride, vi, 4);
    br = (V)_mm256_i32gather_ps(img + stride + 1, vi, 4);
  }
  const V top = tl + ax * (tr - tl);
  const V bottom = bl + ax * (br - bl);
  return top + ay * (bottom - top);
}
// Bilinear blend of the quads of one level (LevelFetch4, two groups of 4 side by side).
MAV_SIM_INLINE V LevelFetch(const uint16_t* const q[8], V ax, V ay) {
  auto pair = [&](int j) {
    return _mm_unpacklo_epi64(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(q[j])),
                              _mm_loadl_epi64(reinterpret_cast<const __m128i*>(q[j + 1])));
  };
  // Lanes 0-3 in the low halves, 4-7 in the high ones; the unpacks and shuffles work per half.
  const __m256i a = _mm256_inserti128_si256(_mm256_castsi128_si256(pair(0)), pair(4), 1);
  const __m256i b = _mm256_inserti128_si256(_mm256_castsi128_si256(pair(2)), pair(6), 1);
  const __m256i zero = _mm256_setzero_si256();
  const __m256 k0 = _mm256_cvtepi32_ps(_mm256_unpacklo_epi16(a, zero));
  const __m256 k1 = _mm256_cvtepi32_ps(_mm256_unpackhi_epi16(a, zero));
  const __m256 k2 = _mm256_cvtepi32_ps(_mm256_unpacklo_epi16(b, zero));
  const __m256 k3 = _mm256_cvtepi32_ps(_mm256_unpackhi_epi16(b, zero));
  // One lane's quad per register, transposed to one corner per register.
  const __m256 t0 = _mm256_unpacklo_ps(k0, k1), t1 = _mm256_unpacklo_ps(k2, k3);
  const __m256 t2 = _mm256_unpackhi_ps(k0, k1), t3 = _mm256_unpackhi_ps(k2, k3);
  const V tl = (V)_mm256_shuffle_ps(t0, t1, _MM_SHUFFLE(1, 0, 1, 0));
  const V tr = (V)_mm256_shuffle_ps(t0, t1, _MM_SHUFFLE(3, 2, 3, 2));
  const V bl = (V)_mm256_shuffle_ps(t2, t3, _MM_SHUFFLE(1, 0, 1, 0));
  const V br = (V)_mm256_shuffle_ps(t2, t3, _MM_SHUFFLE(3, 2, 3, 2));
  const V top = tl + ax * (tr - tl);
  const V bottom = bl + ax * (br - bl);
  return top + ay * (bottom - top);
}
#include "renderer_lanes.inc"

// Pixels u .. u + 7 of row v: 8 lanes wherever the result is the 4-lane kernel's, which
// decides per group of 4 whether its segments stay inside the image.
MAV_SIM_INLINE V BlurLanesAs4(const BlurFrame& b, const BlurConsts& c, const lanes4::BlurConsts& c4,
                              int v, int u) {
  Segments s;
  if (!SegmentsOf(b, c, v, u, &s)) return s.sharp;
  // Inside over the 8 lanes' longest segment: inside over each 4's (their segments are parts).
  if (All(SegmentsInside(c, s, Splat(static_cast<float>(s.n_max - 1))))) {
    return IntegrateInside(b, c, s);
  }
  // Each 4's own decision; groups of 4 that are still take `sharp` either way.
  const __m128 lo = _mm256_castps256_ps128((__m256)s.count);
  const __m128 hi = _mm256_extractf128_ps((__m256)s.count, 1);
  const float last_lo = std::max(std::max(lo[0], lo[1]), std::max(lo[2], lo[3])) - 1;
  const float last_hi = std::max(std::max(hi[0], hi[1]), std::max(hi[2], hi[3])) - 1;
  const V last = V{last_lo, last_lo, last_lo, last_lo, last_hi, last_hi, last_hi, last_hi};
  const int inside = Mask(SegmentsInside(c, s, last)), still = Mask(s.still);
  const bool lo_inside = (still & 0x0f) != 0x0f && (inside & 0x0f) == 0x0f;
  const bool hi_inside = (still & 0xf0) != 0xf0 && (inside & 0xf0) == 0xf0;
  if (!lo_inside && !hi_inside) return IntegrateClamped(b, c, s);
  const lanes4::V a = lanes4::BlurLanes(b, c4, v, u), d = lanes4::BlurLanes(b, c4, v, u + 4);
  return V{a[0], a[1], a[2], a[3], d[0], d[1], d[2], d[3]};
}

void BlurRows(const BlurFrame& b, float* out) {
  const BlurConsts c = MakeBlurConsts(b);
  const lanes4::BlurConsts c4 = lanes4::MakeBlurConsts(b);
  for (int v = 0; v < b.h; ++v) {
    const size_t row = static_cast<size_t>(v) * b.w;
    int u = 0;
    for (; u + 8 <= b.w; u += 8) Store(out + row + u, BlurLanesAs4(b, c, c4, v, u));
    lanes4::BlurRowFrom(b, c4, v, u, out);
  }
  _mm256_zeroupper();
}

// FormImage, 32 pixels per step.
void FormRows(const float* in, int width, int height, const lanes4::FormConsts& f4,
              cv::Mat* image) {
  const FormConsts f{Splat(f4.scale[0]), Splat(f4.noise_scale[0]), f4.key_lo, f4.key_hi};
  for (int v = 0; v < height; ++v) {
    uint8_t* row = image->ptr<uint8_t>(v);
    const size_t row_start = static_cast<size_t>(v) * width;
    int u = 0;
    for (; u + 32 <= width; u += 32) {
      const size_t i = row_start + u;
      const VI q0 = FormLanes(f, Load(in + i), i), q1 = FormLanes(f, Load(in + i + 8), i + 8);
      const VI q2 = FormLanes(f, Load(in + i + 16), i + 16);
      const VI q3 = FormLanes(f, Load(in + i + 24), i + 24);
      // Values are in [0, 255]: saturating packs are exact. The packs work per 128-bit half;
      // the permutation puts the 4-pixel pieces back in order.
      const __m256i lo = _mm256_packs_epi32((__m256i)q0, (__m256i)q1);
      const __m256i hi = _mm256_packs_epi32((__m256i)q2, (__m256i)q3);
      const __m256i bytes = _mm256_permutevar8x32_epi32(_mm256_packus_epi16(lo, hi),
                                                        _mm256_setr_epi32(0, 4, 1, 5, 2, 6, 3, 7));
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(row + u), bytes);
    }
    lanes4::FormRowFrom(f4, in, row_start, u, width, row);
  }
  _mm256_zeroupper();
}
}  // namespace lanes8
#if defined(__clang__)
#pragma clang attribute pop
#else
#pragma GCC pop_options
#endif

// The kernels 16 lanes wide, AVX-512 (F and DQ; no FMA), run only where the CPU has it
// (CpuLanes). Where a blur group's segments leave the image, it is done as two groups of 8.
#if defined(__clang__)
#pragma clang attribute push(__attribute__((target("avx2,avx512f,avx512dq"))), apply_to = function)
#else
#pragma GCC push_options
#pragma GCC target("avx2,avx512f,avx512dq")
#endif
namespace lanes16 {
typedef float V __attribute__((vector_size(64)));
typedef int32_t VI __attribute__((vector_size(64)));
constexpr int kLanes = 16;
MAV_SIM_INLINE V Splat(float x) { return (V)_mm512_set1_ps(x); }
MAV_SIM_INLINE V Load(const float* p) {
  V v;
  std::memcpy(&v, p, sizeof(v));
  return v;
}
MAV_SIM_INLINE void Store(float* p, V v) { std::memcpy(p, &v, sizeof(v)); }
MAV_SIM_INLINE int Mask(VI m) { return _mm512_movepi32_mask((__m512i)m); }
// m: comparison results (all bits set or clear per lane).
MAV_SIM_INLINE V Select(VI m, V a, V b) {
  return (V)_mm512_mask_blend_ps(static_cast<__mmask16>(Mask(m)), (__m512)b, (__m512)a);
}
// vminps / vmaxps (the second operand when either is NaN, as minps), in the masked forms: GCC
// 12's unmasked ones pass an undefined operand that -Wmaybe-uninitialized reports (GCC bug
// 105593). The same for Sqrt and the gathers below.
MAV_SIM_INLINE V Min(V a, V b) {
  return (V)_mm512_mask_min_ps((__m512)a, 0xffff, (__m512)a, (__m512)b);
}
MAV_SIM_INLINE V Max(V a, V b) {
  return (V)_mm512_mask_max_ps((__m512)a, 0xffff, (__m512)a, (__m512)b);
}
MAV_SIM_INLINE V Abs(V a) { return (V)((VI)a & 0x7fffffff); }
MAV_SIM_INLINE V Sqrt(V a) { return (V)_mm512_mask_sqrt_ps((__m512)a, 0xffff, (__m512)a); }
MAV_SIM_INLINE VI Trunc(V a) { return __builtin_convertvector(a, VI); }
MAV_SIM_INLINE V ToFloat(VI a) { return __builtin_convertvector(a, V); }
MAV_SIM_INLINE bool All(VI m) { return Mask(m) == 0xffff; }
MAV_SIM_INLINE lanes8::V Low(V a) {
  lanes8::V r;
  std::memcpy(&r, &a, sizeof(r));
  return r;
}
MAV_SIM_INLINE lanes8::V High(V a) {
  lanes8::V r;
  std::memcpy(&r, reinterpret_cast<const char*>(&a) + sizeof(r), sizeof(r));
  return r;
}
MAV_SIM_INLINE float HMax(V a) { return lanes8::HMax(lanes8::Max(Low(a), High(a))); }
MAV_SIM_INLINE V LaneIndex() { return V{0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15}; }
MAV_SIM_INLINE V Join(lanes8::V lo, lanes8::V hi) {
  V r;
  std::memcpy(&r, &lo, sizeof(lo));
  std::memcpy(reinterpret_cast<char*>(&r) + sizeof(lo), &hi, sizeof(hi));
  return r;
}
MAV_SIM_INLINE V Bilinear(const float* img, const VI& idx, size_t stride, V ax, V ay) {
  V tl, tr, bl, br;
  const int i0 = idx[0];
  if (All(idx == i0 + VI{0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15})) {
    const float* p = img + i0;  // 16 neighbours in a row: the common case
    tl = Load(p);
    tr = Load(p + 1);
    bl = Load(p + stride);
    br = Load(p + stride + 1);
  } else {
    const __m512i vi = (__m512i)idx;
    const __m512 zero = _mm512_setzero_ps();
    tl = (V)_mm512_mask_i32gather_ps(zero, 0xffff, vi, img, 4);
    tr = (V)_mm512_mask_i32gather_ps(zero, 0xffff, vi, img + 1, 4);
    bl = (V)_mm512_mask_i32gather_ps(zero, 0xffff, vi, img + stride, 4);
    br = (V)_mm512_mask_i32gather_ps(zero, 0xffff, vi, img + stride + 1, 4);
  }
  const V top = tl + ax * (tr - tl);
  const V bottom = bl + ax * (br - bl);
  return top + ay * (bottom - top);
}
MAV_SIM_INLINE V LevelFetch(const uint16_t* const q[16], V ax, V ay) {
  return Join(lanes8::LevelFetch(q, Low(ax), Low(ay)),
              lanes8::LevelFetch(q + 8, High(ax), High(ay)));
}
#include "renderer_lanes.inc"

// Pixels u .. u + 15 of row v: 16 lanes where all segments stay inside the image, else as two
// groups of 8 (which decide as their groups of 4 do).
MAV_SIM_INLINE V BlurLanesAs4(const BlurFrame& b, const BlurConsts& c, const lanes8::BlurConsts& c8,
                              const lanes4::BlurConsts& c4, int v, int u) {
  Segments s;
  if (!SegmentsOf(b, c, v, u, &s)) return s.sharp;
  if (All(SegmentsInside(c, s, Splat(static_cast<float>(s.n_max - 1))))) {
    return IntegrateInside(b, c, s);
  }
  return Join(lanes8::BlurLanesAs4(b, c8, c4, v, u), lanes8::BlurLanesAs4(b, c8, c4, v, u + 8));
}

void BlurRows(const BlurFrame& b, float* out) {
  const BlurConsts c = MakeBlurConsts(b);
  const lanes8::BlurConsts c8 = lanes8::MakeBlurConsts(b);
  const lanes4::BlurConsts c4 = lanes4::MakeBlurConsts(b);
  for (int v = 0; v < b.h; ++v) {
    const size_t row = static_cast<size_t>(v) * b.w;
    int u = 0;
    for (; u + 16 <= b.w; u += 16) Store(out + row + u, BlurLanesAs4(b, c, c8, c4, v, u));
    for (; u + 8 <= b.w; u += 8)
      lanes8::Store(out + row + u, lanes8::BlurLanesAs4(b, c8, c4, v, u));
    lanes4::BlurRowFrom(b, c4, v, u, out);
  }
  _mm256_zeroupper();
}

// FormImage, 16 pixels per step (the values are bytes: vpmovdb's truncation is exact).
void FormRows(const float* in, int width, int height, const lanes4::FormConsts& f4,
              cv::Mat* image) {
  const FormConsts f{Splat(f4.scale[0]), Splat(f4.noise_scale[0]), f4.key_lo, f4.key_hi};
  for (int v = 0; v < height; ++v) {
    uint8_t* row = image->ptr<uint8_t>(v);
    const size_t row_start = static_cast<size_t>(v) * width;
    int u = 0;
    for (; u + 16 <= width; u += 16) {
      const size_t i = row_start + u;
      const VI q = FormLanes(f, Load(in + i), i);
      typedef int8_t Bytes __attribute__((vector_size(16)));
      const Bytes bytes = __builtin_convertvector(q, Bytes);
      std::memcpy(row + u, &bytes, sizeof(bytes));
    }
    lanes4::FormRowFrom(f4, in, row_start, u, width, row);
  }
  _mm256_zeroupper();
}
}  // namespace lanes16
#if defined(__clang__)
#pragma clang attribute pop
#else
#pragma GCC pop_options
#endif
#endif  // MAV_SIM_HAVE_AVX2

// The widest kernels this CPU runs: 16 (AVX-512 F and DQ), 8 (AVX2) or 4 lanes.
int CpuLanes() {
#if defined(MAV_SIM_HAVE_AVX2)
  static const int lanes = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq")
                               ? 16
                           : __builtin_cpu_supports("avx2") ? 8
                                                            : 4;
  return lanes;
#else
  return 4;
#endif
}

int ChooseLanes(int max_lanes) {
  const int cpu = CpuLanes();
  return max_lanes >= 16 ? cpu : max_lanes >= 8 ? std::min(cpu, 8) : 4;
}

}  // namespace

struct CameraRenderer::Impl {
  std::shared_ptr<const World> world;
  camera::PinholeRadTan camera;
  int width = 0, height = 0;
  int tiles_x = 0, tiles_y = 0, supers_x = 0, supers_y = 0;
  // Ray LUT (camera frame, unit length; zero for pixels without a valid ray), SoA.
  std::vector<float> rx, ry, rz;
  // The same in tile order (kTile^2 rays per tile, row-major inside the tile; zero rays pad
  // partial tiles), and the initial nearest-hit distance per tile pixel: +inf, or 0 for pixels
  // without a ray and padding (never hit).
  std::vector<float> tile_rx, tile_ry, tile_rz, tile_t0;
  std::vector<float> pixel_angle;  // angular size of each pixel (radians)
  std::vector<Cone> tile_cones, super_cones;
  std::vector<Proxy> proxies;
  std::vector<const Texture*> textures;  // per material
  int lanes = 4;                         // kernels: 4, 8 or 16 lanes (ChooseLanes)
  bool exact_atan2 = false;              // SetExactCylinderAngles

  void Render(const geometry::SE3& T_world_cam, float* radiance, float* range) const;
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
  s.lanes = CpuLanes();
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
  const size_t tile_rays = static_cast<size_t>(s.tiles_x) * s.tiles_y * kTile * kTile;
  s.tile_rx.assign(tile_rays, 0.0f);
  s.tile_ry.assign(tile_rays, 0.0f);
  s.tile_rz.assign(tile_rays, 0.0f);
  s.tile_t0.assign(tile_rays, 0.0f);
  for (int v = 0; v < s.height; ++v) {
    for (int u = 0; u < s.width; ++u) {
      const size_t i = static_cast<size_t>(v) * s.width + u;
      const size_t k = (static_cast<size_t>(v / kTile) * s.tiles_x + u / kTile) * kTile * kTile +
                       (v % kTile) * kTile + u % kTile;
      s.tile_rx[k] = s.rx[i];
      s.tile_ry[k] = s.ry[i];
      s.tile_rz[k] = s.rz[i];
      const bool valid = s.rx[i] != 0 || s.ry[i] != 0 || s.rz[i] != 0;
      s.tile_t0[k] = valid ? std::numeric_limits<float>::infinity() : 0.0f;
    }
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
void CameraRenderer::SetSimdLanes(int max_lanes) { impl_->lanes = ChooseLanes(max_lanes); }
int CameraRenderer::simd_lanes() const { return impl_->lanes; }
void CameraRenderer::SetExactCylinderAngles(bool exact) { impl_->exact_atan2 = exact; }
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
  MAV_CHECK(w >= 2 && h >= 2);
  blurred->resize(n);
  BlurFrame b;
  b.sharp = sharp.data();
  b.range = range.data();
  b.rx = s.rx.data();
  b.ry = s.ry.data();
  b.rz = s.rz.data();
  b.n = n;
  b.w = w;
  b.h = h;
  b.max_samples = max_samples;
  const geometry::SE3 T_open_mid = T_world_cam_open.Inverse() * T_world_cam_mid;
  const geometry::SE3 T_close_mid = T_world_cam_close.Inverse() * T_world_cam_mid;
  const Eigen::Matrix3d ro = T_open_mid.RotationMatrix(), rc = T_close_mid.RotationMatrix();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      b.ro[3 * r + c] = static_cast<float>(ro(r, c));
      b.rc[3 * r + c] = static_cast<float>(rc(r, c));
    }
    b.to[r] = static_cast<float>(T_open_mid.Translation()[r]);
    b.tc[r] = static_cast<float>(T_close_mid.Translation()[r]);
  }
  const camera::PinholeRadTan& cam = s.camera;
  b.fx = static_cast<float>(cam.fx);
  b.fy = static_cast<float>(cam.fy);
  b.cx = static_cast<float>(cam.cx);
  b.cy = static_cast<float>(cam.cy);
  b.k1 = static_cast<float>(cam.k1);
  b.k2 = static_cast<float>(cam.k2);
  b.p1 = static_cast<float>(cam.p1);
  b.p2 = static_cast<float>(cam.p2);
  float* out = blurred->data();
#if defined(MAV_SIM_HAVE_AVX2)
  if (s.lanes == 16) return lanes16::BlurRows(b, out);
  if (s.lanes == 8) return lanes8::BlurRows(b, out);
#endif
  const lanes4::BlurConsts c = lanes4::MakeBlurConsts(b);
  for (int v = 0; v < h; ++v) lanes4::BlurRowFrom(b, c, v, 0, out);
}

void CameraRenderer::Impl::Render(const geometry::SE3& T_world_cam, float* radiance,
                                  float* range) const {
  const auto& prims = world->primitives();
  const auto& materials = world->materials();
  const Lighting& lighting = world->lighting();
  const Eigen::Matrix3d R_wc = T_world_cam.RotationMatrix();
  const Eigen::Vector3d& o_w = T_world_cam.Translation();

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
      f.inv_h[k] = 1.0f / std::max(f.h[k], 1e-9f);
      f.light[k] = static_cast<float>(l[k]);
      for (int j = 0; j < 3; ++j) f.m[3 * k + j] = static_cast<float>(m(k, j));
    }
    f.uv_offset[0] = static_cast<float>(p.uv_offset.x());
    f.uv_offset[1] = static_cast<float>(p.uv_offset.y());
    f.emission = materials[p.material].emission;
    f.texture = textures[p.material];
    f.type = p.type;
  }
  // Proxy spheres in the camera frame.
  const Eigen::Matrix3d R_cw = R_wc.transpose();
  const size_t np = proxies.size();
  std::vector<SphereView> spheres(np);
  for (size_t i = 0; i < np; ++i) {
    const Eigen::Vector3d c = R_cw * (proxies[i].center - o_w);
    spheres[i] = ViewSphere(static_cast<float>(c.x()), static_cast<float>(c.y()),
                            static_cast<float>(c.z()), static_cast<float>(proxies[i].radius));
  }

  RenderFrame rf;
  rf.width = width;
  rf.height = height;
  rf.tiles_x = tiles_x;
  rf.tiles_y = tiles_y;
  rf.supers_x = supers_x;
  rf.supers_y = supers_y;
  rf.tile_rx = tile_rx.data();
  rf.tile_ry = tile_ry.data();
  rf.tile_rz = tile_rz.data();
  rf.tile_t0 = tile_t0.data();
  rf.pixel_angle = pixel_angle.data();
  rf.tile_cones = tile_cones.data();
  rf.super_cones = super_cones.data();
  rf.proxies = proxies.data();
  rf.spheres = spheres.data();
  rf.num_spheres = np;
  rf.frames = frames.data();
  rf.num_prims = frames.size();
  rf.background = static_cast<float>(lighting.background);
  rf.ambient = static_cast<float>(lighting.ambient);
  rf.diffuse = static_cast<float>(lighting.diffuse);
  rf.exact_atan2 = exact_atan2;
#if defined(MAV_SIM_HAVE_AVX2)
  // 8 lanes at most: with 16 (a whole tile row a group) fewer groups share a primitive and a
  // texture level, and the 16-lane tile loop is no faster (docs/benchmarks.md).
  if (lanes >= 8) return lanes8::RenderTiles(rf, radiance, range);
#endif
  lanes4::RenderTiles(rf, radiance, range);
}

void FormImage(const std::vector<float>& radiance, int width, int height, double gain,
               double noise_sigma, uint64_t noise_key, cv::Mat* image, int max_lanes) {
  MAV_CHECK(image != nullptr);
  MAV_CHECK(radiance.size() == static_cast<size_t>(width) * height);
  image->create(height, width, CV_8UC1);
  const float scale = static_cast<float>(255.0 * gain);
  // The sum of four uniform bytes has variance 4 (256^2 - 1) / 12 = 21845.
  const float noise_scale =
      noise_sigma > 0 ? static_cast<float>(noise_sigma / std::sqrt(21845.0)) : 0.0f;
  const uint64_t key = internal::Mix64(noise_key);
  const uint32_t key_lo = static_cast<uint32_t>(key), key_hi = static_cast<uint32_t>(key >> 32);
  const lanes4::FormConsts f4{Splat(scale), Splat(noise_scale), key_lo, key_hi};
  const float* in = radiance.data();
  const int lanes = ChooseLanes(max_lanes);
#if defined(MAV_SIM_HAVE_AVX2)
  if (lanes == 16) return lanes16::FormRows(in, width, height, f4, image);
  if (lanes == 8) return lanes8::FormRows(in, width, height, f4, image);
#endif
  (void)lanes;
  for (int v = 0; v < height; ++v) {
    uint8_t* row = image->ptr<uint8_t>(v);
    const size_t row_start = static_cast<size_t>(v) * width;
    int u = 0;
#if defined(__SSE2__)
    for (; u + 16 <= width; u += 16) {
      const size_t i = row_start + u;
      const I4 q0 = lanes4::FormLanes(f4, Load4(in + i), i);
      const I4 q1 = lanes4::FormLanes(f4, Load4(in + i + 4), i + 4);
      const I4 q2 = lanes4::FormLanes(f4, Load4(in + i + 8), i + 8);
      const I4 q3 = lanes4::FormLanes(f4, Load4(in + i + 12), i + 12);
      // Values are in [0, 255]: saturating packs are exact.
      const __m128i lo = _mm_packs_epi32((__m128i)q0, (__m128i)q1);
      const __m128i hi = _mm_packs_epi32((__m128i)q2, (__m128i)q3);
      _mm_storeu_si128(reinterpret_cast<__m128i*>(row + u), _mm_packus_epi16(lo, hi));
    }
#endif
    lanes4::FormRowFrom(f4, in, row_start, u, width, row);
  }
}

float internal::LaneAtan2(float y, float x) { return lanes4::Atan2(Splat(y), Splat(x))[0]; }

}  // namespace mav::sim
