#include "mav/localization/dense_vo.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <sstream>
#include <utility>
#include <vector>

#include <Eigen/Cholesky>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "input_checks.h"
#include "mav/common/time.h"

namespace mav::localization {
namespace {

using geometry::SE3;
using internal::CheckImage;
using Matrix8d = Eigen::Matrix<double, 8, 8>;
using Vector8d = Eigen::Matrix<double, 8, 1>;
using JacobianMatrix = Eigen::Matrix<float, Eigen::Dynamic, 8>;

constexpr double kRadToDeg = 180.0 / M_PI;

bool IsFinite(const SE3& T) {
  return T.Rotation().coeffs().allFinite() && T.Translation().allFinite();
}

double RotationDeg(const SE3& T) { return geometry::LogSO3(T.Rotation()).norm() * kRadToDeg; }

// The effective Jacobian at log gain a is the static one times D = diag(exp(a) x 7, 1) (the
// static Jacobian is taken for gain 1; the bias column does not scale).
Vector8d GainScaling(double a) {
  Vector8d d = Vector8d::Constant(std::exp(a));
  d[7] = 1.0;
  return d;
}

// Pinhole intrinsics of one pyramid level. cv::pyrDown keeps pixel (2u, 2v) of the finer level
// at (u, v), so the intrinsics halve exactly: fx_l = fx / 2^l, cx_l = cx / 2^l.
struct LevelCamera {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  int width = 0, height = 0;
};

// The selected pixels of one keyframe level, structure-of-arrays for the hot loop.
struct KeyframeLevel {
  std::vector<float> x, y, z;    // 3D point in the keyframe camera, metres
  std::vector<float> intensity;  // keyframe intensity I_kf
  // Static Jacobian rows: columns 0-5 d r / d xi (inverse compositional, for gain 1), column 6
  // d r / d a (for gain 1) = -I_kf, column 7 d r / d b = -1. The effective Jacobian at gain
  // exp(a) multiplies columns 0-6 by exp(a).
  JacobianMatrix jacobian;
  int size() const { return static_cast<int>(x.size()); }
};

struct Keyframe {
  std::vector<KeyframeLevel> levels;  // indexed by pyramid level; empty below finest_level
  SE3 T_world_kf;
};

// Robust weight for a residual normalised by the scale (s = r / sigma).
struct RobustWeighting {
  DenseRobustLoss loss = DenseRobustLoss::kStudentT;
  float nu = 5.f;
  float huber_k = 1.345f;
  float sigma = 1.f;

  float Weight(float r) const {
    const float s = r / sigma;
    switch (loss) {
      case DenseRobustLoss::kStudentT:
        return (nu + 1.f) / (nu + s * s);
      case DenseRobustLoss::kHuber: {
        const float a = std::abs(s);
        return a <= huber_k ? 1.f : huber_k / a;
      }
      case DenseRobustLoss::kNone:
        return 1.f;
    }
    return 1.f;
  }
  // rho(r) / sigma^2, up to constants: the cost the weights are the IRLS weights of.
  float Cost(float r) const {
    const float s = r / sigma;
    switch (loss) {
      case DenseRobustLoss::kStudentT:
        return 0.5f * (nu + 1.f) * std::log1p(s * s / nu);
      case DenseRobustLoss::kHuber: {
        const float a = std::abs(s);
        return a <= huber_k ? 0.5f * s * s : huber_k * (a - 0.5f * huber_k);
      }
      case DenseRobustLoss::kNone:
        return 0.5f * s * s;
    }
    return 0.5f * s * s;
  }
};

}  // namespace

// ---------------------------------------------------------------------------------------------
// Building blocks.

Eigen::Matrix<double, 2, 6> ProjectionTwistJacobian(const Eigen::Vector3d& p, double fx,
                                                    double fy) {
  const double inv_z = 1.0 / p.z();
  const double x = p.x() * inv_z, y = p.y() * inv_z;
  Eigen::Matrix<double, 2, 3> d_pi_d_p;
  d_pi_d_p << fx * inv_z, 0, -fx * x * inv_z,  //
      0, fy * inv_z, -fy * y * inv_z;
  // d (Exp(xi) p) / d xi at 0 = [I, -Hat(p)] for xi = (rho, phi).
  Eigen::Matrix<double, 3, 6> d_p_d_xi;
  d_p_d_xi.leftCols<3>().setIdentity();
  d_p_d_xi.rightCols<3>() = -geometry::Hat(p);
  return d_pi_d_p * d_p_d_xi;
}

float SampleBilinear(const cv::Mat& image, float u, float v) {
  const int u0 = static_cast<int>(u), v0 = static_cast<int>(v);
  const float fu = u - u0, fv = v - v0;
  const float* row0 = image.ptr<float>(v0) + u0;
  const float* row1 = image.ptr<float>(v0 + 1) + u0;
  const float top = row0[0] + fu * (row0[1] - row0[0]);
  const float bottom = row1[0] + fu * (row1[1] - row1[0]);
  return top + fv * (bottom - top);
}

Eigen::Matrix<double, 1, 6> PhotometricJacobian(const cv::Mat& image, int u, int v,
                                                const Eigen::Vector3d& p, double fx, double fy) {
  const float* row = image.ptr<float>(v);
  const Eigen::RowVector2d gradient(
      0.5 * (row[u + 1] - row[u - 1]),
      0.5 * (image.ptr<float>(v + 1)[u] - image.ptr<float>(v - 1)[u]));
  return gradient * ProjectionTwistJacobian(p, fx, fy);
}

bool DenseVoOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why != nullptr) *why = m;
    return false;
  };
  if (num_levels < 1 || num_levels > 6) return fail("num_levels: must be in [1, 6]");
  if (finest_level < 0 || finest_level >= num_levels) {
    return fail("finest_level: must be in [0, num_levels)");
  }
  if (!(min_gradient >= 0)) return fail("min_gradient: must be >= 0");
  if (max_pixels_per_level < 16) return fail("max_pixels_per_level: must be >= 16");
  if (depth_level < 0 || depth_level > 2 || depth_level >= num_levels) {
    return fail("depth_level: must be in [0, min(2, num_levels - 1)]");
  }
  if (num_disparities < 16 || num_disparities % 16 != 0) {
    return fail("num_disparities: must be a positive multiple of 16");
  }
  if (block_size < 5 || block_size > 51 || block_size % 2 == 0) {
    return fail("block_size: must be odd and in [5, 51]");
  }
  if (sgbm_block_size < 3 || sgbm_block_size > 11 || sgbm_block_size % 2 == 0) {
    return fail("sgbm_block_size: must be odd and in [3, 11]");
  }
  if (texture_threshold < 0) return fail("texture_threshold: must be >= 0");
  if (uniqueness_ratio < 0) return fail("uniqueness_ratio: must be >= 0");
  if (speckle_window_size < 0) return fail("speckle_window_size: must be >= 0");
  if (speckle_range < 0) return fail("speckle_range: must be >= 0");
  if (!(min_depth_m > 0) || !(max_depth_m > min_depth_m)) {
    return fail("min_depth_m/max_depth_m: need 0 < min_depth_m < max_depth_m");
  }
  if (max_iterations_per_level < 1) return fail("max_iterations_per_level: must be >= 1");
  if (!(min_step > 0)) return fail("min_step: must be > 0");
  if (!(initial_lambda >= 0)) return fail("initial_lambda: must be >= 0");
  if (!(student_t_nu > 0)) return fail("student_t_nu: must be > 0");
  if (!(huber_k > 0)) return fail("huber_k: must be > 0");
  if (!(keyframe_max_rotation_deg > 0)) return fail("keyframe_max_rotation_deg: must be > 0");
  if (!(keyframe_max_translation_m > 0)) return fail("keyframe_max_translation_m: must be > 0");
  if (!(keyframe_max_rms_error > 0)) return fail("keyframe_max_rms_error: must be > 0");
  if (!(keyframe_min_visible_fraction >= 0 && keyframe_min_visible_fraction <= 1)) {
    return fail("keyframe_min_visible_fraction: must be in [0, 1]");
  }
  if (!(max_refined_disparity_rms > 0)) return fail("max_refined_disparity_rms: must be > 0");
  if (min_pixels < 8) return fail("min_pixels: must be >= 8");
  if (!(max_rms_error > 0)) return fail("max_rms_error: must be > 0");
  if (!(max_brightness_gain_change > 1)) return fail("max_brightness_gain_change: must be > 1");
  if (!(min_image_contrast >= 0)) return fail("min_image_contrast: must be >= 0");
  if (!(max_translation_per_frame_m > 0)) return fail("max_translation_per_frame_m: must be > 0");
  if (!(max_rotation_per_frame_deg > 0)) return fail("max_rotation_per_frame_deg: must be > 0");
  if (!(max_gyro_rotation_error_deg > 0)) return fail("max_gyro_rotation_error_deg: must be > 0");
  if (!(max_acceleration_mps2 >= 0)) return fail("max_acceleration_mps2: must be >= 0");
  if (!(motion_check_floor_m > 0)) return fail("motion_check_floor_m: must be > 0");
  if (!(min_support_fraction >= 0 && min_support_fraction <= 1)) {
    return fail("min_support_fraction: must be in [0, 1]");
  }
  if (!(max_rms_growth > 1)) return fail("max_rms_growth: must be > 1");
  if (max_degraded_frames < 0) return fail("max_degraded_frames: must be >= 0");
  if (!(rotation_prior_weight >= 0)) return fail("rotation_prior_weight: must be >= 0");
  return true;
}

// ---------------------------------------------------------------------------------------------

struct DenseVo::Impl {
  camera::RectifiedStereo rig;
  DenseVoOptions options;
  SE3 T_world_cam0;
  std::vector<LevelCamera> cameras;
  cv::Ptr<cv::StereoMatcher> stereo_matcher;

  // Tracking state.
  bool has_keyframe = false;
  Keyframe keyframe;
  SE3 T_world_cam;
  // The last OK frame: its pose in the keyframe and its stamp. DEGRADED frames do not move it, so
  // the next frame is predicted and checked from the last measurement, not from a prediction.
  SE3 T_kf_prev;
  int64_t t_ok_ns = 0;
  // Velocity (twist per second, SE3::Log order) measured between the last two OK frames.
  geometry::Vector6d velocity = geometry::Vector6d::Zero();
  bool velocity_valid = false;
  // Gyro rotation from the last OK frame to the previous frame (identity when the previous frame
  // was the OK one); invalid when a frame since came without a hint.
  Eigen::Quaterniond R_ok_prev_gyro = Eigen::Quaterniond::Identity();
  bool gyro_chain_valid = true;
  double rms_mean = 0;   // running mean of the OK frames' RMS error (0 = none yet)
  int degraded_run = 0;  // DEGRADED frames in a row
  int ok_run = 0;        // OK frames in a row since the last reset (the velocity is checked
                         // once two of them agree)
  double log_gain = 0, bias = 0;
  int64_t frames = 0;
  int64_t keyframes = 0;

  // Scratch buffers (kept to avoid reallocations).
  std::vector<cv::Mat> pyramid;        // CV_32FC1 left image pyramid of the current frame
  std::vector<cv::Mat> right_pyramid;  // the same for the right image, keyframes only
  std::vector<float> residuals, valid, weights;
  JacobianMatrix weighted_jacobian;

  // After a loss or a reset: no velocity, no degraded run, no residual history.
  void ForgetMotion() {
    T_kf_prev = SE3();
    t_ok_ns = 0;
    velocity.setZero();
    velocity_valid = false;
    R_ok_prev_gyro.setIdentity();
    gyro_chain_valid = true;
    degraded_run = 0;
    ok_run = 0;
    rms_mean = 0;
  }

  void BuildPyramid(const cv::Mat& left) {
    pyramid.resize(options.num_levels);
    left.convertTo(pyramid[0], CV_32F);
    for (int l = 1; l < options.num_levels; ++l) cv::pyrDown(pyramid[l - 1], pyramid[l]);
  }

  // Block matching at depth_level; returns the depth map (CV_32FC1, 0 = invalid) at that level.
  cv::Mat ComputeDepth(const cv::Mat& left, const cv::Mat& right) {
    cv::Mat l8 = left, r8 = right;
    for (int l = 0; l < options.depth_level; ++l) {
      cv::Mat tl, tr;
      cv::pyrDown(l8, tl);
      cv::pyrDown(r8, tr);
      l8 = tl;
      r8 = tr;
    }
    cv::Mat disparity16;
    stereo_matcher->compute(l8, r8, disparity16);
    const LevelCamera& cam = cameras[options.depth_level];
    cv::Mat dmax, dmin;
    if (options.filter_discontinuities) {
      // Min/max filters over the matching window; invalid disparities (< 0) must not count
      // as minima, so they are raised above any valid value first.
      const int window = options.matcher == DenseStereoMatcher::kBlockMatching
                             ? options.block_size
                             : options.sgbm_block_size + 2;
      const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(window, window));
      cv::Mat raised = disparity16.clone();
      raised.setTo(cv::Scalar(32767), disparity16 <= 0);
      cv::dilate(disparity16, dmax, kernel);
      cv::erode(raised, dmin, kernel);
    }
    const float fb = static_cast<float>(cam.fx * rig.baseline);
    const float min_d = static_cast<float>(options.min_depth_m);
    const float max_d = static_cast<float>(options.max_depth_m);
    cv::Mat depth(disparity16.size(), CV_32F);
    for (int v = 0; v < depth.rows; ++v) {
      const int16_t* d = disparity16.ptr<int16_t>(v);
      float* z = depth.ptr<float>(v);
      for (int u = 0; u < depth.cols; ++u) {
        float zz = 0.f;
        bool smooth = true;
        if (!dmax.empty()) {
          const int jump = dmax.ptr<int16_t>(v)[u] - dmin.ptr<int16_t>(v)[u];
          smooth = jump <= std::max(16, d[u] / 10);
        }
        if (d[u] > 0 && smooth) {
          zz = fb * 16.f / static_cast<float>(d[u]);
          if (zz < min_d || zz > max_d) zz = 0.f;
        }
        z[u] = zz;
      }
    }
    return depth;
  }

  // Depth of pixel (u, v) of `level` from the depth map at depth_level; 0 if unknown or at a
  // depth discontinuity (inverse depths of the footprint differ by more than 10 %).
  float DepthAt(const cv::Mat& depth, int level, int u, int v) const {
    const int d = options.depth_level;
    if (level >= d) {
      const int s = 1 << (level - d);
      const int cu = u * s, cv_ = v * s;
      const int r = s / 2;
      float lo = std::numeric_limits<float>::max(), hi = 0.f, sum = 0.f;
      int n = 0;
      for (int y = std::max(0, cv_ - r); y <= std::min(depth.rows - 1, cv_ + r); ++y) {
        const float* row = depth.ptr<float>(y);
        for (int x = std::max(0, cu - r); x <= std::min(depth.cols - 1, cu + r); ++x) {
          if (row[x] <= 0.f) continue;
          const float inv = 1.f / row[x];
          lo = std::min(lo, inv);
          hi = std::max(hi, inv);
          sum += inv;
          ++n;
        }
      }
      const int area = (std::min(depth.rows - 1, cv_ + r) - std::max(0, cv_ - r) + 1) *
                       (std::min(depth.cols - 1, cu + r) - std::max(0, cu - r) + 1);
      if (n * 2 < area + 1 || hi > 1.1f * lo) return 0.f;
      return static_cast<float>(n) / sum;
    }
    // Finer than the depth map: bilinear in inverse depth over the 4 neighbours, all valid
    // and consistent.
    const float s = 1.f / static_cast<float>(1 << (d - level));
    const float fu = u * s, fv = v * s;
    const int u0 = static_cast<int>(fu), v0 = static_cast<int>(fv);
    if (u0 + 1 >= depth.cols || v0 + 1 >= depth.rows) return 0.f;
    const float z00 = depth.ptr<float>(v0)[u0], z01 = depth.ptr<float>(v0)[u0 + 1];
    const float z10 = depth.ptr<float>(v0 + 1)[u0], z11 = depth.ptr<float>(v0 + 1)[u0 + 1];
    if (z00 <= 0.f || z01 <= 0.f || z10 <= 0.f || z11 <= 0.f) return 0.f;
    const float i00 = 1.f / z00, i01 = 1.f / z01, i10 = 1.f / z10, i11 = 1.f / z11;
    const float lo = std::min({i00, i01, i10, i11}), hi = std::max({i00, i01, i10, i11});
    if (hi > 1.1f * lo) return 0.f;
    const float a = fu - u0, b = fv - v0;
    const float inv = (1 - b) * ((1 - a) * i00 + a * i01) + b * ((1 - a) * i10 + a * i11);
    return 1.f / inv;
  }

  // Refines the disparity of left pixel (u, v) of `level` by Gauss-Newton on the photometric
  // error of a 5x5 patch against the right image, sampled bilinearly along the row (a 1-D
  // Lucas-Kanade step; the patch mean difference is removed, so it is insensitive to a gain
  // offset between the cameras). Returns the refined disparity, or 0 if the refinement leaves
  // the image, moves more than 1 pixel or ends with a large error.
  float RefineDisparity(int level, int u, int v, float disparity) const {
    const cv::Mat& left = pyramid[level];
    const cv::Mat& right = right_pyramid[level];
    constexpr int kRadius = 2;
    if (u - kRadius < 1 || v - kRadius < 0 || u + kRadius >= left.cols - 1 ||
        v + kRadius >= left.rows) {
      return 0.f;
    }
    float patch[2 * kRadius + 1][2 * kRadius + 1];
    float mean_left = 0.f;
    for (int dy = -kRadius; dy <= kRadius; ++dy) {
      for (int dx = -kRadius; dx <= kRadius; ++dx) {
        patch[dy + kRadius][dx + kRadius] = left.ptr<float>(v + dy)[u + dx];
        mean_left += left.ptr<float>(v + dy)[u + dx];
      }
    }
    mean_left /= (2 * kRadius + 1) * (2 * kRadius + 1);
    float d = disparity;
    float rms = 0.f;
    for (int iteration = 0; iteration < 4; ++iteration) {
      const float x0 = u - d;
      if (x0 - kRadius < 1.f || x0 + kRadius >= right.cols - 2) return 0.f;
      float values[2 * kRadius + 1][2 * kRadius + 1];
      float grads[2 * kRadius + 1][2 * kRadius + 1];
      float mean_right = 0.f, mean_grad = 0.f;
      for (int dy = -kRadius; dy <= kRadius; ++dy) {
        const float* row = right.ptr<float>(v + dy);
        for (int dx = -kRadius; dx <= kRadius; ++dx) {
          const float x = x0 + dx;
          const int xi = static_cast<int>(x);
          const float f = x - xi;
          const float value = row[xi] + f * (row[xi + 1] - row[xi]);
          // Gradient of the bilinear interpolant's smooth version: central differences,
          // interpolated.
          const float g0 = 0.5f * (row[xi + 1] - row[xi - 1]);
          const float g1 = 0.5f * (row[xi + 2] - row[xi]);
          values[dy + kRadius][dx + kRadius] = value;
          grads[dy + kRadius][dx + kRadius] = g0 + f * (g1 - g0);
          mean_right += value;
          mean_grad += grads[dy + kRadius][dx + kRadius];
        }
      }
      constexpr float kCount = (2 * kRadius + 1) * (2 * kRadius + 1);
      mean_right /= kCount;
      mean_grad /= kCount;
      // r = (I_R(x - d) - mean_R) - (I_L - mean_L); dr/dd = -(g - mean_g).
      float jtj = 0.f, jtr = 0.f, r2 = 0.f;
      for (int y = 0; y < 2 * kRadius + 1; ++y) {
        for (int x = 0; x < 2 * kRadius + 1; ++x) {
          const float r = (values[y][x] - mean_right) - (patch[y][x] - mean_left);
          const float j = -(grads[y][x] - mean_grad);
          jtj += j * j;
          jtr += j * r;
          r2 += r * r;
        }
      }
      rms = std::sqrt(r2 / kCount);
      if (jtj < 1e-3f) return 0.f;
      const float step = -jtr / jtj;
      d += std::clamp(step, -0.5f, 0.5f);
      if (std::abs(step) < 0.01f) break;
    }
    if (!(std::abs(d - disparity) <= 1.f) || d <= 0.f ||
        rms > static_cast<float>(options.max_refined_disparity_rms)) {
      return 0.f;
    }
    return d;
  }

  // Selects the pixels of one level and precomputes their points and Jacobians.
  void BuildKeyframeLevel(const cv::Mat& depth, int level, KeyframeLevel* out) const {
    const cv::Mat& image = pyramid[level];
    const LevelCamera& cam = cameras[level];
    const float min_g2 = static_cast<float>(options.min_gradient * options.min_gradient);
    struct Candidate {
      int u, v;
      float g2, z;
    };
    std::vector<Candidate> candidates;
    candidates.reserve(image.total() / 4);
    const int border = 2;
    for (int v = border; v < image.rows - border; ++v) {
      const float* row = image.ptr<float>(v);
      const float* up = image.ptr<float>(v - 1);
      const float* down = image.ptr<float>(v + 1);
      for (int u = border; u < image.cols - border; ++u) {
        const float gx = 0.5f * (row[u + 1] - row[u - 1]);
        const float gy = 0.5f * (down[u] - up[u]);
        const float g2 = gx * gx + gy * gy;
        if (g2 < min_g2) continue;
        const float z = DepthAt(depth, level, u, v);
        if (z <= 0.f) continue;
        candidates.push_back({u, v, g2, z});
      }
    }
    const int budget = options.max_pixels_per_level;
    if (static_cast<int>(candidates.size()) > budget) {
      // Keep the strongest pixel per square cell; cells sized so that a full image gives about
      // `budget` cells.
      const int cell = std::max(
          2, static_cast<int>(std::ceil(std::sqrt(static_cast<double>(image.total()) / budget))));
      const int cells_x = (image.cols + cell - 1) / cell;
      const int cells_y = (image.rows + cell - 1) / cell;
      std::vector<int> best(static_cast<size_t>(cells_x) * cells_y, -1);
      for (int i = 0; i < static_cast<int>(candidates.size()); ++i) {
        const int c = (candidates[i].v / cell) * cells_x + candidates[i].u / cell;
        if (best[c] < 0 || candidates[best[c]].g2 < candidates[i].g2) best[c] = i;
      }
      std::vector<Candidate> kept;
      kept.reserve(budget);
      for (int b : best) {
        if (b >= 0) kept.push_back(candidates[b]);
      }
      candidates.swap(kept);
    }
    if (options.refine_disparity) {
      // Sub-pixel refinement on this level's pair; pixels whose refinement fails are dropped.
      size_t kept = 0;
      for (const Candidate& c : candidates) {
        const float disparity = static_cast<float>(cam.fx * rig.baseline) / c.z;
        const float refined = RefineDisparity(level, c.u, c.v, disparity);
        if (refined <= 0.f) continue;
        candidates[kept] = c;
        candidates[kept].z = static_cast<float>(cam.fx * rig.baseline) / refined;
        ++kept;
      }
      candidates.resize(kept);
    }
    const int n = static_cast<int>(candidates.size());
    out->x.resize(n);
    out->y.resize(n);
    out->z.resize(n);
    out->intensity.resize(n);
    out->jacobian.resize(n, 8);
    for (int i = 0; i < n; ++i) {
      const Candidate& c = candidates[i];
      const Eigen::Vector3d p(c.z * (c.u - cam.cx) / cam.fx, c.z * (c.v - cam.cy) / cam.fy, c.z);
      out->x[i] = static_cast<float>(p.x());
      out->y[i] = static_cast<float>(p.y());
      out->z[i] = static_cast<float>(p.z());
      const float intensity = image.ptr<float>(c.v)[c.u];
      out->intensity[i] = intensity;
      // Inverse compositional: r = I_cur(w(x)) - (I_kf(pi(Exp(xi) p)) ...), so d r / d xi is
      // minus the photometric Jacobian of the keyframe.
      const Eigen::Matrix<double, 1, 6> j = PhotometricJacobian(image, c.u, c.v, p, cam.fx, cam.fy);
      for (int k = 0; k < 6; ++k) out->jacobian(i, k) = static_cast<float>(-j[k]);
      out->jacobian(i, 6) = -intensity;
      out->jacobian(i, 7) = -1.f;
    }
  }

  // Builds a keyframe from the current pyramid and pair. Returns an empty string on success,
  // otherwise why it failed.
  std::string BuildKeyframe(const cv::Mat& left, const cv::Mat& right, const SE3& T_world_kf) {
    const cv::Mat depth = ComputeDepth(left, right);
    if (options.refine_disparity) {
      right_pyramid.resize(options.num_levels);
      right.convertTo(right_pyramid[0], CV_32F);
      for (int l = 1; l < options.num_levels; ++l) {
        cv::pyrDown(right_pyramid[l - 1], right_pyramid[l]);
      }
    }
    Keyframe kf;
    kf.T_world_kf = T_world_kf;
    kf.levels.resize(options.num_levels);
    for (int l = options.finest_level; l < options.num_levels; ++l) {
      BuildKeyframeLevel(depth, l, &kf.levels[l]);
    }
    const int n = kf.levels[options.finest_level].size();
    if (n < options.min_pixels) {
      std::ostringstream msg;
      msg << "keyframe has only " << n << " pixels with depth and gradient on level "
          << options.finest_level << " (min_pixels " << options.min_pixels << ")";
      return msg.str();
    }
    keyframe = std::move(kf);
    has_keyframe = true;
    ++keyframes;
    log_gain = 0;
    bias = 0;
    return {};
  }

  // Residuals of every keyframe pixel of `level` at motion T_cur_kf and brightness (gain,
  // bias); valid[i] is 1 where the pixel lands inside the image. Returns the number valid.
  int Evaluate(int level, const SE3& T_cur_kf, float gain, float b) {
    const KeyframeLevel& kf = keyframe.levels[level];
    const cv::Mat& image = pyramid[level];
    const LevelCamera& cam = cameras[level];
    const int n = kf.size();
    residuals.resize(n);
    valid.resize(n);
    const Eigen::Matrix3f R = T_cur_kf.RotationMatrix().cast<float>();
    const Eigen::Vector3f t = T_cur_kf.Translation().cast<float>();
    const float fx = static_cast<float>(cam.fx), fy = static_cast<float>(cam.fy);
    const float cx = static_cast<float>(cam.cx), cy = static_cast<float>(cam.cy);
    const float max_u = static_cast<float>(cam.width - 1) - 1e-3f;
    const float max_v = static_cast<float>(cam.height - 1) - 1e-3f;
    const float min_z = static_cast<float>(options.min_depth_m) * 0.5f;
    const float* xs = kf.x.data();
    const float* ys = kf.y.data();
    const float* zs = kf.z.data();
    const float* is = kf.intensity.data();
    const size_t step = image.step[0] / sizeof(float);
    const float* data = image.ptr<float>(0);
    int count = 0;
    for (int i = 0; i < n; ++i) {
      const float X = R(0, 0) * xs[i] + R(0, 1) * ys[i] + R(0, 2) * zs[i] + t[0];
      const float Y = R(1, 0) * xs[i] + R(1, 1) * ys[i] + R(1, 2) * zs[i] + t[1];
      const float Z = R(2, 0) * xs[i] + R(2, 1) * ys[i] + R(2, 2) * zs[i] + t[2];
      const float inv_z = 1.f / Z;
      const float u = fx * X * inv_z + cx;
      const float v = fy * Y * inv_z + cy;
      // Written so that NaN fails the test.
      if (!(Z > min_z && u >= 0.f && v >= 0.f && u < max_u && v < max_v)) {
        residuals[i] = 0.f;
        valid[i] = 0.f;
        continue;
      }
      const int u0 = static_cast<int>(u), v0 = static_cast<int>(v);
      const float fu = u - u0, fv = v - v0;
      const float* p0 = data + v0 * step + u0;
      const float* p1 = p0 + step;
      const float top = p0[0] + fu * (p0[1] - p0[0]);
      const float bottom = p1[0] + fu * (p1[1] - p1[0]);
      residuals[i] = top + fv * (bottom - top) - (gain * is[i] + b);
      valid[i] = 1.f;
      ++count;
    }
    return count;
  }

  // The robust scale of the valid residuals: Student-t as Kerl et al. (fixed point of
  // sigma^2 = mean(r^2 (nu + 1) / (nu + r^2 / sigma^2))), or 1.4826 * MAD for Huber.
  float EstimateScale(int count, float previous_sigma = 0.f) {
    constexpr float kMinSigma = 0.05f;
    if (count == 0) return 1.f;
    const int n = static_cast<int>(residuals.size());
    if (options.loss == DenseRobustLoss::kHuber) {
      weights.clear();
      for (int i = 0; i < n; ++i) {
        if (valid[i] > 0.f) weights.push_back(std::abs(residuals[i]));
      }
      auto mid = weights.begin() + static_cast<std::ptrdiff_t>(weights.size() / 2);
      std::nth_element(weights.begin(), mid, weights.end());
      return std::max(kMinSigma, 1.4826f * *mid);
    }
    double sum2 = 0;
    for (int i = 0; i < n; ++i) sum2 += valid[i] * residuals[i] * residuals[i];
    double sigma2 = std::max<double>(sum2 / count, kMinSigma * kMinSigma);
    if (options.loss == DenseRobustLoss::kNone) return static_cast<float>(std::sqrt(sigma2));
    // The fixed point lies below the plain RMS; start from the previous estimate when there
    // is one (it changes little between iterations).
    if (previous_sigma > kMinSigma) sigma2 = previous_sigma * previous_sigma;
    const float nu = static_cast<float>(options.student_t_nu);
    for (int iteration = 0; iteration < 10; ++iteration) {
      const float inv = static_cast<float>(1.0 / sigma2);
      double acc = 0;
      for (int i = 0; i < n; ++i) {
        const float r2 = residuals[i] * residuals[i];
        acc += valid[i] * r2 * (nu + 1.f) / (nu + r2 * inv);
      }
      const double next = std::max<double>(acc / count, kMinSigma * kMinSigma);
      const bool converged = std::abs(next - sigma2) < 1e-3 * sigma2;
      sigma2 = next;
      if (converged) break;
    }
    return static_cast<float>(std::sqrt(sigma2));
  }

  // Weights, mean robust cost, and (if H != nullptr) the normal equations of the static
  // Jacobian: H = J^T W J, g = J^T W r.
  double WeightAndCost(const RobustWeighting& rw, int count, Matrix8d* H, Vector8d* g,
                       double* weighted_rms, int level) {
    const int n = static_cast<int>(residuals.size());
    weights.resize(n);
    double cost = 0, wr2 = 0, wsum = 0;
    for (int i = 0; i < n; ++i) {
      const float w = valid[i] * rw.Weight(residuals[i]);
      weights[i] = w;
      cost += valid[i] * rw.Cost(residuals[i]);
      wr2 += w * residuals[i] * residuals[i];
      wsum += w;
    }
    if (weighted_rms != nullptr) *weighted_rms = wsum > 0 ? std::sqrt(wr2 / wsum) : 0.0;
    if (H != nullptr) {
      const JacobianMatrix& J = keyframe.levels[level].jacobian;
      const Eigen::Map<const Eigen::VectorXf> w(weights.data(), n);
      const Eigen::Map<const Eigen::VectorXf> r(residuals.data(), n);
      weighted_jacobian.resize(n, 8);
      weighted_jacobian = J.array().colwise() * w.array();
      const Eigen::Matrix<float, 8, 8> Hf = weighted_jacobian.transpose() * J;
      const Eigen::Matrix<float, 8, 1> gf = weighted_jacobian.transpose() * r;
      *H = Hf.cast<double>();
      *g = gf.cast<double>();
    }
    return count > 0 ? cost / count : std::numeric_limits<double>::infinity();
  }

  struct AlignStats {
    int iterations = 0;
    int used = 0;
    double rms = 0;
    // With a rotation prior: the angle between the rotation the pixels alone support and the
    // prior [deg].
    double vision_prior_angle_deg = 0;
  };

  // Coarse-to-fine Levenberg-Marquardt over (xi, a, b). T_cur_kf, log_gain, bias are updated
  // in place.
  //
  // With `rotation_prior` (the predicted rotation P of T_cur_kf, from the gyro) the cost gains
  // 0.5 w |Log(R P^-1)|^2 in the units of the normal equations, w = rotation_prior_weight times
  // the mean diagonal of the photometric rotation block at the start of the level: the pixels'
  // errors are far from independent, so a prior weighted by the gyro's noise alone would be
  // drowned by thousands of pixels. Under the update R <- R Exp(-phi) the prior's Jacobian is
  // -P (to first order), so the normal equations gain w I on the rotation block.
  AlignStats Align(SE3* T_cur_kf, double* a, double* b,
                   const Eigen::Quaterniond* rotation_prior = nullptr) {
    AlignStats stats;
    const bool use_prior = rotation_prior != nullptr && options.rotation_prior_weight > 0;
    double prior_w = 0;  // w of the current level
    auto prior_residual = [&](const SE3& T) -> Eigen::Vector3d {
      return geometry::LogSO3(T.Rotation() * rotation_prior->conjugate());
    };
    // The prior's share of the mean robust cost (normalised per pixel by the residual scale,
    // like WeightAndCost's) with `count` pixels.
    auto prior_cost = [&](const SE3& T, int count, float sigma) {
      if (!use_prior || count <= 0) return 0.0;
      return 0.5 * prior_w * prior_residual(T).squaredNorm() /
             (static_cast<double>(sigma) * sigma * count);
    };
    const bool affine = options.estimate_affine_brightness;
    const int dims = affine ? 8 : 6;
    // Converged when the motion moves less than min_step and the brightness less than 1e-4 in
    // log gain and 0.01 grey levels in bias.
    auto small_step = [&](const Eigen::VectorXd& delta) {
      return delta.head<6>().norm() < options.min_step &&
             (!affine || (std::abs(delta[6]) < 1e-4 && std::abs(delta[7]) < 1e-2));
    };
    RobustWeighting rw;
    rw.loss = options.loss;
    rw.nu = static_cast<float>(options.student_t_nu);
    rw.huber_k = static_cast<float>(options.huber_k);
    for (int level = options.num_levels - 1; level >= options.finest_level; --level) {
      if (keyframe.levels[level].size() < 8) continue;
      double lambda = options.initial_lambda;
      int count =
          Evaluate(level, *T_cur_kf, static_cast<float>(std::exp(*a)), static_cast<float>(*b));
      if (count < 8) continue;
      rw.sigma = EstimateScale(count);
      Matrix8d H;
      Vector8d g;
      double cost = WeightAndCost(rw, count, &H, &g, nullptr, level);
      if (use_prior) prior_w = options.rotation_prior_weight * H.block<3, 3>(3, 3).trace() / 3.0;
      cost += prior_cost(*T_cur_kf, count, rw.sigma);
      for (int it = 0; it < options.max_iterations_per_level; ++it) {
        ++stats.iterations;
        const Vector8d d = GainScaling(*a);
        Matrix8d He = d.asDiagonal() * H * d.asDiagonal();
        Vector8d ge = d.asDiagonal() * g;
        if (use_prior) {
          const Eigen::Matrix3d P = rotation_prior->toRotationMatrix();
          He.block<3, 3>(3, 3) += prior_w * Eigen::Matrix3d::Identity();
          ge.segment<3>(3) -= prior_w * P.transpose() * prior_residual(*T_cur_kf);
        }
        Eigen::MatrixXd A = He.topLeftCorner(dims, dims);
        A.diagonal() *= (1.0 + lambda);
        A.diagonal().array() += 1e-9;
        const Eigen::VectorXd delta = A.ldlt().solve(-ge.head(dims));
        if (!delta.allFinite()) break;
        geometry::Vector6d xi = delta.head<6>();
        const SE3 T_candidate = *T_cur_kf * SE3::Exp(xi).Inverse();
        const double a_candidate = affine ? *a + delta[6] : *a;
        const double b_candidate = affine ? *b + delta[7] : *b;
        const int count_candidate =
            Evaluate(level, T_candidate, static_cast<float>(std::exp(a_candidate)),
                     static_cast<float>(b_candidate));
        const double cost_candidate =
            count_candidate >= 8
                ? WeightAndCost(rw, count_candidate, nullptr, nullptr, nullptr, level) +
                      prior_cost(T_candidate, count_candidate, rw.sigma)
                : std::numeric_limits<double>::infinity();
        if (cost_candidate <= cost) {
          *T_cur_kf = T_candidate;
          *a = a_candidate;
          *b = b_candidate;
          count = count_candidate;
          lambda = std::max(lambda * 0.5, 1e-7);
          rw.sigma = EstimateScale(count, rw.sigma);
          cost = WeightAndCost(rw, count, &H, &g, nullptr, level) +
                 prior_cost(*T_cur_kf, count, rw.sigma);
          if (small_step(delta)) break;
        } else {
          // Residual buffers now hold the rejected candidate; H, g still describe the
          // accepted state.
          lambda = std::max(lambda, 1e-4) * 10.0;
          if (lambda > 1e4 || small_step(delta)) break;
        }
      }
      if (level == options.finest_level && use_prior) {
        // Where the pixels alone would put the rotation: one Gauss-Newton step on the
        // photometric normal equations without the prior, from the accepted state (a quadratic
        // model; at the prior-constrained optimum the two gradients balance). The gyro check
        // uses this, since the prior pulls the estimate itself to the gyro.
        const Vector8d d = GainScaling(*a);
        Eigen::MatrixXd A = (d.asDiagonal() * H * d.asDiagonal()).topLeftCorner(dims, dims);
        A.diagonal().array() += 1e-9;
        const Eigen::VectorXd delta = A.ldlt().solve(-(d.asDiagonal() * g).head(dims));
        if (delta.allFinite()) {
          const geometry::Vector6d xi = delta.head<6>();
          const SE3 T_vision = *T_cur_kf * SE3::Exp(xi).Inverse();
          stats.vision_prior_angle_deg =
              geometry::AngleBetween(T_vision.Rotation(), *rotation_prior) * kRadToDeg;
        }
      }
      if (level == options.finest_level) {
        // Final statistics at the accepted state.
        count =
            Evaluate(level, *T_cur_kf, static_cast<float>(std::exp(*a)), static_cast<float>(*b));
        rw.sigma = EstimateScale(count);
        double rms = 0;
        WeightAndCost(rw, count, nullptr, nullptr, &rms, level);
        stats.used = count;
        stats.rms = rms;
      }
    }
    return stats;
  }
};

// ---------------------------------------------------------------------------------------------

Result<DenseVo> DenseVo::Create(const camera::RectifiedStereo& rig, const DenseVoOptions& options,
                                const geometry::SE3& T_world_cam0) {
  std::string why;
  if (!rig.IsValid(&why)) return Status::InvalidArgument("rig: " + why);
  if (!options.IsValid(&why)) return Status::InvalidArgument("options." + why);
  if (!IsFinite(T_world_cam0)) return Status::InvalidArgument("T_world_cam0: not finite");
  const int coarse = 1 << (options.num_levels - 1);
  if (rig.width / coarse < 16 || rig.height / coarse < 16) {
    return Status::InvalidArgument("options.num_levels: the coarsest level of a " +
                                   std::to_string(rig.width) + "x" + std::to_string(rig.height) +
                                   " image would be smaller than 16x16 pixels");
  }
  auto impl = std::make_unique<Impl>();
  impl->rig = rig;
  impl->options = options;
  impl->T_world_cam0 = T_world_cam0;
  impl->T_world_cam = T_world_cam0;
  int w = rig.width, h = rig.height;
  for (int l = 0; l < options.num_levels; ++l) {
    const double s = 1.0 / (1 << l);
    impl->cameras.push_back({rig.fx * s, rig.fy * s, rig.cx * s, rig.cy * s, w, h});
    w = (w + 1) / 2;  // cv::pyrDown's size
    h = (h + 1) / 2;
  }
  if (options.matcher == DenseStereoMatcher::kBlockMatching) {
    cv::Ptr<cv::StereoBM> bm = cv::StereoBM::create(options.num_disparities, options.block_size);
    bm->setTextureThreshold(options.texture_threshold);
    bm->setUniquenessRatio(options.uniqueness_ratio);
    bm->setSpeckleWindowSize(options.speckle_window_size);
    bm->setSpeckleRange(options.speckle_range * 16);
    bm->setMinDisparity(0);
    impl->stereo_matcher = bm;
  } else {
    // Smoothness penalties as OpenCV recommends for grey images: P1 = 8 b^2, P2 = 32 b^2.
    const int b2 = options.sgbm_block_size * options.sgbm_block_size;
    impl->stereo_matcher = cv::StereoSGBM::create(
        0, options.num_disparities, options.sgbm_block_size, 8 * b2, 32 * b2,
        /*disp12MaxDiff=*/1, /*preFilterCap=*/0, options.uniqueness_ratio,
        options.speckle_window_size, options.speckle_range * 16, cv::StereoSGBM::MODE_SGBM_3WAY);
  }
  return DenseVo(std::move(impl));
}

DenseVo::DenseVo(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
DenseVo::DenseVo(DenseVo&&) noexcept = default;
DenseVo& DenseVo::operator=(DenseVo&&) noexcept = default;
DenseVo::~DenseVo() = default;

void DenseVo::Reset() {
  Impl& s = *impl_;
  s.has_keyframe = false;
  s.keyframe = Keyframe();
  s.T_world_cam = s.T_world_cam0;
  s.ForgetMotion();
  s.log_gain = s.bias = 0;
  s.frames = 0;
  s.keyframes = 0;
}

const geometry::SE3& DenseVo::T_world_cam() const { return impl_->T_world_cam; }
const DenseVoOptions& DenseVo::options() const { return impl_->options; }
const camera::RectifiedStereo& DenseVo::rig() const { return impl_->rig; }
int64_t DenseVo::frames_processed() const { return impl_->frames; }
int64_t DenseVo::keyframes_created() const { return impl_->keyframes; }

Result<DenseFrameResult> DenseVo::ProcessFrame(int64_t t_ns, const cv::Mat& left,
                                               const cv::Mat& right, const MotionHint* hint) {
  Impl& s = *impl_;
  MAV_RETURN_IF_ERROR(CheckImage("left", left, s.rig));
  MAV_RETURN_IF_ERROR(CheckImage("right", right, s.rig));
  const DenseVoOptions& o = s.options;
  const int64_t t_start = MonotonicNowNs();

  DenseFrameResult result;
  result.t_ns = t_ns;
  result.frame_index = s.frames++;
  result.T_world_cam = s.T_world_cam;

  int64_t t0 = MonotonicNowNs();
  s.BuildPyramid(left);
  result.timing.pyramid_ms = MsSince(t0);

  auto finish = [&]() {
    result.timing.total_ms = MsSince(t_start);
    return result;
  };

  // A frame without contrast (black, saturated, lens covered) can neither be tracked nor become
  // a keyframe; the affine brightness model would otherwise "explain" it with a zero gain.
  {
    cv::Scalar mean, stddev;
    cv::meanStdDev(s.pyramid.back(), mean, stddev);
    if (!(stddev[0] >= o.min_image_contrast)) {
      std::ostringstream msg;
      msg << "left image without contrast (intensity std dev " << stddev[0]
          << " grey levels < min_image_contrast " << o.min_image_contrast << ")";
      result.state = TrackingState::kLost;
      result.lost_reason = msg.str();
      s.has_keyframe = false;
      s.ForgetMotion();
      return finish();
    }
  }

  if (!s.has_keyframe) {
    t0 = MonotonicNowNs();
    const std::string why = s.BuildKeyframe(left, right, s.T_world_cam);
    result.timing.keyframe_ms = MsSince(t0);
    s.ForgetMotion();
    if (!why.empty()) {
      result.state = TrackingState::kLost;
      result.lost_reason = why;
      return finish();
    }
    s.t_ok_ns = t_ns;
    result.reference_reset = true;
    result.new_keyframe = true;
    result.num_keyframe_pixels = s.keyframe.levels[o.finest_level].size();
    result.num_pixels_used = result.num_keyframe_pixels;
    return finish();
  }

  // Motion prediction since the last OK frame (the previous frame unless it was DEGRADED): the
  // measured velocity over the interval (constant velocity), its rotation replaced by the gyro's
  // when the hints cover the interval.
  const double dt_s = t_ns > s.t_ok_ns ? 1e-9 * static_cast<double>(t_ns - s.t_ok_ns) : 0.0;
  const SE3 T_ok_cv = s.velocity_valid ? SE3::Exp(s.velocity * dt_s) : SE3();
  SE3 T_ok_pred = o.use_motion_prior ? T_ok_cv : SE3();
  const bool gyro = hint != nullptr && s.gyro_chain_valid;
  const Eigen::Quaterniond R_ok_gyro = gyro
                                           ? Eigen::Quaterniond(s.R_ok_prev_gyro * hint->R_prev_cur)
                                           : Eigen::Quaterniond::Identity();
  if (gyro) T_ok_pred = SE3(R_ok_gyro, T_ok_pred.Translation());
  const SE3 T_kf_pred = s.T_kf_prev * T_ok_pred;
  SE3 T_cur_kf = T_kf_pred.Inverse();
  const Eigen::Quaterniond rotation_prior = T_cur_kf.Rotation();
  double a = s.log_gain, b = s.bias;
  t0 = MonotonicNowNs();
  const Impl::AlignStats stats = s.Align(&T_cur_kf, &a, &b, gyro ? &rotation_prior : nullptr);
  result.timing.tracking_ms = MsSince(t0);
  result.iterations = stats.iterations;
  result.num_keyframe_pixels = s.keyframe.levels[o.finest_level].size();
  result.num_pixels_used = stats.used;
  result.rms_error = stats.rms;
  result.brightness_gain = std::exp(a);
  result.brightness_bias = b;

  // Failure checks.
  std::ostringstream lost;
  const SE3 T_kf_cur = T_cur_kf.Inverse();
  const SE3 T_ok_cur = s.T_kf_prev.Inverse() * T_kf_cur;
  const SE3 T_prev_cur = s.T_world_cam.Inverse() * (s.keyframe.T_world_kf * T_kf_cur);
  if (!IsFinite(T_cur_kf) || !std::isfinite(a) || !std::isfinite(b)) {
    lost << "alignment diverged (non-finite motion)";
  } else if (stats.used < o.min_pixels) {
    lost << "only " << stats.used << " of " << result.num_keyframe_pixels
         << " keyframe pixels inside the image (min_pixels " << o.min_pixels << ")";
  } else if (std::abs(a) > std::log(o.max_brightness_gain_change)) {
    lost << "brightness gain " << std::exp(a) << " outside [1/" << o.max_brightness_gain_change
         << ", " << o.max_brightness_gain_change << "] (max_brightness_gain_change)";
  } else if (stats.rms > o.max_rms_error) {
    lost << "photometric RMS error " << stats.rms << " above max_rms_error " << o.max_rms_error;
  } else if (T_prev_cur.Translation().norm() > o.max_translation_per_frame_m) {
    lost << "implausible translation of " << T_prev_cur.Translation().norm()
         << " m in one frame (max_translation_per_frame_m " << o.max_translation_per_frame_m << ")";
  } else if (RotationDeg(T_prev_cur) > o.max_rotation_per_frame_deg) {
    lost << "implausible rotation of " << RotationDeg(T_prev_cur)
         << " deg in one frame (max_rotation_per_frame_deg " << o.max_rotation_per_frame_deg << ")";
  }

  // Consistency check of a tracked frame against the prediction.
  std::ostringstream inconsistent;
  if (lost.str().empty()) {
    if (gyro) {
      // With the prior on, the estimate itself sits near the gyro; the check compares the
      // rotation the pixels alone support.
      result.gyro_rotation_error_deg =
          o.rotation_prior_weight > 0
              ? stats.vision_prior_angle_deg
              : geometry::AngleBetween(T_ok_cur.Rotation(), R_ok_gyro) * kRadToDeg;
    }
    if (s.velocity_valid) {
      result.prediction_error_m = (T_ok_cur.Translation() - T_ok_cv.Translation()).norm();
    }
    const double motion_bound =
        0.5 * o.max_acceleration_mps2 * dt_s * dt_s + o.motion_check_floor_m;
    const double rms_bound = std::max(8.0, o.max_rms_growth * s.rms_mean);
    if (o.consistency_check) {
      if (gyro && result.gyro_rotation_error_deg > o.max_gyro_rotation_error_deg) {
        inconsistent << "rotation differs from the gyro's by " << result.gyro_rotation_error_deg
                     << " deg (max_gyro_rotation_error_deg " << o.max_gyro_rotation_error_deg
                     << ")";
      } else if (s.velocity_valid && s.ok_run >= 2 && result.prediction_error_m > motion_bound) {
        inconsistent << "translation is " << result.prediction_error_m
                     << " m off the constant-velocity prediction (bound " << motion_bound
                     << " m from max_acceleration_mps2 " << o.max_acceleration_mps2
                     << " and motion_check_floor_m " << o.motion_check_floor_m << ")";
      } else if (stats.used < o.min_support_fraction * result.num_keyframe_pixels) {
        inconsistent << "only " << stats.used << " of " << result.num_keyframe_pixels
                     << " keyframe pixels used (min_support_fraction " << o.min_support_fraction
                     << ")";
      } else if (s.rms_mean > 0 && stats.rms > rms_bound) {
        inconsistent << "photometric RMS error " << stats.rms << " is above " << rms_bound
                     << " (max_rms_growth " << o.max_rms_growth << " x the running mean "
                     << s.rms_mean << ")";
      }
    }
    if (!inconsistent.str().empty() && s.degraded_run >= o.max_degraded_frames) {
      lost << "consistency check failed " << s.degraded_run + 1
           << " frames in a row (max_degraded_frames " << o.max_degraded_frames
           << "): " << inconsistent.str();
    }
  }
  if (!lost.str().empty()) {
    result.state = TrackingState::kLost;
    result.lost_reason = lost.str();
    result.iterations = stats.iterations;
    // Re-initialise: this pair becomes the keyframe at the held pose if it can.
    s.has_keyframe = false;
    t0 = MonotonicNowNs();
    const std::string why = s.BuildKeyframe(left, right, s.T_world_cam);
    result.timing.keyframe_ms = MsSince(t0);
    result.new_keyframe = why.empty();
    s.ForgetMotion();
    if (result.new_keyframe) s.t_ok_ns = t_ns;
    return finish();
  }
  if (!inconsistent.str().empty()) {
    // DEGRADED: publish the prediction, keep the velocity, the brightness and the keyframe.
    result.state = TrackingState::kDegraded;
    result.lost_reason = inconsistent.str();
    ++s.degraded_run;
    const SE3 T_world_pred = s.keyframe.T_world_kf * T_kf_pred;
    result.T_prev_cur = s.T_world_cam.Inverse() * T_world_pred;
    s.T_world_cam = T_world_pred;
    result.T_world_cam = s.T_world_cam;
    s.gyro_chain_valid = gyro;
    s.R_ok_prev_gyro = R_ok_gyro;
    return finish();
  }

  s.T_world_cam = s.keyframe.T_world_kf * T_kf_cur;
  s.T_kf_prev = T_kf_cur;
  if (dt_s > 0) {
    s.velocity = T_ok_cur.Log() / dt_s;
    s.velocity_valid = true;
  }
  s.t_ok_ns = t_ns;
  s.R_ok_prev_gyro.setIdentity();
  s.gyro_chain_valid = true;
  s.degraded_run = 0;
  ++s.ok_run;
  s.rms_mean = s.rms_mean > 0 ? 0.9 * s.rms_mean + 0.1 * stats.rms : stats.rms;
  s.log_gain = a;
  s.bias = b;
  result.T_world_cam = s.T_world_cam;
  result.T_prev_cur = T_prev_cur;

  const double visible = result.num_keyframe_pixels > 0
                             ? static_cast<double>(stats.used) / result.num_keyframe_pixels
                             : 0.0;
  const bool need_keyframe = RotationDeg(T_kf_cur) > o.keyframe_max_rotation_deg ||
                             T_kf_cur.Translation().norm() > o.keyframe_max_translation_m ||
                             stats.rms > o.keyframe_max_rms_error ||
                             visible < o.keyframe_min_visible_fraction;
  if (need_keyframe) {
    t0 = MonotonicNowNs();
    Keyframe old = std::move(s.keyframe);
    const std::string why = s.BuildKeyframe(left, right, s.T_world_cam);
    result.timing.keyframe_ms = MsSince(t0);
    if (why.empty()) {
      result.new_keyframe = true;
      s.T_kf_prev = SE3();
    } else {
      // Keep tracking against the old keyframe.
      s.keyframe = std::move(old);
      s.has_keyframe = true;
    }
  }
  return finish();
}

}  // namespace mav::localization
