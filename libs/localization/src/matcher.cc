#include "mav/localization/matcher.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include <Eigen/Core>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
// The square window searches with AVX-512 (F, BW, VL, DQ), chosen at run time.
#define MAV_MATCHER_AVX512 1
#define MAV_TARGET_AVX512 __attribute__((target("avx2,avx512f,avx512bw,avx512vl,avx512dq")))
#endif

namespace mav::localization {
namespace {

struct Best {
  int index = -1;
  uint32_t cost = std::numeric_limits<uint32_t>::max();
};

// The match of a (SAD << 32 | index) key; none for ~0.
Best BestOfKey(uint64_t key) {
  if (key == std::numeric_limits<uint64_t>::max()) return Best{};
  return Best{static_cast<int>(key & 0xffffffffu), static_cast<uint32_t>(key >> 32)};
}

#ifdef MAV_MATCHER_AVX512
bool CpuHasMatcherAvx512() {
  return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
         __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("avx512dq");
}

// The SADs of eight consecutive descriptors against `query` (the query descriptor in both
// halves), z0 .. z3 holding two each: per 512-bit psadbw four partial sums (8 bytes) per
// descriptor, added in pairs, then halves. The result's lanes hold descriptors 0, 2, 1, 3, 4,
// 6, 5, 7. (The maskz forms with a full mask throughout: GCC 12's unmasked ones trip
// -Wmaybe-uninitialized, GCC bug 105593.)
MAV_TARGET_AVX512 inline __m512i EightSads(__m512i query, __m512i z0, __m512i z1, __m512i z2,
                                           __m512i z3) {
  z0 = _mm512_sad_epu8(z0, query);
  z1 = _mm512_sad_epu8(z1, query);
  z2 = _mm512_sad_epu8(z2, query);
  z3 = _mm512_sad_epu8(z3, query);
  const __m512i s01 = _mm512_add_epi64(_mm512_maskz_unpacklo_epi64(0xff, z0, z1),
                                       _mm512_maskz_unpackhi_epi64(0xff, z0, z1));
  const __m512i s23 = _mm512_add_epi64(_mm512_maskz_unpacklo_epi64(0xff, z2, z3),
                                       _mm512_maskz_unpackhi_epi64(0xff, z2, z3));
  return _mm512_add_epi64(_mm512_maskz_shuffle_i64x2(0xff, s01, s23, 0x88),
                          _mm512_maskz_shuffle_i64x2(0xff, s01, s23, 0xdd));
}

// (SAD << 32 | index) keys from EightSads' sums and the lanes' feature indices.
MAV_TARGET_AVX512 inline __m512i Keys(__m512i sads, __m512i indices) {
  return _mm512_or_si512(_mm512_maskz_slli_epi64(0xff, sads, 32), indices);
}

// The query descriptor in both 256-bit halves.
MAV_TARGET_AVX512 inline __m512i QueryOf(const Descriptor& d) {
  return _mm512_maskz_broadcast_i64x4(
      0xff, _mm256_load_si256(reinterpret_cast<const __m256i*>(d.bytes.data())));
}

// The smallest of the eight keys.
MAV_TARGET_AVX512 inline uint64_t MinLane(__m512i keys) {
  alignas(64) uint64_t lanes[8];
  _mm512_store_si512(lanes, keys);
  return *std::min_element(lanes, lanes + 8);
}

// The lowest (SAD << 32 | index) key of `d` among the features of `c` inside the window
// [u0, u1] x [v0, v1] (clipped to the image), or ~0: ForEachInWindow's cell ranges, eight features
// at a time without a branch per feature. Each block's bounds tests give a mask; the SADs of all
// eight descriptors (two per 512-bit psadbw) are summed in lanes and the masked keys kept in a
// vector of running minima: the same minimum as visiting the window's features one by one.
MAV_TARGET_AVX512 uint64_t BestKeyInWindowAvx512(const FeatureSet& fs, const FeatureSet::Class& c,
                                                 const Descriptor& d, int u0, int u1, int v0,
                                                 int v1) {
  constexpr uint64_t kNone = std::numeric_limits<uint64_t>::max();
  const FeatureSet::Window w = fs.ClipWindow(c, u0, u1, v0, v1);
  if (w.empty) return kNone;
  const int size = c.size();
  const __m128i lo_u = _mm_set1_epi16(static_cast<int16_t>(w.u0 - 1));
  const __m128i hi_u = _mm_set1_epi16(static_cast<int16_t>(w.u1 + 1));
  const __m128i lo_v = _mm_set1_epi16(static_cast<int16_t>(w.v0 - 1));
  const __m128i hi_v = _mm_set1_epi16(static_cast<int16_t>(w.v1 + 1));
  const __m512i query = QueryOf(d);
  // The lanes of EightSads for contiguous descriptors: 0, 2, 1, 3, 4, 6, 5, 7 of a block.
  const __m512i lane_index = _mm512_setr_epi64(0, 2, 1, 3, 4, 6, 5, 7);
  const uint8_t* descriptors = reinterpret_cast<const uint8_t*>(c.descriptors.data());
  __m512i best = _mm512_set1_epi64(static_cast<long long>(kNone));
  uint64_t best_scalar = kNone;
  for (int cy = w.cy0; cy <= w.cy1; ++cy) {
    const int first = fs.CellRowFirst(c, w, cy), last = fs.CellRowLast(c, w, cy);
    int i = first;
    for (; i < last && i + 8 <= size; i += 8) {
      const __m128i u = _mm_loadu_si128(reinterpret_cast<const __m128i*>(c.u.data() + i));
      const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(c.v.data() + i));
      unsigned in = _mm_cmpgt_epi16_mask(u, lo_u) & _mm_cmplt_epi16_mask(u, hi_u) &
                    _mm_cmpgt_epi16_mask(v, lo_v) & _mm_cmplt_epi16_mask(v, hi_v);
      if (last - i < 8) in &= (1u << (last - i)) - 1;
      if (in == 0) continue;
      const uint8_t* block = descriptors + static_cast<size_t>(i) * sizeof(Descriptor);
      const __m512i key =
          Keys(EightSads(query, _mm512_loadu_si512(block), _mm512_loadu_si512(block + 64),
                         _mm512_loadu_si512(block + 128), _mm512_loadu_si512(block + 192)),
               _mm512_add_epi64(lane_index, _mm512_set1_epi64(static_cast<long long>(i))));
      // The mask in the same lane order (bits 1 and 2, 5 and 6 swapped).
      const unsigned lanes = (in & 0x99u) | ((in & 0x22u) << 1) | ((in & 0x44u) >> 1);
      best = _mm512_mask_min_epu64(best, static_cast<__mmask8>(lanes), best, key);
    }
    for (; i < last; ++i) {  // the last features of the class, past the last whole block
      if (c.u[i] < w.u0 || c.u[i] > w.u1 || c.v[i] < w.v0 || c.v[i] > w.v1) continue;
      best_scalar =
          std::min(best_scalar, (static_cast<uint64_t>(DescriptorSad(d, c.descriptors[i])) << 32) |
                                    static_cast<uint32_t>(i));
    }
  }
  return std::min(best_scalar, MinLane(best));
}

#endif

// Best match of `d` among the features of class `c` inside [u0, u1] x [v0, v1] (inclusive): the
// lowest SAD, the lowest index among equals (whatever the order of the visits). A window a few
// rows tall (the stereo searches) is searched by rows, a square one by grid cells (with AVX-512
// when `avx512`).
Best FindBest(const FeatureSet& fs, const FeatureSet::Class& c, const Descriptor& d, int u0, int u1,
              int v0, int v1, bool avx512 = false) {
  // (cost, index) as one key whose minimum is the lowest cost, then the lowest index: a
  // conditional move per visit instead of a branch on the costs, which mispredicted and held
  // up the next visits' descriptor loads.
  uint64_t best = std::numeric_limits<uint64_t>::max();
  auto visit = [&](int i) {
    const uint64_t key = (static_cast<uint64_t>(DescriptorSad(d, c.descriptors[i])) << 32) |
                         static_cast<uint32_t>(i);
    best = std::min(best, key);
  };
  const bool rows = v1 - v0 < 4;
#ifdef MAV_MATCHER_AVX512
  if (avx512 && !rows) return BestOfKey(BestKeyInWindowAvx512(fs, c, d, u0, u1, v0, v1));
#endif
  if (rows) {
    fs.ForEachInRows(c, u0, u1, v0, v1, visit);
  } else {
    fs.ForEachInWindow(c, u0, u1, v0, v1, visit);
  }
  return BestOfKey(best);
}

// std::lround (halves away from zero) to int without the library call (half a percent of a VO
// frame): truncation and the remainder (exact) below 1e9 in magnitude, where every predicted
// position lies; the library beyond, and for NaN.
inline int RoundToInt(double x) {
  if (!(std::abs(x) < 1e9)) return static_cast<int>(std::lround(x));
  const int t = static_cast<int>(x);
  const double f = x - t;  // exact
  return t + (f >= 0.5) - (f <= -0.5);
}

// Projects the point of a stereo feature (left pixel, disparity) through a rigid motion into
// the left (right = false) or right image. False if the point ends up behind the camera.
struct MotionPredictor {
  double fx, fy, cx, cy, b;
  Eigen::Matrix3d R;
  Eigen::Vector3d t;

  bool Predict(double u, double v, double disparity, bool right, double* pu, double* pv) const {
    const double z = fx * b / disparity;
    const Eigen::Vector3d x((u - cx) / fx * z, (v - cy) / fy * z, z);
    const Eigen::Vector3d p = R * x + t;
    if (p.z() < 0.05) return false;
    *pu = fx * (p.x() - (right ? b : 0.0)) / p.z() + cx;
    *pv = fy * p.y() / p.z() + cy;
    return std::abs(*pu) < 1e5 && std::abs(*pv) < 1e5;
  }
};

// The window of both Sobel images around a reference pixel, compared by the sum of squared
// differences (SSD) with windows of other images: RefineOne compares one reference with up to
// 16 targets in each of three images, so its rows are loaded and widened once.
class ReferenceWindow {
 public:
  ReferenceWindow(const FeatureSet& ref, int ru, int rv, int r)
      : ref_(ref), ru_(ru), rv_(rv), r_(r) {
#ifdef __SSE2__
    // The 8-byte rows must lie inside the image (a feature keeps a wider margin; a match given
    // by another caller may not: then the scalar path, which reads only when a target is in).
    simd_ =
        r <= 3 && ru - r >= 0 && ru - r + 8 <= ref.width() && rv - r >= 0 && rv + r < ref.height();
    if (simd_) {
      // 8 bytes per row (the window plus padding, masked out in Ssd), widened to 16 bits.
      const __m128i zero = _mm_setzero_si128();
      const int w = ref.width();
      const std::vector<uint8_t>* images[2] = {&ref.sobel_u(), &ref.sobel_v()};
      for (int c = 0; c < 2; ++c) {
        for (int dy = -r; dy <= r; ++dy) {
          const uint8_t* a = images[c]->data() + (rv + dy) * w + ru - r;
          rows_[c][dy + r] =
              _mm_unpacklo_epi8(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(a)), zero);
        }
      }
      mask_ = _mm_cmplt_epi16(_mm_setr_epi16(0, 1, 2, 3, 4, 5, 6, 7),
                              _mm_set1_epi16(static_cast<int16_t>(2 * r + 1)));
    }
#endif
  }

  // SSD between this window and the one around (tu, tv) in `tgt` (same size as the reference).
  int64_t Ssd(const FeatureSet& tgt, int tu, int tv) const {
    const int w = ref_.width(), r = r_;
#ifdef __SSE2__
    if (simd_) {
      // pmaddwd squares and pairs the masked 16-bit differences.
      const __m128i zero = _mm_setzero_si128();
      __m128i acc = _mm_setzero_si128();
      const std::vector<uint8_t>* images[2] = {&tgt.sobel_u(), &tgt.sobel_v()};
      for (int c = 0; c < 2; ++c) {
        for (int dy = -r; dy <= r; ++dy) {
          const uint8_t* b = images[c]->data() + (tv + dy) * w + tu - r;
          const __m128i vb =
              _mm_unpacklo_epi8(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(b)), zero);
          const __m128i d = _mm_and_si128(_mm_sub_epi16(rows_[c][dy + r], vb), mask_);
          acc = _mm_add_epi32(acc, _mm_madd_epi16(d, d));
        }
      }
      acc = _mm_add_epi32(acc, _mm_srli_si128(acc, 8));
      acc = _mm_add_epi32(acc, _mm_srli_si128(acc, 4));
      return _mm_cvtsi128_si32(acc);
    }
#endif
    int64_t sum = 0;
    for (int dy = -r; dy <= r; ++dy) {
      const uint8_t* au = ref_.sobel_u().data() + (rv_ + dy) * w + ru_;
      const uint8_t* av = ref_.sobel_v().data() + (rv_ + dy) * w + ru_;
      const uint8_t* bu = tgt.sobel_u().data() + (tv + dy) * w + tu;
      const uint8_t* bv = tgt.sobel_v().data() + (tv + dy) * w + tu;
      int row = 0;
      for (int dx = -r; dx <= r; ++dx) {
        const int eu = int(au[dx]) - int(bu[dx]);
        const int ev = int(av[dx]) - int(bv[dx]);
        row += eu * eu + ev * ev;
      }
      sum += row;
    }
    return sum;
  }

  int radius() const { return r_; }

 private:
  const FeatureSet& ref_;
  int ru_, rv_, r_;
#ifdef __SSE2__
  bool simd_ = false;
  __m128i rows_[2][7];
  __m128i mask_;
#endif
};

// Vertex offset of the parabola through (-1, a), (0, b), (1, c), clamped to [-0.5, 0.5].
double ParabolaVertex(double a, double b, double c) {
  const double denom = a - 2.0 * b + c;
  if (!(denom > 0)) return 0.0;
  return std::clamp(0.5 * (a - c) / denom, -0.5, 0.5);
}

void RefineOne(const ReferenceWindow& ref, const FeatureSet& tgt, bool subpixel, float* u,
               float* v) {
  const int r = ref.radius();
  const int u0 = static_cast<int>(std::lround(*u)), v0 = static_cast<int>(std::lround(*v));
  int cu = u0, cv = v0;
  const int lo = r + 2, hi_u = tgt.width() - r - 3, hi_v = tgt.height() - r - 3;
  // The centre moves at most twice, so all costs lie within +-3 of the start; each is computed
  // once (a move re-uses the 6 or 4 costs it shares with the previous 3x3 neighbourhood).
  int64_t memo[7][7];
  for (auto& row : memo) std::fill(std::begin(row), std::end(row), int64_t{-1});
  auto cost_at = [&](int tu, int tv) {
    int64_t& c = memo[tv - v0 + 3][tu - u0 + 3];
    if (c < 0) c = ref.Ssd(tgt, tu, tv);
    return c;
  };
  int64_t cost[3][3];
  for (int step = 0; step < 3; ++step) {
    if (cu < lo || cu > hi_u || cv < lo || cv > hi_v) return;  // too close to the border
    // All nine first: the minimum search must compare against this neighbourhood's centre.
    for (int j = 0; j < 3; ++j) {
      for (int i = 0; i < 3; ++i) cost[j][i] = cost_at(cu + i - 1, cv + j - 1);
    }
    int bi = 1, bj = 1;
    for (int j = 0; j < 3; ++j) {
      for (int i = 0; i < 3; ++i) {
        if (cost[j][i] < cost[bj][bi]) {
          bi = i;
          bj = j;
        }
      }
    }
    if ((bi == 1 && bj == 1) || step == 2) {
      if (bi != 1 || bj != 1) return;  // no minimum found within two moves: keep as is
      if (!subpixel) {
        *u = static_cast<float>(cu);
        *v = static_cast<float>(cv);
        return;
      }
      *u = static_cast<float>(cu + ParabolaVertex(cost[1][0], cost[1][1], cost[1][2]));
      *v = static_cast<float>(cv + ParabolaVertex(cost[0][1], cost[1][1], cost[2][1]));
      return;
    }
    cu += bi - 1;
    cv += bj - 1;
  }
}

}  // namespace

bool MatcherOptions::IsValid(std::string* why) const {
  std::ostringstream msg;
  if (stereo_row_tolerance_px < 0 || stereo_row_tolerance_px > 8) {
    msg << "stereo_row_tolerance_px: must be in [0, 8], got " << stereo_row_tolerance_px;
  } else if (min_disparity_px < 0) {
    msg << "min_disparity_px: must be >= 0, got " << min_disparity_px;
  } else if (max_disparity_px <= min_disparity_px) {
    msg << "max_disparity_px: must exceed min_disparity_px (" << min_disparity_px << "), got "
        << max_disparity_px;
  } else if (search_radius_px < 1) {
    msg << "search_radius_px: must be >= 1, got " << search_radius_px;
  } else if (search_radius_no_prior_px < 1) {
    msg << "search_radius_no_prior_px: must be >= 1, got " << search_radius_no_prior_px;
  } else if (loop_tolerance_px < 0 || loop_tolerance_px > 4) {
    msg << "loop_tolerance_px: must be in [0, 4], got " << loop_tolerance_px;
  } else if (bucket_width_px < 1 || bucket_height_px < 1) {
    msg << "bucket_width_px/bucket_height_px: must be >= 1, got " << bucket_width_px << "x"
        << bucket_height_px;
  } else if (max_starts_per_bucket < 0) {
    msg << "max_starts_per_bucket: must be >= 0, got " << max_starts_per_bucket;
  } else if (bucket_max_matches < 1) {
    msg << "bucket_max_matches: must be >= 1, got " << bucket_max_matches;
  } else if (refine_half_window_px < 1 || refine_half_window_px > 4) {
    msg << "refine_half_window_px: must be in [1, 4], got " << refine_half_window_px;
  } else {
    return true;
  }
  if (why) *why = msg.str();
  return false;
}

bool MatcherUsesAvx512(const MatcherOptions& options) {
#ifdef MAV_MATCHER_AVX512
  static const bool cpu = CpuHasMatcherAvx512();
  return options.use_avx512 && cpu;
#else
  (void)options;
  return false;
#endif
}

void MatchCircular(const FeatureSet& prev_left, const FeatureSet& prev_right,
                   const FeatureSet& cur_left, const FeatureSet& cur_right,
                   const camera::RectifiedStereo& rig, const geometry::SE3* T_cur_prev_predicted,
                   const MatcherOptions& options, std::vector<QuadMatch>* matches) {
  matches->clear();
  const bool avx512 = MatcherUsesAvx512(options);
  const int tol = options.stereo_row_tolerance_px;
  const int dmin = options.min_disparity_px, dmax = options.max_disparity_px;
  const bool prior = options.use_motion_prior && T_cur_prev_predicted != nullptr;
  const int radius = prior ? options.search_radius_px : options.search_radius_no_prior_px;
  const int loop_tol = options.loop_tolerance_px;
  const geometry::SE3 T_cur_prev_predicted_or_identity =
      prior ? *T_cur_prev_predicted : geometry::SE3();
  const MotionPredictor forward{rig.fx,
                                rig.fy,
                                rig.cx,
                                rig.cy,
                                rig.baseline,
                                T_cur_prev_predicted_or_identity.RotationMatrix(),
                                T_cur_prev_predicted_or_identity.Translation()};
  const geometry::SE3 T_prev_cur = T_cur_prev_predicted_or_identity.Inverse();
  const MotionPredictor backward{rig.fx,
                                 rig.fy,
                                 rig.cx,
                                 rig.cy,
                                 rig.baseline,
                                 T_prev_cur.RotationMatrix(),
                                 T_prev_cur.Translation()};

  // Start features, optionally only the strongest few per bucket of the previous left image.
  // A start is one key whose ascending order is the strongest first, then the lowest class,
  // then the lowest index (a total order): sorting keys is cheaper than sorting by a comparator.
  auto start_key = [](int strength, int feature_class, int index) {
    return (static_cast<uint64_t>(static_cast<uint16_t>(32767 - strength)) << 48) |
           (static_cast<uint64_t>(static_cast<uint16_t>(feature_class)) << 32) |
           static_cast<uint32_t>(index);
  };
  std::vector<uint64_t> starts;
  const int bw = options.bucket_width_px, bh = options.bucket_height_px;
  const int bcols = std::max(1, (prev_left.width() + bw - 1) / bw);
  const int brows = std::max(1, (prev_left.height() + bh - 1) / bh);
  std::vector<int32_t> bucket_start(static_cast<size_t>(bcols) * brows + 1, 0);
  // The bucket of a pixel from two tables (no divisions per feature).
  std::vector<int32_t> bucket_col(std::max(prev_left.width(), 0));
  std::vector<int32_t> bucket_row(std::max(prev_left.height(), 0));
  for (size_t u = 0; u < bucket_col.size(); ++u) {
    bucket_col[u] = std::min(static_cast<int>(u) / bw, bcols - 1);
  }
  for (size_t v = 0; v < bucket_row.size(); ++v) {
    bucket_row[v] = std::min(static_cast<int>(v) / bh, brows - 1) * bcols;
  }
  auto bucket_of = [&](int u, int v) { return bucket_row[v] + bucket_col[u]; };
  for (int k = 0; k < kNumFeatureClasses; ++k) {
    const FeatureSet::Class& pl = prev_left.features(k);
    for (int i = 0; i < pl.size(); ++i) ++bucket_start[bucket_of(pl.u[i], pl.v[i]) + 1];
  }
  for (size_t b = 1; b < bucket_start.size(); ++b) bucket_start[b] += bucket_start[b - 1];
  starts.resize(bucket_start.back());
  {
    std::vector<int32_t> fill(bucket_start.begin(), bucket_start.end() - 1);
    for (int k = 0; k < kNumFeatureClasses; ++k) {
      const FeatureSet::Class& pl = prev_left.features(k);
      for (int i = 0; i < pl.size(); ++i) {
        starts[fill[bucket_of(pl.u[i], pl.v[i])]++] = start_key(pl.strength[i], k, i);
      }
    }
  }
  if (options.max_starts_per_bucket > 0) {
    const int p = options.max_starts_per_bucket;
    size_t out = 0;
    for (size_t b = 0; b + 1 < bucket_start.size(); ++b) {
      auto first = starts.begin() + bucket_start[b], last = starts.begin() + bucket_start[b + 1];
      if (last - first > p) {
        // The p first keys: selected, then sorted.
        std::nth_element(first, first + p, last);
        std::sort(first, first + p);
        last = first + p;
      }
      for (auto it = first; it != last; ++it) starts[out++] = *it;
    }
    starts.resize(out);
  }

  for (const uint64_t start : starts) {
    const int k = static_cast<uint16_t>(start >> 32), i = static_cast<int32_t>(start & 0xffffffffu);
    const FeatureSet::Class& pl = prev_left.features(k);
    const FeatureSet::Class& pr = prev_right.features(k);
    const FeatureSet::Class& cl = cur_left.features(k);
    const FeatureSet::Class& cr = cur_right.features(k);
    {
      const int u_i = pl.u[i], v_i = pl.v[i];
      // 1. previous left -> previous right (same row, positive disparity).
      const Best j =
          FindBest(prev_right, pr, pl.descriptors[i], u_i - dmax, u_i - dmin, v_i - tol, v_i + tol);
      if (j.index < 0) continue;
      const int u_j = pr.u[j.index], v_j = pr.v[j.index];
      // 2. previous right -> current right (motion window).
      double pu = u_j, pv = v_j;
      if (prior) forward.Predict(u_i, v_i, u_i - u_j, /*right=*/true, &pu, &pv);
      const int cu = RoundToInt(pu), cv = RoundToInt(pv);
      const Best kk = FindBest(cur_right, cr, pr.descriptors[j.index], cu - radius, cu + radius,
                               cv - radius, cv + radius, avx512);
      if (kk.index < 0) continue;
      const int u_k = cr.u[kk.index], v_k = cr.v[kk.index];
      // 3. current right -> current left (same row, positive disparity).
      const Best l = FindBest(cur_left, cl, cr.descriptors[kk.index], u_k + dmin, u_k + dmax,
                              v_k - tol, v_k + tol);
      if (l.index < 0) continue;
      const int u_l = cl.u[l.index], v_l = cl.v[l.index];
      // 4. current left -> previous left (motion window); the loop must return to feature i.
      double qu = u_l, qv = v_l;
      if (prior) backward.Predict(u_l, v_l, u_l - u_k, /*right=*/false, &qu, &qv);
      const int bu = RoundToInt(qu), bv = RoundToInt(qv);
      const Best m = FindBest(prev_left, pl, cl.descriptors[l.index], bu - radius, bu + radius,
                              bv - radius, bv + radius, avx512);
      if (m.index < 0) continue;
      if (m.index != i &&
          (std::abs(pl.u[m.index] - u_i) > loop_tol || std::abs(pl.v[m.index] - v_i) > loop_tol)) {
        continue;
      }
      QuadMatch q;
      q.u_prev_left = static_cast<float>(u_i);
      q.v_prev_left = static_cast<float>(v_i);
      q.u_prev_right = static_cast<float>(u_j);
      q.v_prev_right = static_cast<float>(v_j);
      q.u_cur_left = static_cast<float>(u_l);
      q.v_cur_left = static_cast<float>(v_l);
      q.u_cur_right = static_cast<float>(u_k);
      q.v_cur_right = static_cast<float>(v_k);
      q.cost = j.cost + kk.cost + l.cost + m.cost;
      q.feature_class = k;
      matches->push_back(q);
    }
  }
}

void BucketMatches(const MatcherOptions& options, int image_width, int image_height,
                   std::vector<QuadMatch>* matches) {
  const int bw = options.bucket_width_px, bh = options.bucket_height_px;
  const int cols = std::max(1, (image_width + bw - 1) / bw);
  const int rows = std::max(1, (image_height + bh - 1) / bh);
  auto bucket = [&](const QuadMatch& q) {
    const int c = std::clamp(static_cast<int>(q.u_cur_left) / bw, 0, cols - 1);
    const int r = std::clamp(static_cast<int>(q.v_cur_left) / bh, 0, rows - 1);
    return r * cols + c;
  };
  // Grouped by bucket (a counting sort; each match's bucket computed once), then ordered within
  // its bucket by cost, start position and class (a total order: one match per start), of
  // which the first bucket_max_matches are kept: the order of a full sort by (bucket, cost,
  // position, class) at the cost of sorting a few matches per bucket.
  struct Entry {
    uint32_t cost;
    float v, u;
    int32_t feature_class;
    int32_t index;
  };
  const std::vector<QuadMatch>& m = *matches;
  std::vector<int32_t> buckets(m.size());
  std::vector<int32_t> start(static_cast<size_t>(cols) * rows + 1, 0);
  for (size_t i = 0; i < m.size(); ++i) {
    buckets[i] = bucket(m[i]);
    ++start[buckets[i] + 1];
  }
  for (size_t b = 1; b < start.size(); ++b) start[b] += start[b - 1];
  std::vector<Entry> entries(m.size());
  {
    std::vector<int32_t> fill(start.begin(), start.end() - 1);
    for (size_t i = 0; i < m.size(); ++i) {
      entries[fill[buckets[i]]++] = {m[i].cost, m[i].v_prev_left, m[i].u_prev_left,
                                     m[i].feature_class, static_cast<int32_t>(i)};
    }
  }
  auto before = [](const Entry& a, const Entry& b) {
    if (a.cost != b.cost) return a.cost < b.cost;
    if (a.v != b.v) return a.v < b.v;
    if (a.u != b.u) return a.u < b.u;
    return a.feature_class < b.feature_class;
  };
  std::vector<QuadMatch> kept;
  kept.reserve(m.size());
  for (size_t b = 0; b + 1 < start.size(); ++b) {
    const auto first = entries.begin() + start[b], last = entries.begin() + start[b + 1];
    const auto keep = first + std::clamp<ptrdiff_t>(options.bucket_max_matches, 0, last - first);
    if (keep != last) std::nth_element(first, keep, last, before);
    std::sort(first, keep, before);
    for (auto it = first; it != keep; ++it) kept.push_back(m[it->index]);
  }
  matches->swap(kept);
}

void RefineMatchesSubpixel(const FeatureSet& prev_left, const FeatureSet& prev_right,
                           const FeatureSet& cur_left, const FeatureSet& cur_right,
                           const MatcherOptions& options, std::vector<QuadMatch>* matches) {
  const int r = options.refine_half_window_px;
  for (QuadMatch& q : *matches) {
    const int ru = static_cast<int>(q.u_prev_left), rv = static_cast<int>(q.v_prev_left);
    const ReferenceWindow ref(prev_left, ru, rv, r);
    RefineOne(ref, prev_right, true, &q.u_prev_right, &q.v_prev_right);
    RefineOne(ref, cur_left, true, &q.u_cur_left, &q.v_cur_left);
    RefineOne(ref, cur_right, true, &q.u_cur_right, &q.v_cur_right);
  }
}

void RefineMatchesPixel(const FeatureSet& prev_left, const FeatureSet& prev_right,
                        const FeatureSet& cur_left, const FeatureSet& cur_right,
                        const MatcherOptions& options, std::vector<QuadMatch>* matches) {
  const int r = options.refine_half_window_px;
  for (QuadMatch& q : *matches) {
    const int ru = static_cast<int>(q.u_prev_left), rv = static_cast<int>(q.v_prev_left);
    const ReferenceWindow ref(prev_left, ru, rv, r);
    RefineOne(ref, prev_right, false, &q.u_prev_right, &q.v_prev_right);
    RefineOne(ref, cur_left, false, &q.u_cur_left, &q.v_cur_left);
    RefineOne(ref, cur_right, false, &q.u_cur_right, &q.v_cur_right);
  }
}

}  // namespace mav::localization
