#include "mav/localization/features.h"

#include <algorithm>
#include <cstdlib>
#include <random>

#include <gtest/gtest.h>

#include "synthetic_stereo.h"

namespace mav::localization {
namespace {

// The StereoScan masks, written out.
constexpr int kBlob[5][5] = {{-1, -1, -1, -1, -1},
                             {-1, 1, 1, 1, -1},
                             {-1, 1, 8, 1, -1},
                             {-1, 1, 1, 1, -1},
                             {-1, -1, -1, -1, -1}};
constexpr int kCorner[5][5] = {
    {-1, -1, 0, 1, 1}, {-1, -1, 0, 1, 1}, {0, 0, 0, 0, 0}, {1, 1, 0, -1, -1}, {1, 1, 0, -1, -1}};

std::vector<uint8_t> RandomImage(int w, int h, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<uint8_t> img(static_cast<size_t>(w) * h);
  for (auto& p : img) p = static_cast<uint8_t>(rng() & 0xff);
  return img;
}

TEST(FeaturesTest, FilterResponsesEqualDirectConvolution) {
  const int w = 61, h = 37;
  const std::vector<uint8_t> img = RandomImage(w, h, 1);
  for (const bool avx2 : {false, true}) {
    std::vector<int16_t> blob, corner, scratch;
    ComputeFilterResponses({img.data(), w, h, w}, &blob, &corner, &scratch, avx2);
    for (int y = 2; y < h - 2; ++y)
      for (int x = 2; x < w - 2; ++x) {
        int b = 0, c = 0;
        for (int j = -2; j <= 2; ++j)
          for (int i = -2; i <= 2; ++i) {
            b += kBlob[j + 2][i + 2] * img[(y + j) * w + x + i];
            c += kCorner[j + 2][i + 2] * img[(y + j) * w + x + i];
          }
        ASSERT_EQ(blob[y * w + x], b) << "blob at " << x << "," << y;
        ASSERT_EQ(corner[y * w + x], c) << "corner at " << x << "," << y;
      }
  }
}

// The Sobel images (the descriptors' source, computed 16 pixels at a time) equal the 3x3 Sobel
// masks applied directly and mapped to bytes as Descriptor says, with a 128 border.
TEST(FeaturesTest, SobelImagesEqualDirectConvolution) {
  for (const int w : {61, 83}) {
    const int h = 37;
    const std::vector<uint8_t> img = RandomImage(w, h, w);
    FeatureExtractor extractor(FeatureOptions{});
    FeatureSet fs;
    extractor.Extract({img.data(), w, h, w}, &fs);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        int eu = 128, ev = 128;
        if (x > 0 && y > 0 && x < w - 1 && y < h - 1) {
          auto p = [&](int dx, int dy) { return int(img[(y + dy) * w + x + dx]); };
          const int gu = (p(1, -1) + 2 * p(1, 0) + p(1, 1)) - (p(-1, -1) + 2 * p(-1, 0) + p(-1, 1));
          const int gv = (p(-1, 1) + 2 * p(0, 1) + p(1, 1)) - (p(-1, -1) + 2 * p(0, -1) + p(1, -1));
          eu = std::clamp((gu >> 2) + 128, 0, 255);
          ev = std::clamp((gv >> 2) + 128, 0, 255);
        }
        ASSERT_EQ(fs.sobel_u()[y * w + x], eu)
            << "u at " << x << "," << y << " (width " << w << ")";
        ASSERT_EQ(fs.sobel_v()[y * w + x], ev)
            << "v at " << x << "," << y << " (width " << w << ")";
      }
    }
  }
}

TEST(FeaturesTest, SadMatchesScalarDefinition) {
  std::mt19937_64 rng(3);
  for (int trial = 0; trial < 100; ++trial) {
    Descriptor a, b;
    uint32_t expected = 0;
    for (int i = 0; i < 32; ++i) {
      a.bytes[i] = static_cast<uint8_t>(rng());
      b.bytes[i] = static_cast<uint8_t>(rng());
      expected += std::abs(int(a.bytes[i]) - int(b.bytes[i]));
    }
    ASSERT_EQ(DescriptorSad(a, b), expected);
  }
}

// Every feature is an extremum of its neighbourhood, above the threshold, inside the
// margin, in the right class; the grid index covers every feature exactly once.
void CheckFeatures(const std::vector<uint8_t>& img, int w, int h, const FeatureOptions& options,
                   const FeatureSet& fs) {
  std::vector<int16_t> blob, corner, scratch;
  ComputeFilterResponses({img.data(), w, h, w}, &blob, &corner, &scratch);
  const int n = options.nms_radius, m = FeatureSet::kDescriptorMargin;
  int total = 0;
  for (int k = 0; k < kNumFeatureClasses; ++k) {
    const FeatureSet::Class& c = fs.features(k);
    const std::vector<int16_t>& r = (k == kBlobMax || k == kBlobMin) ? blob : corner;
    const int sign = (k == kBlobMax || k == kCornerMax) ? 1 : -1;
    ASSERT_EQ(c.cell_start.back(), c.size());
    for (int i = 0; i < c.size(); ++i) {
      const int u = c.u[i], v = c.v[i];
      ASSERT_GE(u, m);
      ASSERT_LT(u, w - m);
      ASSERT_GE(v, m);
      ASSERT_LT(v, h - m);
      const int cell = (v / fs.grid_cell_px()) * fs.grid_cols() + u / fs.grid_cell_px();
      ASSERT_GE(i, c.cell_start[cell]);
      ASSERT_LT(i, c.cell_start[cell + 1]);
      const int val = sign * r[v * w + u];
      ASSERT_GE(val, options.response_threshold);
      for (int dy = -n; dy <= n; ++dy)
        for (int dx = -n; dx <= n; ++dx) {
          if (dx == 0 && dy == 0) continue;
          const int other = sign * r[(v + dy) * w + u + dx];
          ASSERT_LE(other, val) << "class " << k << " at " << u << "," << v;
          // Plateaus: an equal 8-neighbour earlier in raster order would have won.
          const bool earlier_neighbour = std::abs(dx) <= 1 && (dy == -1 || (dy == 0 && dx == -1));
          if (earlier_neighbour) {
            ASSERT_LT(other, val) << "class " << k << " at " << u << "," << v;
          }
        }
      const Descriptor d = fs.DescriptorAt(u, v);
      ASSERT_EQ(DescriptorSad(d, c.descriptors[i]), 0u);
    }
    // ... and every such extremum inside the margins is a feature (the SIMD passes miss none).
    int extrema = 0;
    for (int v = m; v < h - m; ++v) {
      for (int u = m; u < w - m; ++u) {
        const int val = sign * r[v * w + u];
        bool is_extremum = val >= options.response_threshold;
        for (int dy = -n; dy <= n && is_extremum; ++dy) {
          for (int dx = -n; dx <= n && is_extremum; ++dx) {
            const int other = sign * r[(v + dy) * w + u + dx];
            const bool earlier_neighbour = std::abs(dx) <= 1 && (dy == -1 || (dy == 0 && dx == -1));
            is_extremum = other < val || (other == val && !earlier_neighbour);
          }
        }
        extrema += is_extremum;
      }
    }
    EXPECT_EQ(c.size(), extrema) << "class " << k;
    total += c.size();
  }
  EXPECT_EQ(total, fs.TotalFeatures());
  EXPECT_GT(total, 200);
}

TEST(FeaturesTest, NonMaximumSuppressionYieldsStrictExtremaPerClass) {
  const camera::RectifiedStereo rig = synthetic::EurocLikeRig();
  synthetic::SyntheticRoom room;
  std::vector<uint8_t> left, right;
  room.Render(rig, geometry::SE3(), &left, &right);
  FeatureOptions options;
  FeatureExtractor extractor(options);
  FeatureSet fs;
  extractor.Extract({left.data(), rig.width, rig.height, rig.width}, &fs);
  CheckFeatures(left, rig.width, rig.height, options, fs);
  for (int k = 0; k < kNumFeatureClasses; ++k) EXPECT_GT(fs.features(k).size(), 50) << k;

  // Half resolution: fewer features, still inside the margins and in every class.
  options.half_resolution = true;
  FeatureExtractor half(options);
  FeatureSet hs;
  half.Extract({left.data(), rig.width, rig.height, rig.width}, &hs);
  EXPECT_GT(hs.TotalFeatures(), 100);
  EXPECT_LT(hs.TotalFeatures(), fs.TotalFeatures());
  for (int k = 0; k < kNumFeatureClasses; ++k) {
    for (int i = 0; i < hs.features(k).size(); ++i) {
      EXPECT_EQ(hs.features(k).u[i] % 2, 0);
      EXPECT_GE(hs.features(k).u[i], FeatureSet::kDescriptorMargin);
      EXPECT_LT(hs.features(k).u[i], rig.width - FeatureSet::kDescriptorMargin);
    }
  }
}

// The window scans (eight features at a time with SIMD compares) visit exactly the features a
// scan of every feature finds: ForEachInWindow in increasing index, ForEachInRows in raster
// order; windows of every size, clipped at every border, empty and inverted.
TEST(FeaturesTest, WindowScansVisitExactlyTheWindowsFeatures) {
  const camera::RectifiedStereo rig = synthetic::EurocLikeRig();
  synthetic::SyntheticRoom room;
  std::vector<uint8_t> left, right;
  room.Render(rig, geometry::SE3(), &left, &right);
  FeatureExtractor extractor(FeatureOptions{});
  FeatureSet fs;
  extractor.Extract({left.data(), rig.width, rig.height, rig.width}, &fs);
  std::mt19937_64 rng(7);
  auto coord = [&](int extent) {
    return static_cast<int>(rng() % (extent + 80)) - 40;  // reaches past both borders
  };
  int visited = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    const FeatureSet::Class& c = fs.features(trial % kNumFeatureClasses);
    const int u0 = coord(rig.width), v0 = coord(rig.height);
    const int u1 = u0 + static_cast<int>(rng() % 120) - 4;  // a few inverted (empty) windows
    const int v1 = v0 + static_cast<int>(rng() % (trial % 2 == 0 ? 4 : 60)) - 1;
    std::vector<int> expected;  // by index
    for (int i = 0; i < c.size(); ++i) {
      if (c.u[i] >= u0 && c.u[i] <= u1 && c.v[i] >= v0 && c.v[i] <= v1) expected.push_back(i);
    }
    std::vector<int> in_window;
    fs.ForEachInWindow(c, u0, u1, v0, v1, [&](int i) { in_window.push_back(i); });
    ASSERT_EQ(in_window, expected)
        << "window [" << u0 << ", " << u1 << "] x [" << v0 << ", " << v1 << "]";
    std::sort(expected.begin(), expected.end(),
              [&](int a, int b) { return c.v[a] != c.v[b] ? c.v[a] < c.v[b] : c.u[a] < c.u[b]; });
    std::vector<int> in_rows;
    fs.ForEachInRows(c, u0, u1, v0, v1, [&](int i) { in_rows.push_back(i); });
    ASSERT_EQ(in_rows, expected) << "rows [" << u0 << ", " << u1 << "] x [" << v0 << ", " << v1
                                 << "]";
    visited += static_cast<int>(expected.size());
  }
  EXPECT_GT(visited, 10000);  // the windows were not all empty
}

// The AVX-512 and AVX2 kernels (chosen at run time) find the same features as the SSE2 ones, on
// the rendered room and on noise (plateaus, every radius), at full and half resolution.
TEST(FeaturesTest, WideKernelsAndSse2KernelsFindTheSameFeatures) {
  const camera::RectifiedStereo rig = synthetic::EurocLikeRig();
  synthetic::SyntheticRoom room;
  std::vector<uint8_t> left, right;
  room.Render(rig, geometry::SE3(), &left, &right);
  const int nw = 203, nh = 77;
  std::vector<uint8_t> noise = RandomImage(nw, nh, 11);
  for (size_t i = 0; i < noise.size(); ++i) noise[i] = static_cast<uint8_t>(noise[i] & 0xe0);
  struct Case {
    const std::vector<uint8_t>* image;
    int w, h;
  };
  for (const Case& image : {Case{&left, rig.width, rig.height}, Case{&noise, nw, nh}}) {
    for (int n = 1; n <= 8; ++n) {
      for (const bool half : {false, true}) {
        FeatureOptions options;
        options.nms_radius = n;
        options.half_resolution = half;
        options.response_threshold = image.image == &noise ? 0 : 50;
        FeatureExtractor best(options);
        options.use_vbmi2 = false;
        FeatureExtractor avx512(options);
        ASSERT_FALSE(avx512.UsesVbmi2());
        options.use_avx512 = false;
        FeatureExtractor avx2(options);
        ASSERT_FALSE(avx2.UsesAvx512());
        options.use_avx2 = false;
        FeatureExtractor sse2(options);
        ASSERT_FALSE(sse2.UsesAvx2());
        FeatureSet a, a2, b, c;
        best.Extract({image.image->data(), image.w, image.h, image.w}, &a);
        avx512.Extract({image.image->data(), image.w, image.h, image.w}, &a2);
        avx2.Extract({image.image->data(), image.w, image.h, image.w}, &b);
        sse2.Extract({image.image->data(), image.w, image.h, image.w}, &c);
        for (int k = 0; k < kNumFeatureClasses; ++k) {
          for (const FeatureSet* wide : {&a, &a2, &b}) {
            const char* which = wide == &a ? "widest" : wide == &a2 ? "AVX-512BW" : "AVX2";
            ASSERT_EQ(wide->features(k).u, c.features(k).u)
                << which << " n " << n << " class " << k;
            ASSERT_EQ(wide->features(k).v, c.features(k).v)
                << which << " n " << n << " class " << k;
            ASSERT_EQ(wide->features(k).strength, c.features(k).strength) << which << " n " << n;
          }
          // The descriptors (AVX2's row shuffles, SSE2's byte loads) against DescriptorAt.
          for (const FeatureSet* set : {&a, &a2, &b, &c}) {
            const FeatureSet::Class& fc = set->features(k);
            for (int i = 0; i < fc.size(); ++i) {
              ASSERT_EQ(fc.descriptors[i].bytes, set->DescriptorAt(fc.u[i], fc.v[i]).bytes)
                  << (set == &c    ? "SSE2"
                      : set == &b  ? "AVX2"
                      : set == &a2 ? "AVX-512BW"
                                   : "widest")
                  << " n " << n << " class " << k << " feature " << i;
            }
          }
        }
        EXPECT_GT(a.TotalFeatures(), 0);
      }
    }
  }
  if (!FeatureExtractor(FeatureOptions{}).UsesAvx2()) {
    GTEST_SKIP() << "this CPU has no AVX2: only the SSE2 kernels ran";
  }
  if (!FeatureExtractor(FeatureOptions{}).UsesAvx512()) {
    GTEST_SKIP() << "this CPU has no AVX-512BW: only the AVX2 and SSE2 kernels ran";
  }
  if (!FeatureExtractor(FeatureOptions{}).UsesVbmi2()) {
    GTEST_SKIP() << "this CPU has no AVX512-VBMI2: its candidate compression did not run";
  }
}

TEST(FeaturesTest, UniformAndTinyImagesHaveNoFeatures) {
  FeatureExtractor extractor({});
  FeatureSet fs;
  std::vector<uint8_t> black(752 * 480, 0);
  extractor.Extract({black.data(), 752, 480, 752}, &fs);
  EXPECT_EQ(fs.TotalFeatures(), 0);
  std::vector<uint8_t> tiny = RandomImage(10, 10, 2);
  extractor.Extract({tiny.data(), 10, 10, 10}, &fs);
  EXPECT_EQ(fs.TotalFeatures(), 0);
  extractor.Extract({nullptr, 0, 0, 0}, &fs);
  EXPECT_EQ(fs.TotalFeatures(), 0);
}

TEST(FeaturesTest, OptionsValidationNamesTheField) {
  FeatureOptions o;
  std::string why;
  EXPECT_TRUE(o.IsValid(&why));
  o.nms_radius = 0;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("nms_radius"), std::string::npos);
  o = {};
  o.grid_cell_px = 1;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("grid_cell_px"), std::string::npos);
}

}  // namespace
}  // namespace mav::localization
