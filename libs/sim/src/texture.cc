#include "mav/sim/texture.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "mav/common/check.h"
#include "random.h"

namespace mav::sim {
namespace {

constexpr int kN = Texture::kSize;

// One octave of tileable value noise: a random lattice with `period` texels per cell, wrapped,
// up-sampled bicubically (smooth, band-limited to about 1/period), values roughly in [-1, 1].
cv::Mat NoiseOctave(int period, internal::Rng& rng) {
  const int cells = std::max(1, kN / period);
  cv::Mat lattice(cells, cells, CV_32F);
  for (int r = 0; r < cells; ++r) {
    for (int c = 0; c < cells; ++c)
      lattice.at<float>(r, c) = static_cast<float>(rng.Uniform(-1, 1));
  }
  if (cells == 1) return cv::Mat(kN, kN, CV_32F, cv::Scalar(lattice.at<float>(0, 0)));
  constexpr int kPad = 3;
  cv::Mat padded;
  cv::copyMakeBorder(lattice, padded, kPad, kPad, kPad, kPad, cv::BORDER_WRAP);
  cv::Mat up;
  cv::resize(padded, up, cv::Size(padded.cols * period, padded.rows * period), 0, 0,
             cv::INTER_CUBIC);
  // The crop is periodic with period kN because the padded lattice is periodic.
  return up(cv::Rect(kPad * period, kPad * period, kN, kN)).clone();
}

// Normalises to zero mean and unit standard deviation.
void Standardise(cv::Mat* m) {
  cv::Scalar mean, stddev;
  cv::meanStdDev(*m, mean, stddev);
  const double s = stddev[0] > 1e-9 ? stddev[0] : 1.0;
  *m = (*m - mean[0]) / s;
}

// Fractal noise: octaves with periods from `coarsest` down to `finest` texels, amplitude ~
// period^h.
cv::Mat FractalNoise(int coarsest, int finest, double h, internal::Rng& rng) {
  cv::Mat sum(kN, kN, CV_32F, cv::Scalar(0));
  for (int p = coarsest; p >= finest; p /= 2) {
    sum += NoiseOctave(p, rng) * std::pow(static_cast<double>(p), h);
  }
  Standardise(&sum);
  return sum;
}

// Adds a smooth radial blob at (cx, cy) with radius r (texels) and amplitude a, wrapping.
void AddBlob(cv::Mat* m, double cx, double cy, double r, double a) {
  const int reach = static_cast<int>(std::ceil(2.0 * r));
  const double inv_r2 = 1.0 / (r * r);
  for (int dy = -reach; dy <= reach; ++dy) {
    const int y = ((static_cast<int>(std::floor(cy)) + dy) % kN + kN) % kN;
    const double ddy = std::floor(cy) + dy - cy;
    float* row = m->ptr<float>(y);
    for (int dx = -reach; dx <= reach; ++dx) {
      const double ddx = std::floor(cx) + dx - cx;
      const double q = (ddx * ddx + ddy * ddy) * inv_r2;
      // A flat-topped blob (smooth edge) reads as a "feature" better than a pure Gaussian.
      const double w = std::exp(-q * q);
      const int x = ((static_cast<int>(std::floor(cx)) + dx) % kN + kN) % kN;
      row[x] += static_cast<float>(a * w);
    }
  }
}

cv::Mat Pattern(const Material& mat, internal::Rng& rng) {
  switch (mat.pattern) {
    case TexturePattern::kUniform:
      return cv::Mat(kN, kN, CV_32F, cv::Scalar(0));
    case TexturePattern::kNoise:
      return FractalNoise(128, 2, 0.8, rng);
    case TexturePattern::kBlobs: {
      cv::Mat m = FractalNoise(128, 4, 0.9, rng) * 0.35;
      const int count = 260;
      for (int i = 0; i < count; ++i) {
        const double r = std::exp(rng.Uniform(std::log(3.0), std::log(28.0)));
        AddBlob(&m, rng.Uniform(0, kN), rng.Uniform(0, kN), r, rng.Uniform() < 0.5 ? -1.2 : 1.2);
      }
      Standardise(&m);
      return m;
    }
    case TexturePattern::kBricks: {
      constexpr int kBrickW = 64, kBrickH = 16, kMortar = 3;  // texels (powers of two divide kN)
      cv::Mat m(kN, kN, CV_32F);
      std::vector<float> shade((kN / kBrickW) * (kN / kBrickH));
      for (float& s : shade) s = static_cast<float>(rng.Uniform(-1.0, 1.0));
      for (int y = 0; y < kN; ++y) {
        const int row = y / kBrickH;
        const int shift = (row % 2) * (kBrickW / 2);
        for (int x = 0; x < kN; ++x) {
          const int xs = (x + shift) % kN;
          const int col = xs / kBrickW;
          const bool mortar = (y % kBrickH) < kMortar || (xs % kBrickW) < kMortar;
          m.at<float>(y, x) = mortar ? 2.2f : shade[row * (kN / kBrickW) + col];
        }
      }
      cv::Mat blurred;
      // Soften the joints a little (wrap by padding) so the pattern stays band-limited.
      cv::Mat padded;
      cv::copyMakeBorder(m, padded, 4, 4, 4, 4, cv::BORDER_WRAP);
      cv::GaussianBlur(padded, blurred, cv::Size(5, 5), 0.8);
      m = blurred(cv::Rect(4, 4, kN, kN)) + FractalNoise(64, 2, 0.6, rng) * 0.45;
      Standardise(&m);
      return m;
    }
    case TexturePattern::kPlanks: {
      cv::Mat m(kN, kN, CV_32F);
      constexpr int kPlank = 64;
      std::vector<float> shade(kN / kPlank);
      for (float& s : shade) s = static_cast<float>(rng.Uniform(-1.2, 1.2));
      cv::Mat grain = FractalNoise(32, 2, 0.5, rng);
      for (int y = 0; y < kN; ++y) {
        for (int x = 0; x < kN; ++x) {
          // Grain is stretched along v: sample the noise with x scaled up, y scaled down.
          const float g = grain.at<float>((y / 8) % kN, (x * 4) % kN);
          const bool gap = (x % kPlank) < 2;
          m.at<float>(y, x) = gap ? -2.5f : shade[x / kPlank] + 0.6f * g;
        }
      }
      Standardise(&m);
      return m;
    }
    case TexturePattern::kSpeckle: {
      cv::Mat m = FractalNoise(128, 16, 0.8, rng) * 0.6 + FractalNoise(8, 2, 0.3, rng);
      for (int i = 0; i < 1500; ++i) {
        AddBlob(&m, rng.Uniform(0, kN), rng.Uniform(0, kN), rng.Uniform(1.5, 4.0),
                rng.Uniform() < 0.5 ? -2.0 : 2.0);
      }
      Standardise(&m);
      return m;
    }
    case TexturePattern::kChecker: {
      cv::Mat m(kN, kN, CV_32F);
      constexpr int kSquare = 16;
      for (int y = 0; y < kN; ++y) {
        for (int x = 0; x < kN; ++x) {
          m.at<float>(y, x) = ((x / kSquare + y / kSquare) % 2) ? 1.0f : -1.0f;
        }
      }
      return m;
    }
  }
  return cv::Mat(kN, kN, CV_32F, cv::Scalar(0));
}

}  // namespace

Texture::Texture(std::vector<std::vector<float>> levels, float texel_size_m)
    : levels_(std::move(levels)),
      texel_size_m_(texel_size_m),
      inv_texel_size_m_(1.0f / texel_size_m) {
  MAV_CHECK(!levels_.empty() && texel_size_m > 0);
  MAV_CHECK(static_cast<int>(levels_.size()) <= kMaxLevels);
  texels_.resize(levels_.size());
  for (size_t l = 0; l < levels_.size(); ++l) {
    const int n = kSize >> l;
    MAV_CHECK(levels_[l].size() == static_cast<size_t>(n) * n);
    // Stored size: at least one block per side (small levels repeat, they wrap anyway).
    const int stored = std::max(n, kBlockW);
    texels_[l].resize(static_cast<size_t>(stored) * stored * 4);
    auto texel = [&](int x, int y) {
      const float a = levels_[l][static_cast<size_t>(y % n) * n + x % n];
      return static_cast<uint16_t>(std::round(std::clamp(a, 0.0f, 1.0f) / kAlbedoPerTexel));
    };
    for (int y = 0; y < stored; ++y) {
      for (int x = 0; x < stored; ++x) {
        uint16_t* q = texels_[l].data() + 4 * (BlockRow(y, stored) + BlockColumn(x));
        q[0] = texel(x, y);
        q[1] = texel(x + 1, y);
        q[2] = texel(x, y + 1);
        q[3] = texel(x + 1, y + 1);
      }
    }
    level_data_[l] = texels_[l].data();
    level_scale_[l] = inv_texel_size_m_ / static_cast<float>(1 << l);
    level_size_[l] = stored;
  }
  const size_t last = levels_.size() - 1;
  level_data_[last + 1] = level_data_[last];
  level_scale_[last + 1] = level_scale_[last];
  level_size_[last + 1] = level_size_[last];
  last_level_ = static_cast<int>(levels_.size()) - 1;
  top_pair_ = std::max(last_level_ - 1, 0);
  max_level_ = static_cast<float>(last_level_);
}

std::shared_ptr<const Texture> GenerateTexture(const Material& material, uint64_t seed) {
  internal::Rng rng(
      internal::HashCombine(seed, static_cast<uint64_t>(material.pattern) * 7919 +
                                      static_cast<uint64_t>(material.albedo * 1e4) +
                                      static_cast<uint64_t>(material.contrast * 1e7)));
  cv::Mat pattern = Pattern(material, rng);
  float texel = material.texel_size_m;
  float low = 0.0f, high = 1.0f;
  if (material.pattern == TexturePattern::kChecker) {
    texel = material.checker_square_m / 16.0f;
    low = 0.06f;
    high = 0.94f;
  }
  std::vector<std::vector<float>> levels;
  std::vector<float> base(static_cast<size_t>(kN) * kN);
  for (int y = 0; y < kN; ++y) {
    const float* row = pattern.ptr<float>(y);
    for (int x = 0; x < kN; ++x) {
      float a;
      if (material.pattern == TexturePattern::kChecker) {
        a = row[x] > 0 ? high : low;
      } else {
        a = std::clamp(material.albedo + material.contrast * row[x], 0.02f, 1.0f);
      }
      base[static_cast<size_t>(y) * kN + x] = a;
    }
  }
  levels.push_back(std::move(base));
  // Box-filtered pyramid (exactly tileable: sizes are powers of two).
  for (int size = kN / 2; size >= 1; size /= 2) {
    const std::vector<float>& prev = levels.back();
    const int ps = size * 2;
    std::vector<float> next(static_cast<size_t>(size) * size);
    for (int y = 0; y < size; ++y) {
      for (int x = 0; x < size; ++x) {
        const size_t i = static_cast<size_t>(2 * y) * ps + 2 * x;
        next[static_cast<size_t>(y) * size + x] =
            0.25f * (prev[i] + prev[i + 1] + prev[i + ps] + prev[i + ps + 1]);
      }
    }
    levels.push_back(std::move(next));
  }
  return std::make_shared<Texture>(std::move(levels), texel);
}

}  // namespace mav::sim
