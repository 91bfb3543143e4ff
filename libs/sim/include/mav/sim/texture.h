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
// Sampling reads the pyramid as 16-bit texels stored in "quads" (each texel with its right,
// lower and lower-right neighbours, 8 bytes, blocked by cache line), so one bilinear fetch is one
// load; the renderer is bound by these fetches.
//
// Patterns are band-limited by construction (value noise up-sampled with bicubic interpolation,
// smooth blobs, bricks with soft mortar, ...). "Poorly textured" surfaces are the same patterns
// with a small contrast.

#include <algorithm>
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

  // levels[l] holds (kSize >> l)^2 albedo values in [0, 1], row-major, v along rows. Sampling
  // uses them quantised to 16 bits (steps of 1.5e-5 albedo).
  Texture(std::vector<std::vector<float>> levels, float texel_size_m);
  Texture(const Texture&) = delete;  // holds pointers into its own levels
  Texture& operator=(const Texture&) = delete;

  int num_levels() const { return static_cast<int>(levels_.size()); }
  float texel_size_m() const { return texel_size_m_; }
  const std::vector<float>& level(int l) const { return levels_[l]; }

  // Trilinear sample at metric (u, v) (wrapping) for a footprint of `footprint_m` metres.
  // (The renderer uses a 4-wide equivalent built on the accessors below.)
  float Sample(float u, float v, float footprint_m) const {
    // Branch-free (the level varies from pixel to pixel, a branch would be unpredictable):
    // level clamped to [0, last_level_]; level 0 and the coarsest level come out as a plain
    // bilinear sample of that level (blend weight 0 or 1).
    const float texels = std::max(footprint_m * inv_texel_size_m_, 1.0f);
    const float level = std::min(FastLog2(texels), max_level_);
    const int l0 = std::min(static_cast<int>(level), top_pair_);
    const float f = level - static_cast<float>(l0);
    const float a = SampleLevel(l0, u, v);
    const float b = SampleLevel(l0 + 1, u, v);
    return a + f * (b - a);
  }
  // The filter's parameters, for vectorised samplers implementing the same filter as Sample():
  // the 16-bit texel quads (albedo = texel * kAlbedoPerTexel; layout below), metric scale
  // (texels per metre) and stored size per level l in [0, num_levels()] (index num_levels()
  // repeats the last level), the clamped level range.
  static constexpr float kAlbedoPerTexel = 1.0f / 65535.0f;
  const uint16_t* level_data(int l) const { return level_data_[l]; }
  float level_scale(int l) const { return level_scale_[l]; }
  int level_size(int l) const { return level_size_[l]; }
  float inv_texel_size_m() const { return inv_texel_size_m_; }
  float max_level() const { return max_level_; }
  int top_pair() const { return top_pair_; }

  // Bilinear sample of one level.
  float SampleLevel(int l, float u, float v) const {
    const int mask = level_size_[l] - 1;
    const float scale = level_scale_[l];
    const float x = u * scale - 0.5f;
    const float y = v * scale - 0.5f;
    const int ix = FloorToInt(x);
    const int iy = FloorToInt(y);
    const float ax = x - static_cast<float>(ix);
    const float ay = y - static_cast<float>(iy);
    const uint16_t* q =
        level_data_[l] + 4 * (BlockRow(iy & mask, level_size_[l]) + BlockColumn(ix & mask));
    const float a00 = q[0], a01 = q[1], a10 = q[2], a11 = q[3];
    const float top = a00 + ax * (a01 - a00);
    const float bottom = a10 + ax * (a11 - a10);
    return (top + ay * (bottom - top)) * kAlbedoPerTexel;
  }

  // Texel storage (4 MB per texture with the float levels): every texel (x, y) is stored as a
  // "quad" of four 16-bit values, the texels (x, y), (x + 1, y), (x, y + 1), (x + 1, y + 1)
  // (wrapping), so that a bilinear fetch is one 8-byte load. Quads are stored in blocks of kBlockW
  // x kBlockH (one 64-byte cache line), blocks row-major. Levels smaller than a block are stored
  // repeated (periodically) to one block side, and level_size() is the stored size. The quad of
  // texel (x, y) of a level with stored size s is quad number BlockRow(y, s) + BlockColumn(x).
  static constexpr int kBlockW = 4, kBlockH = 2;
  static int BlockColumn(int x) { return (x >> 2) * (kBlockW * kBlockH) + (x & 3); }
  static int BlockRow(int y, int size) { return (y >> 1) * (size * kBlockH) + (y & 1) * kBlockW; }

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
  int top_pair_ = 0;     // lower level of the coarsest blended pair
  float max_level_ = 0;  // last_level_ as float
  // The levels as quads of 16-bit texels (albedo / kAlbedoPerTexel, rounded), see BlockRow().
  std::vector<std::vector<uint16_t>> texels_;
  // Per level, plus one entry past the last that repeats it (read with blend weight 0).
  const uint16_t* level_data_[kMaxLevels + 1] = {};
  float level_scale_[kMaxLevels + 1] = {};
  int level_size_[kMaxLevels + 1] = {};
};

// Generates the texture pyramid of a material; deterministic for (material, seed).
std::shared_ptr<const Texture> GenerateTexture(const Material& material, uint64_t seed);

}  // namespace mav::sim
