#include "mav/localization/features.h"

#include <algorithm>
#include <cstring>
#include <sstream>

#include "mav/common/check.h"

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
// AVX2 kernels compiled beside the baseline (SSE2) ones and chosen at run time
// (FeatureOptions::use_avx2): integer max, min and compares, the same output either way.
#define MAV_FEATURES_AVX2 1
#define MAV_TARGET_AVX2 __attribute__((target("avx2")))
// The suppression's kernels also 32 lanes wide with AVX-512BW (FeatureOptions::use_avx512).
#define MAV_TARGET_AVX512 __attribute__((target("avx2,avx512f,avx512bw")))
// And the suppression's candidates compressed with AVX512-VBMI2 (FeatureOptions::use_vbmi2).
#define MAV_TARGET_VBMI2 __attribute__((target("avx2,avx512f,avx512bw,avx512vbmi2")))
#endif

namespace mav::localization {
namespace {

// Sparse sampling pattern of the 11x11 descriptor window (offsets du, dv), used for both Sobel
// images: symmetric, denser near the centre, reaching the window border at +-5.
constexpr int kPatternU[16] = {-1, 1, -3, 3, -5, -1, 1, 5, -5, -1, 1, 5, -3, 3, -1, 1};
constexpr int kPatternV[16] = {-5, -5, -3, -3, -1, -1, -1, -1, 1, 1, 1, 1, 3, 3, 5, 5};

inline uint8_t SobelToByte(int s) {
  return static_cast<uint8_t>(std::clamp((s >> 2) + 128, 0, 255));
}

// Grows the scratch buffer shared by the Sobel images, the filters and the suppression to at
// least n entries, never shrinking it: shrunk by the Sobel pass and grown again by the filters,
// it was zero-filled anew for every image (2 MB each, 1 % of a VO frame in memset).
inline int16_t* ScratchOf(std::vector<int16_t>* scratch, size_t n) {
  if (scratch->size() < n) scratch->resize(n);
  return scratch->data();
}

struct RawFeature {
  int16_t u, v, strength;  // strength = |response|
};

// Running maximum and minimum over [x - n, x + n] (row pass) for x in [x0, x1); the radius is a
// template parameter so the inner loop unrolls. 8 pixels at a time with SSE2's pmaxsw/pminsw
// on shifted unaligned loads: GCC vectorised the scalar loop with compare-and-blend sequences
// instead, and this pass was 16 % of a VO frame (docs/benchmarks.md, "Hot paths profiled").
template <int N>
void RunningExtremaN(const int16_t* __restrict in, int x0, int x1, int16_t* __restrict omax,
                     int16_t* __restrict omin) {
  int x = x0;
#ifdef __SSE2__
  for (; x + 8 <= x1; x += 8) {
    const __m128i c = _mm_loadu_si128(reinterpret_cast<const __m128i*>(in + x));
    __m128i a = c, b = c;
    for (int k = 1; k <= N; ++k) {
      const __m128i l = _mm_loadu_si128(reinterpret_cast<const __m128i*>(in + x - k));
      const __m128i r = _mm_loadu_si128(reinterpret_cast<const __m128i*>(in + x + k));
      a = _mm_max_epi16(a, _mm_max_epi16(l, r));
      b = _mm_min_epi16(b, _mm_min_epi16(l, r));
    }
    _mm_storeu_si128(reinterpret_cast<__m128i*>(omax + x), a);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(omin + x), b);
  }
#endif
  for (; x < x1; ++x) {
    int16_t a = in[x], b = in[x];
    for (int k = 1; k <= N; ++k) {
      a = std::max(a, std::max(in[x - k], in[x + k]));
      b = std::min(b, std::min(in[x - k], in[x + k]));
    }
    omax[x] = a;
    omin[x] = b;
  }
}

template <int N>
void RunningColumnExtremaN(const int16_t* __restrict imax, const int16_t* __restrict imin, int x0,
                           int x1, int stride, int16_t* __restrict omax, int16_t* __restrict omin) {
  int x = x0;
#ifdef __SSE2__
  auto load = [](const int16_t* p) { return _mm_loadu_si128(reinterpret_cast<const __m128i*>(p)); };
  for (; x + 8 <= x1; x += 8) {
    __m128i a = load(imax + x), b = load(imin + x);
    for (int k = 1; k <= N; ++k) {
      a = _mm_max_epi16(a, _mm_max_epi16(load(imax + x - k * stride), load(imax + x + k * stride)));
      b = _mm_min_epi16(b, _mm_min_epi16(load(imin + x - k * stride), load(imin + x + k * stride)));
    }
    _mm_storeu_si128(reinterpret_cast<__m128i*>(omax + x), a);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(omin + x), b);
  }
#endif
  for (; x < x1; ++x) {
    int16_t a = imax[x], b = imin[x];
    for (int k = 1; k <= N; ++k) {
      a = std::max(a, std::max(imax[x - k * stride], imax[x + k * stride]));
      b = std::min(b, std::min(imin[x - k * stride], imin[x + k * stride]));
    }
    omax[x] = a;
    omin[x] = b;
  }
}

#ifdef MAV_FEATURES_AVX2
MAV_TARGET_AVX2 inline __m256i Load16(const int16_t* p) {
  return _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p));
}

// The two passes 16 pixels at a time; the rest of the row with the SSE2 kernels.
template <int N>
MAV_TARGET_AVX2 void RunningExtremaAvx2N(const int16_t* __restrict in, int x0, int x1,
                                         int16_t* __restrict omax, int16_t* __restrict omin) {
  int x = x0;
  for (; x + 16 <= x1; x += 16) {
    const __m256i c = Load16(in + x);
    __m256i a = c, b = c;
    for (int k = 1; k <= N; ++k) {
      const __m256i l = Load16(in + x - k), r = Load16(in + x + k);
      a = _mm256_max_epi16(a, _mm256_max_epi16(l, r));
      b = _mm256_min_epi16(b, _mm256_min_epi16(l, r));
    }
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(omax + x), a);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(omin + x), b);
  }
  _mm256_zeroupper();  // GCC leaves it out before a tail call; legacy SSE would pay for it
  RunningExtremaN<N>(in, x, x1, omax, omin);
}

template <int N>
MAV_TARGET_AVX2 void RunningColumnExtremaAvx2N(const int16_t* __restrict imax,
                                               const int16_t* __restrict imin, int x0, int x1,
                                               int stride, int16_t* __restrict omax,
                                               int16_t* __restrict omin) {
  int x = x0;
  for (; x + 16 <= x1; x += 16) {
    __m256i a = Load16(imax + x), b = Load16(imin + x);
    for (int k = 1; k <= N; ++k) {
      a = _mm256_max_epi16(
          a, _mm256_max_epi16(Load16(imax + x - k * stride), Load16(imax + x + k * stride)));
      b = _mm256_min_epi16(
          b, _mm256_min_epi16(Load16(imin + x - k * stride), Load16(imin + x + k * stride)));
    }
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(omax + x), a);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(omin + x), b);
  }
  _mm256_zeroupper();
  RunningColumnExtremaN<N>(imax, imin, x, x1, stride, omax, omin);
}

MAV_TARGET_AVX512 inline __m512i Load32(const int16_t* p) { return _mm512_loadu_si512(p); }

// The two passes 32 pixels at a time; the rest of the row with the AVX2 kernels (VEX code: no
// transition penalty from the dirty upper halves, and they clear them before the SSE2 code).
template <int N>
MAV_TARGET_AVX512 void RunningExtremaAvx512N(const int16_t* __restrict in, int x0, int x1,
                                             int16_t* __restrict omax, int16_t* __restrict omin) {
  int x = x0;
  for (; x + 32 <= x1; x += 32) {
    const __m512i c = Load32(in + x);
    __m512i a = c, b = c;
    for (int k = 1; k <= N; ++k) {
      const __m512i l = Load32(in + x - k), r = Load32(in + x + k);
      a = _mm512_max_epi16(a, _mm512_max_epi16(l, r));
      b = _mm512_min_epi16(b, _mm512_min_epi16(l, r));
    }
    _mm512_storeu_si512(omax + x, a);
    _mm512_storeu_si512(omin + x, b);
  }
  RunningExtremaAvx2N<N>(in, x, x1, omax, omin);
}

template <int N>
MAV_TARGET_AVX512 void RunningColumnExtremaAvx512N(const int16_t* __restrict imax,
                                                   const int16_t* __restrict imin, int x0, int x1,
                                                   int stride, int16_t* __restrict omax,
                                                   int16_t* __restrict omin) {
  int x = x0;
  for (; x + 32 <= x1; x += 32) {
    __m512i a = Load32(imax + x), b = Load32(imin + x);
    for (int k = 1; k <= N; ++k) {
      a = _mm512_max_epi16(
          a, _mm512_max_epi16(Load32(imax + x - k * stride), Load32(imax + x + k * stride)));
      b = _mm512_min_epi16(
          b, _mm512_min_epi16(Load32(imin + x - k * stride), Load32(imin + x + k * stride)));
    }
    _mm512_storeu_si512(omax + x, a);
    _mm512_storeu_si512(omin + x, b);
  }
  RunningColumnExtremaAvx2N<N>(imax, imin, x, x1, stride, omax, omin);
}
#endif

// Which kernels run: the SSE2 ones, AVX2, AVX-512BW, or AVX-512BW with VBMI2's compression of
// the candidates (the callers checked the CPU).
enum class Isa { kSse2, kAvx2, kAvx512, kAvx512Vbmi2 };

// The row and the column pass for radius N with the kernels of `isa`.
template <int N>
struct RowPass {
  static void Run(Isa isa, const int16_t* in, int x0, int x1, int16_t* omax, int16_t* omin) {
#ifdef MAV_FEATURES_AVX2
    if (isa >= Isa::kAvx512) return RunningExtremaAvx512N<N>(in, x0, x1, omax, omin);
    if (isa == Isa::kAvx2) return RunningExtremaAvx2N<N>(in, x0, x1, omax, omin);
#endif
    (void)isa;
    RunningExtremaN<N>(in, x0, x1, omax, omin);
  }
};

template <int N>
struct ColumnPass {
  static void Run(Isa isa, const int16_t* imax, const int16_t* imin, int x0, int x1, int stride,
                  int16_t* omax, int16_t* omin) {
#ifdef MAV_FEATURES_AVX2
    if (isa >= Isa::kAvx512) {
      return RunningColumnExtremaAvx512N<N>(imax, imin, x0, x1, stride, omax, omin);
    }
    if (isa == Isa::kAvx2) {
      return RunningColumnExtremaAvx2N<N>(imax, imin, x0, x1, stride, omax, omin);
    }
#endif
    (void)isa;
    RunningColumnExtremaN<N>(imax, imin, x0, x1, stride, omax, omin);
  }
};

// Pass<n>::Run(args) for a run-time radius n in [1, 8]: a template parameter, so that the
// kernels' inner loops unroll.
template <template <int> class Pass, typename... Args>
void WithRadius(int n, Args... args) {
  switch (n) {
    case 1:
      return Pass<1>::Run(args...);
    case 2:
      return Pass<2>::Run(args...);
    case 3:
      return Pass<3>::Run(args...);
    case 4:
      return Pass<4>::Run(args...);
    case 5:
      return Pass<5>::Run(args...);
    case 6:
      return Pass<6>::Run(args...);
    case 7:
      return Pass<7>::Run(args...);
    default:
      return Pass<8>::Run(args...);
  }
}

void RunningExtrema(Isa isa, const int16_t* in, int x0, int x1, int n, int16_t* omax,
                    int16_t* omin) {
  WithRadius<RowPass>(n, isa, in, x0, x1, omax, omin);
}

void RunningColumnExtrema(Isa isa, const int16_t* imax, const int16_t* imin, int x0, int x1, int n,
                          int stride, int16_t* omax, int16_t* omin) {
  WithRadius<ColumnPass>(n, isa, imax, imin, x0, x1, stride, omax, omin);
}

// The pixels x in [x0, x1) of a row that equal the running maximum mx[x] at >= threshold or the
// running minimum mn[x] at <= -threshold, written to out in increasing x; returns how many.
int FindCandidatesSse2(const int16_t* row, const int16_t* mx, const int16_t* mn, int x0, int x1,
                       int threshold, int16_t* out) {
  int count = 0, x = x0;
  auto scalar = [&](int xx) {
    const int16_t val = row[xx];
    if ((val == mx[xx] && val >= threshold) || (val == mn[xx] && val <= -threshold)) {
      out[count++] = static_cast<int16_t>(xx);
    }
  };
#ifdef __SSE2__
  const __m128i tau_m1 = _mm_set1_epi16(static_cast<int16_t>(threshold - 1));
  const __m128i neg_tau_p1 = _mm_set1_epi16(static_cast<int16_t>(-threshold + 1));
  auto load = [](const int16_t* p) { return _mm_loadu_si128(reinterpret_cast<const __m128i*>(p)); };
  for (; x + 8 <= x1; x += 8) {
    const __m128i val = load(row + x);
    const __m128i is_max =
        _mm_and_si128(_mm_cmpeq_epi16(val, load(mx + x)), _mm_cmpgt_epi16(val, tau_m1));
    const __m128i is_min =
        _mm_and_si128(_mm_cmpeq_epi16(val, load(mn + x)), _mm_cmplt_epi16(val, neg_tau_p1));
    unsigned mask = static_cast<unsigned>(_mm_movemask_epi8(_mm_or_si128(is_max, is_min)));
    while (mask != 0) {
      const int lane = __builtin_ctz(mask) / 2;
      mask &= ~(3u << (2 * lane));
      out[count++] = static_cast<int16_t>(x + lane);
    }
  }
#endif
  for (; x < x1; ++x) scalar(x);
  return count;
}

#ifdef MAV_FEATURES_AVX2
MAV_TARGET_AVX2 int FindCandidatesAvx2(const int16_t* row, const int16_t* mx, const int16_t* mn,
                                       int x0, int x1, int threshold, int16_t* out) {
  const __m256i tau_m1 = _mm256_set1_epi16(static_cast<int16_t>(threshold - 1));
  const __m256i neg_tau_p1 = _mm256_set1_epi16(static_cast<int16_t>(-threshold + 1));
  int count = 0, x = x0;
  for (; x + 16 <= x1; x += 16) {
    const __m256i val = Load16(row + x);
    const __m256i is_max =
        _mm256_and_si256(_mm256_cmpeq_epi16(val, Load16(mx + x)), _mm256_cmpgt_epi16(val, tau_m1));
    const __m256i is_min = _mm256_and_si256(_mm256_cmpeq_epi16(val, Load16(mn + x)),
                                            _mm256_cmpgt_epi16(neg_tau_p1, val));
    unsigned mask = static_cast<unsigned>(_mm256_movemask_epi8(_mm256_or_si256(is_max, is_min)));
    while (mask != 0) {
      const int lane = __builtin_ctz(mask) / 2;
      mask &= ~(3u << (2 * lane));
      out[count++] = static_cast<int16_t>(x + lane);
    }
  }
  _mm256_zeroupper();  // before the SSE2 code of the rest
  return count + FindCandidatesSse2(row, mx, mn, x, x1, threshold, out + count);
}

// The candidates among the 32 pixels from x, as a bit mask: equal to the running maximum at
// >= threshold or to the running minimum at <= -threshold (the compares straight into masks).
MAV_TARGET_AVX512 inline __mmask32 Candidates32(const int16_t* row, const int16_t* mx,
                                                const int16_t* mn, int x, int threshold) {
  const __m512i tau_m1 = _mm512_set1_epi16(static_cast<int16_t>(threshold - 1));
  const __m512i neg_tau_p1 = _mm512_set1_epi16(static_cast<int16_t>(-threshold + 1));
  const __m512i val = Load32(row + x);
  const __mmask32 is_max =
      _mm512_cmpeq_epi16_mask(val, Load32(mx + x)) & _mm512_cmpgt_epi16_mask(val, tau_m1);
  const __mmask32 is_min =
      _mm512_cmpeq_epi16_mask(val, Load32(mn + x)) & _mm512_cmpgt_epi16_mask(neg_tau_p1, val);
  return is_max | is_min;
}

// 32 pixels at a time.
MAV_TARGET_AVX512 int FindCandidatesAvx512(const int16_t* row, const int16_t* mx, const int16_t* mn,
                                           int x0, int x1, int threshold, int16_t* out) {
  int count = 0, x = x0;
  for (; x + 32 <= x1; x += 32) {
    for (uint32_t mask = Candidates32(row, mx, mn, x, threshold); mask != 0; mask &= mask - 1) {
      out[count++] = static_cast<int16_t>(x + __builtin_ctz(mask));
    }
  }
  return count + FindCandidatesAvx2(row, mx, mn, x, x1, threshold, out + count);
}

// FindCandidatesAvx512 without a branch per candidate (the loop over the mask's bits
// mispredicted its exit on every block): a block's candidate positions are compressed into the
// first lanes (vpcompressw) and stored as one vector of 32, of which the first popcount(mask)
// count. `out` must have room for 32 entries past the last candidate.
MAV_TARGET_VBMI2 int FindCandidatesVbmi2(const int16_t* row, const int16_t* mx, const int16_t* mn,
                                         int x0, int x1, int threshold, int16_t* out) {
  alignas(64) static constexpr int16_t kLanes[32] = {0,  1,  2,  3,  4,  5,  6,  7,  8,  9,  10,
                                                     11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21,
                                                     22, 23, 24, 25, 26, 27, 28, 29, 30, 31};
  const __m512i lanes = _mm512_load_si512(kLanes);
  int count = 0, x = x0;
  for (; x + 32 <= x1; x += 32) {
    const __mmask32 mask = Candidates32(row, mx, mn, x, threshold);
    const __m512i positions = _mm512_add_epi16(lanes, _mm512_set1_epi16(static_cast<int16_t>(x)));
    _mm512_storeu_si512(out + count, _mm512_maskz_compress_epi16(mask, positions));
    count += __builtin_popcount(mask);
  }
  return count + FindCandidatesAvx2(row, mx, mn, x, x1, threshold, out + count);
}
#endif

int FindCandidates(Isa isa, const int16_t* row, const int16_t* mx, const int16_t* mn, int x0,
                   int x1, int threshold, int16_t* out) {
#ifdef MAV_FEATURES_AVX2
  if (isa == Isa::kAvx512Vbmi2) return FindCandidatesVbmi2(row, mx, mn, x0, x1, threshold, out);
  if (isa == Isa::kAvx512) return FindCandidatesAvx512(row, mx, mn, x0, x1, threshold, out);
  if (isa == Isa::kAvx2) return FindCandidatesAvx2(row, mx, mn, x0, x1, threshold, out);
#endif
  (void)isa;
  return FindCandidatesSse2(row, mx, mn, x0, x1, threshold, out);
}

// Non-maximum suppression by grey-level dilation: the (2n+1)x(2n+1) running maximum and minimum
// are computed separably (rows, then columns; 32, 16 or 8 pixels at a time with AVX-512, AVX2
// or SSE2);
// a pixel is a maximum (minimum) feature when it equals the running maximum (minimum) and passes
// the threshold. Plateaus are broken by keeping only the first pixel in raster order among equal
// 8-neighbours.
void SuppressNonExtrema(Isa isa, const int16_t* r, int w, int h, int lo_x, int hi_x, int lo_y,
                        int hi_y, int n, int threshold, int scale, std::vector<int16_t>* scratch,
                        std::vector<RawFeature>* maxima, std::vector<RawFeature>* minima) {
  // Rows [lo_y - n, hi_y + n) and columns [lo_x - n, hi_x + n) must hold valid responses.
  const int y0 = std::max(lo_y - n, 2), y1 = std::min(hi_y + n, h - 2);
  // Columns: the row pass reads x - n .. x + n, which must stay inside the row.
  const int x0 = std::max(lo_x, std::max(2, n)), x1 = std::min(hi_x, w - 2 - n);
  if (x0 >= x1 || lo_y >= hi_y) return;
  // Row extrema (two images), column extrema (two rows), the candidates of a row (at most w,
  // plus the 32 a vector store of FindCandidatesVbmi2 may write past the last).
  int16_t* rmax = ScratchOf(scratch, static_cast<size_t>(2) * w * h + 3 * w + 32);
  int16_t* rmin = rmax + static_cast<size_t>(w) * h;
  int16_t* cmax = rmin + static_cast<size_t>(w) * h;
  int16_t* cmin = cmax + w;
  int16_t* candidates = cmin + w;
  for (int y = y0; y < y1; ++y) {
    RunningExtrema(isa, r + static_cast<size_t>(y) * w, x0, x1, n,
                   rmax + static_cast<size_t>(y) * w, rmin + static_cast<size_t>(y) * w);
  }
  for (int y = lo_y; y < hi_y; ++y) {
    if (y - n >= y0 && y + n < y1) {
      // Column pass: the same kernel with a stride of one row, centred on row y.
      RunningColumnExtrema(isa, rmax + static_cast<size_t>(y) * w,
                           rmin + static_cast<size_t>(y) * w, x0, x1, n, w, cmax, cmin);
    } else {
      const int ya = std::max(y - n, y0), yb = std::min(y + n, y1 - 1);
      for (int x = x0; x < x1; ++x) {
        int16_t a = rmax[static_cast<size_t>(ya) * w + x],
                b = rmin[static_cast<size_t>(ya) * w + x];
        for (int yy = ya + 1; yy <= yb; ++yy) {
          a = std::max(a, rmax[static_cast<size_t>(yy) * w + x]);
          b = std::min(b, rmin[static_cast<size_t>(yy) * w + x]);
        }
        cmax[x] = a;
        cmin[x] = b;
      }
    }
    // The pixels equal to the running maximum or minimum past the threshold (vector compares),
    // then the plateau test on those few: an equal neighbour earlier in raster order wins.
    const int16_t* row = r + static_cast<size_t>(y) * w;
    const int count = FindCandidates(isa, row, cmax, cmin, x0, x1, threshold, candidates);
    for (int c = 0; c < count; ++c) {
      const int x = candidates[c];
      const int16_t val = row[x];
      if (row[x - 1] == val || row[x - w - 1] == val || row[x - w] == val ||
          row[x - w + 1] == val) {
        continue;
      }
      if (val == cmax[x] && val >= threshold) {
        maxima->push_back({static_cast<int16_t>(x * scale), static_cast<int16_t>(y * scale), val});
      } else {
        minima->push_back({static_cast<int16_t>(x * scale), static_cast<int16_t>(y * scale),
                           static_cast<int16_t>(-val)});
      }
    }
  }
}

// The horizontal and vertical 3x3 Sobel responses of `image`, as bytes (Descriptor's mapping),
// 128 on the one-pixel border.
void ComputeSobelBytes(const ImageView& image, std::vector<uint8_t>* sobel_u,
                       std::vector<uint8_t>* sobel_v, std::vector<int16_t>* scratch) {
  const int w = image.width, h = image.height;
  const size_t n = static_cast<size_t>(w) * h;
  sobel_u->resize(n);
  sobel_v->resize(n);
  for (std::vector<uint8_t>* sb : {sobel_u, sobel_v}) {
    std::fill(sb->begin(), sb->begin() + w, 128);
    std::fill(sb->end() - w, sb->end(), 128);
    for (int y = 1; y < h - 1; ++y)
      (*sb)[static_cast<size_t>(y) * w] = (*sb)[static_cast<size_t>(y) * w + w - 1] = 128;
  }
  int16_t* const rows = ScratchOf(scratch, 2 * static_cast<size_t>(w));
  for (int y = 1; y < h - 1; ++y) {
    const uint8_t* __restrict p0 = image.data + static_cast<size_t>(y - 1) * image.stride;
    const uint8_t* __restrict p1 = p0 + image.stride;
    const uint8_t* __restrict p2 = p1 + image.stride;
    int16_t* __restrict vs = rows;    // vertical [1 2 1] smoothing
    int16_t* __restrict hd = vs + w;  // vertical [-1 0 1] difference
    for (int x = 0; x < w; ++x) {
      vs[x] = static_cast<int16_t>(p0[x] + 2 * p1[x] + p2[x]);
      hd[x] = static_cast<int16_t>(p2[x] - p0[x]);
    }
    uint8_t* __restrict su = sobel_u->data() + y * w;
    uint8_t* __restrict sv = sobel_v->data() + y * w;
    int x = 1;
#ifdef __SSE2__
    // SobelToByte is an arithmetic shift and packus's saturation to [0, 255].
    const __m128i bias = _mm_set1_epi16(128);
    auto load = [](const int16_t* p) {
      return _mm_loadu_si128(reinterpret_cast<const __m128i*>(p));
    };
    for (; x + 16 <= w - 1; x += 16) {
      __m128i bytes_u[2], bytes_v[2];
      for (int half = 0; half < 2; ++half) {
        const int xx = x + 8 * half;
        const __m128i gu = _mm_sub_epi16(load(vs + xx + 1), load(vs + xx - 1));
        const __m128i mid = load(hd + xx);
        const __m128i gv = _mm_add_epi16(_mm_add_epi16(load(hd + xx - 1), load(hd + xx + 1)),
                                         _mm_add_epi16(mid, mid));
        bytes_u[half] = _mm_add_epi16(_mm_srai_epi16(gu, 2), bias);
        bytes_v[half] = _mm_add_epi16(_mm_srai_epi16(gv, 2), bias);
      }
      _mm_storeu_si128(reinterpret_cast<__m128i*>(su + x),
                       _mm_packus_epi16(bytes_u[0], bytes_u[1]));
      _mm_storeu_si128(reinterpret_cast<__m128i*>(sv + x),
                       _mm_packus_epi16(bytes_v[0], bytes_v[1]));
    }
#endif
    for (; x < w - 1; ++x) {
      const int gu = vs[x + 1] - vs[x - 1];
      const int gv = hd[x - 1] + 2 * hd[x] + hd[x + 1];
      su[x] = SobelToByte(gu);
      sv[x] = SobelToByte(gv);
    }
  }
}

}  // namespace

bool FeatureOptions::IsValid(std::string* why) const {
  std::ostringstream msg;
  if (nms_radius < 1 || nms_radius > 8) {
    msg << "nms_radius: must be in [1, 8], got " << nms_radius;
  } else if (response_threshold < 0) {
    msg << "response_threshold: must be >= 0, got " << response_threshold;
  } else if (grid_cell_px < 4 || grid_cell_px > 256) {
    msg << "grid_cell_px: must be in [4, 256], got " << grid_cell_px;
  } else {
    return true;
  }
  if (why) *why = msg.str();
  return false;
}

int FeatureSet::TotalFeatures() const {
  int n = 0;
  for (const auto& c : classes_) n += c.size();
  return n;
}

Descriptor FeatureSet::DescriptorAt(int u, int v) const {
  MAV_CHECK(u >= kDescriptorMargin - 2 && u < width_ - kDescriptorMargin + 2 &&
            v >= kDescriptorMargin - 2 && v < height_ - kDescriptorMargin + 2)
      << "descriptor at (" << u << ", " << v << ") outside " << width_ << "x" << height_;
  Descriptor d;
  const uint8_t* su = sobel_u_.data() + v * width_ + u;
  const uint8_t* sv = sobel_v_.data() + v * width_ + u;
  for (int i = 0; i < 16; ++i) {
    const int off = kPatternV[i] * width_ + kPatternU[i];
    d.bytes[i] = su[off];
    d.bytes[16 + i] = sv[off];
  }
  return d;
}

namespace {

// The body of ComputeFilterResponses, inlined into a baseline and an AVX2 copy: its loops are
// plain int16 arithmetic that GCC vectorises for whichever target the copy has.
__attribute__((always_inline)) inline void FilterResponses(const ImageView& image,
                                                           std::vector<int16_t>* blob,
                                                           std::vector<int16_t>* corner,
                                                           std::vector<int16_t>* scratch) {
  const int w = image.width, h = image.height;
  const size_t n = static_cast<size_t>(w) * h;
  if (w < 5 || h < 5) {
    blob->assign(n, 0);
    corner->assign(n, 0);
    return;
  }
  blob->resize(n);
  corner->resize(n);
  // Only the 2-pixel border needs clearing; the rest is overwritten below.
  for (std::vector<int16_t>* r : {blob, corner}) {
    std::fill(r->begin(), r->begin() + 2 * w, 0);
    std::fill(r->end() - 2 * w, r->end(), 0);
    for (int y = 2; y < h - 2; ++y) {
      int16_t* row = r->data() + static_cast<size_t>(y) * w;
      row[0] = row[1] = row[w - 2] = row[w - 1] = 0;
    }
  }
  // Horizontal running sums of width 2, 3 and 5 (int16: at most 5 * 255).
  int16_t* h2 = ScratchOf(scratch, 3 * n);
  int16_t* h3 = h2 + n;
  int16_t* h5 = h3 + n;
  for (int y = 0; y < h; ++y) {
    const uint8_t* __restrict in = image.data + static_cast<size_t>(y) * image.stride;
    int16_t* __restrict r2 = h2 + y * w;
    int16_t* __restrict r3 = h3 + y * w;
    int16_t* __restrict r5 = h5 + y * w;
    for (int x = 0; x < w - 1; ++x) r2[x] = static_cast<int16_t>(in[x] + in[x + 1]);
    for (int x = 2; x < w - 2; ++x) {
      const int16_t a = in[x - 2], b = in[x - 1], c = in[x], d = in[x + 1], e = in[x + 2];
      r3[x] = static_cast<int16_t>(b + c + d);
      r5[x] = static_cast<int16_t>(a + b + c + d + e);
    }
  }
  // blob = 8 c + (inner ring) - (outer ring) = -S5 + 2 S3 + 7 c.
  // corner = -TL + TR + BL - BR with 2x2 quadrants at offsets -2 and +1 from the centre.
  for (int y = 2; y < h - 2; ++y) {
    const uint8_t* __restrict in = image.data + static_cast<size_t>(y) * image.stride;
    const int16_t* __restrict a5 = h5 + (y - 2) * w;
    const int16_t* __restrict b5 = h5 + (y - 1) * w;
    const int16_t* __restrict c5 = h5 + y * w;
    const int16_t* __restrict d5 = h5 + (y + 1) * w;
    const int16_t* __restrict e5 = h5 + (y + 2) * w;
    const int16_t* __restrict b3 = h3 + (y - 1) * w;
    const int16_t* __restrict c3 = h3 + y * w;
    const int16_t* __restrict d3 = h3 + (y + 1) * w;
    const int16_t* __restrict t0 = h2 + (y - 2) * w;
    const int16_t* __restrict t1 = h2 + (y - 1) * w;
    const int16_t* __restrict u0 = h2 + (y + 1) * w;
    const int16_t* __restrict u1 = h2 + (y + 2) * w;
    int16_t* __restrict ob = blob->data() + y * w;
    int16_t* __restrict oc = corner->data() + y * w;
    // Two loops with int16 arithmetic (no overflow: |blob| <= 6375, |corner| <= 2040) so the
    // compiler vectorises each.
    for (int x = 2; x < w - 2; ++x) {
      const int16_t s5 = static_cast<int16_t>(a5[x] + b5[x] + c5[x] + d5[x] + e5[x]);
      const int16_t s3 = static_cast<int16_t>(b3[x] + c3[x] + d3[x]);
      const int16_t c = in[x];
      ob[x] = static_cast<int16_t>(2 * s3 - s5 + 7 * c);
    }
    for (int x = 2; x < w - 2; ++x) {
      const int16_t tl = static_cast<int16_t>(t0[x - 2] + t1[x - 2]);
      const int16_t tr = static_cast<int16_t>(t0[x + 1] + t1[x + 1]);
      const int16_t bl = static_cast<int16_t>(u0[x - 2] + u1[x - 2]);
      const int16_t br = static_cast<int16_t>(u0[x + 1] + u1[x + 1]);
      oc[x] = static_cast<int16_t>(tr + bl - tl - br);
    }
  }
}

#ifdef MAV_FEATURES_AVX2
MAV_TARGET_AVX2 void FilterResponsesAvx2(const ImageView& image, std::vector<int16_t>* blob,
                                         std::vector<int16_t>* corner,
                                         std::vector<int16_t>* scratch) {
  FilterResponses(image, blob, corner, scratch);
}
#endif

bool CpuHasAvx2() {
#ifdef MAV_FEATURES_AVX2
  return __builtin_cpu_supports("avx2");
#else
  return false;
#endif
}

bool CpuHasAvx512Bw() {
#ifdef MAV_FEATURES_AVX2
  return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw");
#else
  return false;
#endif
}

// The descriptors of the n features at (u[i], v[i]) (every one keeps kDescriptorMargin), out
// of the Sobel images (width w).
void GatherDescriptors(const uint8_t* sobel_u, const uint8_t* sobel_v, int w, const int16_t* u,
                       const int16_t* v, int n, Descriptor* out) {
  int offsets[16];
  for (int j = 0; j < 16; ++j) offsets[j] = kPatternV[j] * w + kPatternU[j];
  for (int i = 0; i < n; ++i) {
    const uint8_t* su = sobel_u + v[i] * w + u[i];
    const uint8_t* sv = sobel_v + v[i] * w + u[i];
    uint8_t* d = out[i].bytes.data();
    for (int j = 0; j < 16; ++j) {
      d[j] = su[offsets[j]];
      d[16 + j] = sv[offsets[j]];
    }
  }
}

#ifdef MAV_FEATURES_AVX2
// The pattern's rows, and per row the in-lane shuffle that moves the row's samples from the 16
// bytes at u - 8 .. u + 7 to their places in the descriptor (0x80: zero).
constexpr int kPatternRows[6] = {-5, -3, -1, 1, 3, 5};
struct PatternShuffles {
  alignas(32) int8_t control[6][32];
};
constexpr PatternShuffles MakePatternShuffles() {
  PatternShuffles s{};
  for (int r = 0; r < 6; ++r) {
    for (int j = 0; j < 32; ++j) {
      const int k = j % 16;
      s.control[r][j] = kPatternV[k] == kPatternRows[r] ? static_cast<int8_t>(kPatternU[k] + 8)
                                                        : static_cast<int8_t>(-128);
    }
  }
  return s;
}
constexpr PatternShuffles kPatternShuffles = MakePatternShuffles();
static_assert(FeatureSet::kDescriptorMargin >= 8, "the rows are loaded from u - 8");

// GatherDescriptors with six row loads per Sobel image instead of 32 byte loads: each row of
// the pattern is loaded once (the horizontal image in the low lane, the vertical in the high
// lane), shuffled into place and merged.
MAV_TARGET_AVX2 void GatherDescriptorsAvx2(const uint8_t* sobel_u, const uint8_t* sobel_v, int w,
                                           const int16_t* u, const int16_t* v, int n,
                                           Descriptor* out) {
  __m256i control[6];
  for (int r = 0; r < 6; ++r) {
    control[r] = _mm256_load_si256(reinterpret_cast<const __m256i*>(kPatternShuffles.control[r]));
  }
  for (int i = 0; i < n; ++i) {
    const ptrdiff_t at = static_cast<ptrdiff_t>(v[i]) * w + u[i] - 8;
    __m256i d = _mm256_setzero_si256();
    for (int r = 0; r < 6; ++r) {
      const ptrdiff_t row = at + static_cast<ptrdiff_t>(kPatternRows[r]) * w;
      const __m256i both = _mm256_loadu2_m128i(reinterpret_cast<const __m128i*>(sobel_v + row),
                                               reinterpret_cast<const __m128i*>(sobel_u + row));
      d = _mm256_or_si256(d, _mm256_shuffle_epi8(both, control[r]));
    }
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out[i].bytes.data()), d);
  }
}
#endif

}  // namespace

void ComputeFilterResponses(const ImageView& image, std::vector<int16_t>* blob,
                            std::vector<int16_t>* corner, std::vector<int16_t>* scratch,
                            bool use_avx2) {
#ifdef MAV_FEATURES_AVX2
  if (use_avx2 && CpuHasAvx2()) return FilterResponsesAvx2(image, blob, corner, scratch);
#endif
  (void)use_avx2;
  FilterResponses(image, blob, corner, scratch);
}

FeatureExtractor::FeatureExtractor(const FeatureOptions& options) : options_(options) {
  std::string why;
  MAV_CHECK(options_.IsValid(&why)) << why;
#ifdef MAV_FEATURES_AVX2
  avx2_ = options_.use_avx2 && CpuHasAvx2();
  avx512_ = avx2_ && options_.use_avx512 && CpuHasAvx512Bw();
  vbmi2_ = avx512_ && options_.use_vbmi2 && __builtin_cpu_supports("avx512vbmi2");
#endif
}

bool FeatureExtractor::UsesAvx2() const { return avx2_; }
bool FeatureExtractor::UsesAvx512() const { return avx512_; }
bool FeatureExtractor::UsesVbmi2() const { return vbmi2_; }

void FeatureExtractor::Extract(const ImageView& image, FeatureSet* out) {
  const int w = image.width, h = image.height;
  out->width_ = w;
  out->height_ = h;
  out->cell_ = options_.grid_cell_px;
  out->cols_ = (w + out->cell_ - 1) / out->cell_;
  out->rows_ = (h + out->cell_ - 1) / out->cell_;
  // The per-feature arrays are resized to their new counts below and every entry written: not
  // cleared here, so that a set reused from frame to frame is not zero-filled first.
  for (auto& c : out->classes_) {
    c.cell_start.assign(static_cast<size_t>(out->cols_) * out->rows_ + 1, 0);
    c.row_start.assign(static_cast<size_t>(std::max(h, 0)) + 1, 0);
  }
  const int m = FeatureSet::kDescriptorMargin;
  if (w < 2 * m + 1 || h < 2 * m + 1 || image.data == nullptr) {
    for (auto& c : out->classes_) {
      c.u.clear();
      c.v.clear();
      c.strength.clear();
      c.descriptors.clear();
      c.row_order.clear();
      c.row_u.clear();
    }
    out->sobel_u_.assign(static_cast<size_t>(std::max(w, 0)) * std::max(h, 0), 128);
    out->sobel_v_ = out->sobel_u_;
    return;
  }

  // Sobel images (full resolution) for the descriptors.
  ComputeSobelBytes(image, &out->sobel_u_, &out->sobel_v_, &scratch_);

  // Filter responses on the detection image.
  ImageView det = image;
  int scale = 1;
  if (options_.half_resolution) {
    const int hw = w / 2, hh = h / 2;
    half_.resize(static_cast<size_t>(hw) * hh);
    for (int y = 0; y < hh; ++y) {
      const uint8_t* __restrict r0 = image.data + static_cast<size_t>(2 * y) * image.stride;
      const uint8_t* __restrict r1 = r0 + image.stride;
      uint8_t* __restrict o = half_.data() + y * hw;
      for (int x = 0; x < hw; ++x) {
        o[x] =
            static_cast<uint8_t>((r0[2 * x] + r0[2 * x + 1] + r1[2 * x] + r1[2 * x + 1] + 2) >> 2);
      }
    }
    det = ImageView{half_.data(), hw, hh, hw};
    scale = 2;
  }
  ComputeFilterResponses(det, &blob_, &corner_, &scratch_, avx2_);

  // Candidate range in detection pixels such that full-resolution positions keep the margin.
  const int lo = (m + scale - 1) / scale;
  const int hi_x = (w - m - 1) / scale + 1;  // exclusive
  const int hi_y = (h - m - 1) / scale + 1;
  std::array<std::vector<RawFeature>, kNumFeatureClasses> raw;
  for (auto& r : raw) r.reserve(4096);
  const Isa isa = vbmi2_    ? Isa::kAvx512Vbmi2
                  : avx512_ ? Isa::kAvx512
                  : avx2_   ? Isa::kAvx2
                            : Isa::kSse2;
  SuppressNonExtrema(isa, blob_.data(), det.width, det.height, lo, hi_x, lo, hi_y,
                     options_.nms_radius, options_.response_threshold, scale, &scratch_,
                     &raw[kBlobMax], &raw[kBlobMin]);
  SuppressNonExtrema(isa, corner_.data(), det.width, det.height, lo, hi_x, lo, hi_y,
                     options_.nms_radius, options_.response_threshold, scale, &scratch_,
                     &raw[kCornerMax], &raw[kCornerMin]);

  // Counting sort by grid cell, then descriptors in sorted order. The cell of a pixel from
  // tables (the cell size is not a constant: no divisions per feature).
  const int cell = out->cell_, cols = out->cols_;
  cell_col_.resize(w);
  cell_row_.resize(h);
  for (int x = 0; x < w; ++x) cell_col_[x] = x / cell;
  for (int y = 0; y < h; ++y) cell_row_[y] = (y / cell) * cols;
  for (int k = 0; k < kNumFeatureClasses; ++k) {
    FeatureSet::Class& c = out->classes_[k];
    const std::vector<RawFeature>& r = raw[k];
    std::vector<int32_t>& start = c.cell_start;
    auto cell_of = [&](const RawFeature& f) { return cell_row_[f.v] + cell_col_[f.u]; };
    for (const RawFeature& f : r) ++start[cell_of(f) + 1];
    for (size_t i = 1; i < start.size(); ++i) start[i] += start[i - 1];
    order_.resize(r.size());  // every entry written below
    std::vector<int32_t> fill(start.begin(), start.end() - 1);
    for (size_t i = 0; i < r.size(); ++i) order_[fill[cell_of(r[i])]++] = static_cast<int32_t>(i);
    // The suppression emits in raster order: raw feature j is the j-th by (v, u).
    c.row_order.resize(r.size());
    c.row_u.resize(r.size());
    for (size_t i = 0; i < r.size(); ++i) {
      c.row_order[order_[i]] = static_cast<int32_t>(i);
      c.row_u[order_[i]] = r[order_[i]].u;
    }
    for (const RawFeature& f : r) ++c.row_start[f.v + 1];
    for (size_t v = 1; v < c.row_start.size(); ++v) c.row_start[v] += c.row_start[v - 1];
    c.u.resize(r.size());
    c.v.resize(r.size());
    c.strength.resize(r.size());
    c.descriptors.resize(r.size());
    for (size_t i = 0; i < r.size(); ++i) {
      const RawFeature& f = r[order_[i]];
      c.u[i] = f.u;
      c.v[i] = f.v;
      c.strength[i] = f.strength;
    }
#ifdef MAV_FEATURES_AVX2
    if (avx2_) {
      GatherDescriptorsAvx2(out->sobel_u_.data(), out->sobel_v_.data(), w, c.u.data(), c.v.data(),
                            c.size(), c.descriptors.data());
      continue;
    }
#endif
    GatherDescriptors(out->sobel_u_.data(), out->sobel_v_.data(), w, c.u.data(), c.v.data(),
                      c.size(), c.descriptors.data());
  }
}

}  // namespace mav::localization
