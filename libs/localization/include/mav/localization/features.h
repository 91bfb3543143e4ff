#pragma once
// Sparse features for stereo visual odometry, after Geiger, Ziegler, Stiller, "StereoScan: Dense
// 3d reconstruction in real-time", IEEE Intelligent Vehicles Symposium 2011, Section III-A.
//
// The image is filtered with two zero-mean 5x5 masks, a blob mask (centre 8, inner ring +1,
// outer ring -1) and a corner mask (2x2 quadrants of +-1 around a zero cross). Local maxima and
// minima of both responses (non-maximum suppression over (2n+1)x(2n+1)) above a threshold give
// four feature classes: blob-max, blob-min, corner-max, corner-min. Features are only ever
// compared within their class. Each feature carries a 32-byte descriptor: the horizontal and the
// vertical Sobel response at 16 sparse positions of the 11x11 window around it, compared with
// the sum of absolute differences (SAD, one SSE2 `psadbw` per 16 bytes).
//
// Pure C++ (no OpenCV in this header): images come in as ImageView.

#include <algorithm>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#ifdef __SSE2__
#include <emmintrin.h>
#endif

namespace mav::localization {

enum FeatureClass : int { kBlobMax = 0, kBlobMin = 1, kCornerMax = 2, kCornerMin = 3 };
inline constexpr int kNumFeatureClasses = 4;

// A non-owning view of an 8-bit grey image, row-major with `stride` bytes per row.
struct ImageView {
  const uint8_t* data = nullptr;
  int width = 0;
  int height = 0;
  int stride = 0;
};

// 16 horizontal-Sobel bytes followed by 16 vertical-Sobel bytes, each Sobel value mapped to
// clamp(s / 4 + 128, 0, 255). 16-byte aligned for SSE2 loads.
struct alignas(16) Descriptor {
  std::array<uint8_t, 32> bytes{};
};

// Sum of absolute differences of two descriptors (0 .. 8160). Inline: it is the inner loop of
// matching.
inline uint32_t DescriptorSad(const Descriptor& a, const Descriptor& b) {
#ifdef __SSE2__
  const __m128i a0 = _mm_load_si128(reinterpret_cast<const __m128i*>(a.bytes.data()));
  const __m128i a1 = _mm_load_si128(reinterpret_cast<const __m128i*>(a.bytes.data() + 16));
  const __m128i b0 = _mm_load_si128(reinterpret_cast<const __m128i*>(b.bytes.data()));
  const __m128i b1 = _mm_load_si128(reinterpret_cast<const __m128i*>(b.bytes.data() + 16));
  const __m128i s = _mm_add_epi64(_mm_sad_epu8(a0, b0), _mm_sad_epu8(a1, b1));
  return static_cast<uint32_t>(_mm_cvtsi128_si32(s) + _mm_cvtsi128_si32(_mm_srli_si128(s, 8)));
#else
  uint32_t sum = 0;
  for (int i = 0; i < 32; ++i)
    sum += a.bytes[i] > b.bytes[i] ? a.bytes[i] - b.bytes[i] : b.bytes[i] - a.bytes[i];
  return sum;
#endif
}

struct FeatureOptions {
  // Non-maximum suppression radius n: a feature is the extremum of its (2n+1)x(2n+1)
  // neighbourhood (in the detection image; among equal 8-neighbours the first in raster order).
  // StereoScan suggests n = 3; larger n gives fewer, more distinctive features and faster matching.
  int nms_radius = 4;
  // Minimum |response| of a feature, in units of the masks above applied to 8-bit intensities.
  int response_threshold = 50;
  // Detect on a 2x2-averaged half-resolution image (4x fewer pixels to filter); positions are
  // scaled back, descriptors always come from the full-resolution image.
  bool half_resolution = false;
  // Side of the square cells of the spatial index used for candidate look-up, pixels.
  int grid_cell_px = 16;
  // Run the filters' and the suppression's kernels with AVX2 when the CPU has it (else SSE2).
  // Integer arithmetic: the same features either way (features_test compares the two).
  bool use_avx2 = true;
  // With use_avx2: the suppression's kernels 32 pixels wide with AVX-512BW when the CPU has it.
  bool use_avx512 = true;
  // With use_avx512: the suppression's candidate positions compressed with AVX512-VBMI2 when
  // the CPU has it (no branch per candidate).
  bool use_vbmi2 = true;

  bool IsValid(std::string* why) const;
};

// Features of one image, stored per class and sorted by grid cell so that all features inside a
// rectangle are found by visiting the cells it overlaps. Also keeps the two Sobel images so that
// descriptors can be sampled at any pixel (sub-pixel refinement).
class FeatureSet {
 public:
  struct Class {
    std::vector<int16_t> u, v;            // pixel positions, sorted by cell
    std::vector<int16_t> strength;        // |filter response| (>= response_threshold)
    std::vector<Descriptor> descriptors;  // parallel to u, v
    std::vector<int32_t> cell_start;      // features of cell c: [cell_start[c], cell_start[c+1])
    // The same features in raster order (by v, then u): row_order[row_start[v] ..
    // row_start[v + 1]) are the indices of the features on row v, left to right.
    std::vector<int32_t> row_order;
    std::vector<int16_t> row_u;      // u[row_order[j]]
    std::vector<int32_t> row_start;  // height() + 1 entries
    int size() const { return static_cast<int>(u.size()); }
  };

  int width() const { return width_; }
  int height() const { return height_; }
  int grid_cell_px() const { return cell_; }
  int grid_cols() const { return cols_; }
  int grid_rows() const { return rows_; }
  const Class& features(int feature_class) const { return classes_[feature_class]; }
  int TotalFeatures() const;

  // Sobel responses, mapped to bytes as in Descriptor; width() x height(), row-major.
  const std::vector<uint8_t>& sobel_u() const { return sobel_u_; }
  const std::vector<uint8_t>& sobel_v() const { return sobel_v_; }
  // Descriptor at pixel (u, v); requires kDescriptorMargin <= u < width - kDescriptorMargin and
  // likewise for v.
  Descriptor DescriptorAt(int u, int v) const;
  // Features keep this distance from the image border (descriptor window + refinement step).
  static constexpr int kDescriptorMargin = 8;

  // A window [u0, u1] x [v0, v1] (inclusive) clipped to the image, and the grid cells it
  // overlaps: columns [cx0, cx1], rows [cy0, cy1]. `empty`: nothing of `c` can be inside.
  struct Window {
    int u0, u1, v0, v1;
    int cx0 = 0, cx1 = -1, cy0 = 0, cy1 = -1;
    bool empty = true;
  };
  Window ClipWindow(const Class& c, int u0, int u1, int v0, int v1) const {
    Window w{std::max(u0, 0), std::min(u1, width_ - 1), std::max(v0, 0), std::min(v1, height_ - 1)};
    w.empty = w.u0 > w.u1 || w.v0 > w.v1 || c.u.empty();
    if (!w.empty) {
      w.cx0 = w.u0 / cell_;
      w.cx1 = w.u1 / cell_;
      w.cy0 = w.v0 / cell_;
      w.cy1 = w.v1 / cell_;
    }
    return w;
  }
  // The features of the window's cells on cell row cy, [first, last) of the cell order: a row's
  // cells are contiguous in the sorted order, so the window's cells of a row are one range.
  int CellRowFirst(const Class& c, const Window& w, int cy) const {
    return c.cell_start[cy * cols_ + w.cx0];
  }
  int CellRowLast(const Class& c, const Window& w, int cy) const {
    return c.cell_start[cy * cols_ + w.cx1 + 1];
  }

  // Calls visit(i) for the index i of every feature of `c` (one of this set's classes) inside
  // the window [u0, u1] x [v0, v1] (inclusive, clipped to the image), cell row by cell row, in
  // increasing index: the one window search of the matchers (the VO's and the mapping's stereo
  // matching).
  template <typename Visit>
  void ForEachInWindow(const Class& c, int u0, int u1, int v0, int v1, Visit&& visit) const {
    const Window w = ClipWindow(c, u0, u1, v0, v1);
    for (int cy = w.cy0; cy <= w.cy1; ++cy) {
      ScanRange(c.u.data(), c.v.data(), c.size(), CellRowFirst(c, w, cy), CellRowLast(c, w, cy),
                w.u0, w.u1, w.v0, w.v1, [&](int i) { visit(i); });
    }
  }

  // ForEachInWindow for a window a few rows tall (a stereo search along the epipolar line):
  // visits exactly the window's features in raster order (row by row, left to right), scanning
  // only the features of its rows instead of every feature of the cells it overlaps (a 3-row
  // window in 16-pixel cells scans ~6 times more). The order is not ForEachInWindow's (by
  // index): a search keeping the first best must break ties by the lower index to find the same
  // feature.
  template <typename Visit>
  void ForEachInRows(const Class& c, int u0, int u1, int v0, int v1, Visit&& visit) const {
    if (c.row_start.size() != static_cast<size_t>(height_) + 1 || c.row_u.size() != c.u.size()) {
      ForEachInWindow(c, u0, u1, v0, v1, visit);  // a set not made by FeatureExtractor
      return;
    }
    u0 = std::max(u0, 0);
    v0 = std::max(v0, 0);
    u1 = std::min(u1, width_ - 1);
    v1 = std::min(v1, height_ - 1);
    if (u0 > u1 || v0 > v1) return;
    // The rows' features are one range of the raster order; only u needs testing.
    ScanRange(c.row_u.data(), nullptr, c.size(), c.row_start[v0], c.row_start[v1 + 1], u0, u1, v0,
              v1, [&](int j) { visit(c.row_order[j]); });
  }

 private:
  // Calls visit(i) for every i in [first, last) with u0 <= u[i] <= u1 and (unless v is null)
  // v0 <= v[i] <= v1, in increasing i. `size` is the arrays' length. Eight at a time with SSE2
  // compares: the bounds tests were branch mispredictions, a sixth of a VO frame.
  template <typename Visit>
  static void ScanRange(const int16_t* u, const int16_t* v, int size, int first, int last, int u0,
                        int u1, int v0, int v1, Visit&& visit) {
    int i = first;
#ifdef __SSE2__
    const __m128i lo_u = _mm_set1_epi16(static_cast<int16_t>(u0 - 1));
    const __m128i hi_u = _mm_set1_epi16(static_cast<int16_t>(u1 + 1));
    const __m128i lo_v = _mm_set1_epi16(static_cast<int16_t>(v0 - 1));
    const __m128i hi_v = _mm_set1_epi16(static_cast<int16_t>(v1 + 1));
    // The last block may read past `last` (not past `size`); its extra lanes are masked off.
    for (; i < last && i + 8 <= size; i += 8) {
      const __m128i vu = _mm_loadu_si128(reinterpret_cast<const __m128i*>(u + i));
      __m128i in = _mm_and_si128(_mm_cmpgt_epi16(vu, lo_u), _mm_cmplt_epi16(vu, hi_u));
      if (v != nullptr) {
        const __m128i vv = _mm_loadu_si128(reinterpret_cast<const __m128i*>(v + i));
        in = _mm_and_si128(in, _mm_and_si128(_mm_cmpgt_epi16(vv, lo_v), _mm_cmplt_epi16(vv, hi_v)));
      }
      unsigned mask = static_cast<unsigned>(_mm_movemask_epi8(in));
      if (last - i < 8) mask &= (1u << (2 * (last - i))) - 1;
      while (mask != 0) {
        const int lane = __builtin_ctz(mask) / 2;
        mask &= ~(3u << (2 * lane));
        visit(i + lane);
      }
    }
#endif
    for (; i < last; ++i) {
      if (u[i] < u0 || u[i] > u1) continue;
      if (v != nullptr && (v[i] < v0 || v[i] > v1)) continue;
      visit(i);
    }
  }

  friend class FeatureExtractor;
  int width_ = 0, height_ = 0, cell_ = 16, cols_ = 0, rows_ = 0;
  std::array<Class, kNumFeatureClasses> classes_;
  std::vector<uint8_t> sobel_u_, sobel_v_;
};

// Extracts features; owns scratch buffers so that repeated calls do not allocate.
class FeatureExtractor {
 public:
  explicit FeatureExtractor(const FeatureOptions& options);  // MAV_CHECKs options.IsValid
  // Fills *out (reusing its memory). Images smaller than 2 * kDescriptorMargin + 1 in either
  // direction yield no features.
  void Extract(const ImageView& image, FeatureSet* out);
  // Whether Extract runs the AVX2 kernels (options.use_avx2 and a CPU that has AVX2).
  bool UsesAvx2() const;
  // Whether the suppression runs its AVX-512BW kernels (options.use_avx512 too).
  bool UsesAvx512() const;
  // Whether the suppression compresses its candidates with AVX512-VBMI2 (options.use_vbmi2 too).
  bool UsesVbmi2() const;

 private:
  FeatureOptions options_;
  bool avx2_ = false;
  bool avx512_ = false;
  bool vbmi2_ = false;
  std::vector<uint8_t> half_;
  std::vector<int16_t> blob_, corner_, scratch_;
  std::vector<int32_t> order_;
  std::vector<int32_t> cell_col_, cell_row_;  // pixel -> grid cell column, row * columns
};

// Blob and corner filter responses of `image` (width x height int16, row-major); pixels within
// 2 of the border are 0. With use_avx2 and a CPU that has it, the AVX2 copy of the loops runs
// (the same output). Exposed for tests.
void ComputeFilterResponses(const ImageView& image, std::vector<int16_t>* blob,
                            std::vector<int16_t>* corner, std::vector<int16_t>* scratch,
                            bool use_avx2 = false);

}  // namespace mav::localization
