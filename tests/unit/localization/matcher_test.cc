#include "mav/localization/matcher.h"

#include <algorithm>
#include <random>
#include <tuple>

#include <gtest/gtest.h>

#include "synthetic_stereo.h"

namespace mav::localization {
namespace {

// BucketMatches' rule written as one sort: by bucket of the current left position (clamped to
// the image's buckets), then cost, start position (v, u) and class; the first
// bucket_max_matches of each bucket, in that order.
std::vector<QuadMatch> ReferenceBuckets(const MatcherOptions& o, int w, int h,
                                        std::vector<QuadMatch> m) {
  const int cols = (w + o.bucket_width_px - 1) / o.bucket_width_px;
  const int rows = (h + o.bucket_height_px - 1) / o.bucket_height_px;
  auto bucket = [&](const QuadMatch& q) {
    return std::clamp(static_cast<int>(q.v_cur_left) / o.bucket_height_px, 0, rows - 1) * cols +
           std::clamp(static_cast<int>(q.u_cur_left) / o.bucket_width_px, 0, cols - 1);
  };
  std::sort(m.begin(), m.end(), [&](const QuadMatch& a, const QuadMatch& b) {
    return std::make_tuple(bucket(a), a.cost, a.v_prev_left, a.u_prev_left, a.feature_class) <
           std::make_tuple(bucket(b), b.cost, b.v_prev_left, b.u_prev_left, b.feature_class);
  });
  std::vector<QuadMatch> kept;
  for (size_t i = 0, n = 0; i < m.size(); ++i) {
    n = i > 0 && bucket(m[i]) == bucket(m[i - 1]) ? n + 1 : 0;
    if (static_cast<int>(n) < o.bucket_max_matches) kept.push_back(m[i]);
  }
  return kept;
}

TEST(MatcherTest, BucketMatchesKeepsTheCheapestPerBucketInTheOrderOfOneSort) {
  const int w = 752, h = 480;
  std::mt19937_64 rng(7);
  for (const int max_matches : {1, 6, 1000}) {
    MatcherOptions options;
    options.bucket_max_matches = max_matches;
    // Start positions unique per class (one match per start), costs from a small range (many
    // ties), current positions also off the image (clamped into the border buckets).
    std::vector<QuadMatch> matches;
    for (int k = 0; k < kNumFeatureClasses; ++k) {
      for (int i = 0; i < 1500; ++i) {
        const int row = i / 300 + 7 * k;  // 5 rows of 300 starts per class
        QuadMatch q;
        q.u_prev_left = static_cast<float>(i % 300);
        q.v_prev_left = static_cast<float>(row);
        q.u_cur_left = static_cast<float>(static_cast<int>(rng() % (w + 40)) - 20);
        q.v_cur_left = static_cast<float>(static_cast<int>(rng() % (h + 40)) - 20);
        q.u_cur_right = static_cast<float>(i);  // tells the matches apart
        q.cost = static_cast<uint32_t>(rng() % 20);
        q.feature_class = k;
        matches.push_back(q);
      }
    }
    std::shuffle(matches.begin(), matches.end(), rng);
    const std::vector<QuadMatch> want = ReferenceBuckets(options, w, h, matches);
    BucketMatches(options, w, h, &matches);
    ASSERT_EQ(matches.size(), want.size()) << "bucket_max_matches " << max_matches;
    for (size_t i = 0; i < want.size(); ++i) {
      const QuadMatch &a = matches[i], &b = want[i];
      ASSERT_TRUE(a.u_prev_left == b.u_prev_left && a.v_prev_left == b.v_prev_left &&
                  a.feature_class == b.feature_class && a.cost == b.cost &&
                  a.u_cur_left == b.u_cur_left && a.v_cur_left == b.v_cur_left &&
                  a.u_cur_right == b.u_cur_right)
          << "bucket_max_matches " << max_matches << ", match " << i;
    }
  }
  std::vector<QuadMatch> none;
  BucketMatches(MatcherOptions{}, w, h, &none);
  EXPECT_TRUE(none.empty());
}

// The square window searches with AVX-512 find the matches the scalar scan finds, field for
// field, on rendered pairs: with a motion prior (radius 24) and without (radius 64), full and
// half-resolution features.
TEST(MatcherTest, Avx512WindowSearchesFindTheSameMatches) {
  const camera::RectifiedStereo rig = synthetic::EurocLikeRig();
  synthetic::SyntheticRoom room;
  const geometry::SE3 T0(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.1, -0.05, 0.0));
  const geometry::SE3 T1(Eigen::Quaterniond(Eigen::AngleAxisd(0.03, Eigen::Vector3d::UnitY())),
                         Eigen::Vector3d(0.16, -0.03, 0.05));
  std::vector<uint8_t> l0, r0, l1, r1;
  room.Render(rig, T0, &l0, &r0);
  room.Render(rig, T1, &l1, &r1);
  const geometry::SE3 T_cur_prev = T1.Inverse() * T0;
  for (const bool half : {false, true}) {
    FeatureOptions feature_options;
    feature_options.half_resolution = half;
    FeatureExtractor extractor(feature_options);
    FeatureSet pl, pr, cl, cr;
    const int w = rig.width, h = rig.height;
    extractor.Extract({l0.data(), w, h, w}, &pl);
    extractor.Extract({r0.data(), w, h, w}, &pr);
    extractor.Extract({l1.data(), w, h, w}, &cl);
    extractor.Extract({r1.data(), w, h, w}, &cr);
    for (const bool prior : {true, false}) {
      MatcherOptions wide;
      MatcherOptions scalar;
      scalar.use_avx512 = false;
      ASSERT_FALSE(MatcherUsesAvx512(scalar));
      std::vector<QuadMatch> a, b;
      MatchCircular(pl, pr, cl, cr, rig, prior ? &T_cur_prev : nullptr, wide, &a);
      MatchCircular(pl, pr, cl, cr, rig, prior ? &T_cur_prev : nullptr, scalar, &b);
      ASSERT_GT(b.size(), 100u) << "half " << half << " prior " << prior;
      ASSERT_EQ(a.size(), b.size()) << "half " << half << " prior " << prior;
      for (size_t i = 0; i < a.size(); ++i) {
        ASSERT_TRUE(a[i].u_prev_left == b[i].u_prev_left && a[i].v_prev_left == b[i].v_prev_left &&
                    a[i].u_prev_right == b[i].u_prev_right &&
                    a[i].v_prev_right == b[i].v_prev_right && a[i].u_cur_left == b[i].u_cur_left &&
                    a[i].v_cur_left == b[i].v_cur_left && a[i].u_cur_right == b[i].u_cur_right &&
                    a[i].v_cur_right == b[i].v_cur_right && a[i].cost == b[i].cost &&
                    a[i].feature_class == b[i].feature_class)
            << "half " << half << " prior " << prior << " match " << i;
      }
    }
  }
  if (!MatcherUsesAvx512(MatcherOptions{})) {
    GTEST_SKIP() << "this CPU has no AVX-512 (F, BW, VL, DQ): only the scalar scan ran";
  }
}

}  // namespace
}  // namespace mav::localization
