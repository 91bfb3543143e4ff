#pragma once
// Procedural, filtered surface textures.
//
// Every material owns one tileable texture image in metric surface coordinates (u, v) (metres
// along the surface), generated once, deterministically from a seed, with a full mip-map
// pyramid. The renderer samples it trilinearly with a footprint equal to the pixel's size on the
// surface (distance / focal length / cos(incidence)), so detail finer than a pixel is averaged
// away rather than aliased: the same surface point looks the same from poses 1 mm apart, and the
// textures do not shimmer from frame to frame (Williams, "Pyramidal parametrics", SIGGRAPH 1983).
//
// Patterns are band-limited by construction (value noise up-sampled with bicubic interpolation,
// smooth blobs, bricks with soft mortar, ...). "Poorly textured" surfaces are the same patterns
// with a small contrast.

#include <cstdint>
#include <cstring>
#include <memory>
#include <vector>

namespace mav::sim {

enum class TexturePattern : uint8_t {
  kUniform,  // constant albedo
  kNoise,    // multi-octave value noise (concrete, plaster)
  kBlobs,    // smooth dark/bright blobs on noise (posters, clutter)
  kBricks,   // bricks with mortar joints and per-brick shade
  kPlanks,   // wooden planks: bands with grain along v
  kSpeckle,  // fine speckle on coarse noise (gravel, painted metal)
  kChecker,  // black/white checkerboard with squares of checker_square_m, corners at u,v = k*square
};

struct Material {
  TexturePattern pattern = TexturePattern::kNoise;
  float albedo = 0.5f;            // mean reflectance in [0, 1]
  float contrast = 0.25f;         // standard deviation of the albedo pattern (0.02-0.04 = poor)
  float texel_size_m = 0.004f;    // metres per texel at the finest mip level (tile = 512 texels)
  float emission = 0.0f;          // radiance added independent of light (lamps, windows)
  float checker_square_m = 0.1f;  // kChecker only: square edge (texel size is derived from it)
};

class Texture {
 public:
  static constexpr int kSize = 512;  // texels per side at level 0 (power of two)

  // levels[l] holds (kSize >> l)^2 albedo values, row-major, v along rows.
  Texture(std::vector<std::vector<float>> levels, float texel_size_m);
  Texture(const Texture&) = delete;  // holds pointers into its own levels
  Texture& operator=(const Texture&) = delete;

  int num_levels() const { return static_cast<int>(levels_.size()); }
  float texel_size_m() const { return texel_size_m_; }
  const std::vector<float>& level(int l) const { return levels_[l]; }

  // Trilinear sample at metric (u, v) (wrapping) for a footprint of `footprint_m` metres.
  // Inline: this is the renderer's innermost call.
  float Sample(float u, float v, float footprint_m) const {
    const float texels = footprint_m * inv_texel_size_m_;
    if (!(texels > 1.0f)) return SampleLevel(0, u, v);
    const float level = FastLog2(texels);
    if (level >= static_cast<float>(last_level_)) return coarsest_;
    const int l0 = static_cast<int>(level);
    const float f = level - static_cast<float>(l0);
    const float a = SampleLevel(l0, u, v);
    const float b = SampleLevel(l0 + 1, u, v);
    return a + f * (b - a);
  }
  // Bilinear sample of one level.
  float SampleLevel(int l, float u, float v) const {
    const int size = kSize >> l;
    const int mask = size - 1;
    const float scale = level_scale_[l];
    const float x = u * scale - 0.5f;
    const float y = v * scale - 0.5f;
    const int ix = FloorToInt(x);
    const int iy = FloorToInt(y);
    const float ax = x - static_cast<float>(ix);
    const float ay = y - static_cast<float>(iy);
    const int x0 = ix & mask;
    const int x1 = (x0 + 1) & mask;
    const float* r0 = level_data_[l] + (iy & mask) * size;
    const float* r1 = level_data_[l] + ((iy + 1) & mask) * size;
    const float top = r0[x0] + ax * (r0[x1] - r0[x0]);
    const float bottom = r1[x0] + ax * (r1[x1] - r1[x0]);
    return top + ay * (bottom - top);
  }

 private:
  static constexpr int kMaxLevels = 10;  // 512 -> 1
  // floor() for |x| < 2^31 without a libm call (baseline x86-64 has no SSE4.1 roundss).
  static int FloorToInt(float x) {
    const int i = static_cast<int>(x);
    return i - (x < static_cast<float>(i));
  }
  // A cheap, continuous, monotonic stand-in for log2(x), x >= 1: the exponent plus the
  // mantissa's linear part. Exact at powers of two, so the trilinear blend between mip levels is
  // linear in the footprint instead of logarithmic (both are valid filters, neither aliases).
  static float FastLog2(float x) {
    uint32_t bits;
    std::memcpy(&bits, &x, sizeof(bits));
    const int exponent = static_cast<int>((bits >> 23) & 0xff) - 127;
    bits = (bits & 0x007fffffu) | 0x3f800000u;  // mantissa in [1, 2)
    float m;
    std::memcpy(&m, &bits, sizeof(m));
    return static_cast<float>(exponent) + (m - 1.0f);
  }

  std::vector<std::vector<float>> levels_;
  float texel_size_m_;
  float inv_texel_size_m_;
  int last_level_ = 0;
  float coarsest_ = 0;
  const float* level_data_[kMaxLevels] = {};
  float level_scale_[kMaxLevels] = {};
};

// Generates the texture pyramid of a material; deterministic for (material, seed).
std::shared_ptr<const Texture> GenerateTexture(const Material& material, uint64_t seed);

}  // namespace mav::sim
