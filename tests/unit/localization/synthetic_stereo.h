#pragma once
// A tiny ray-casting stereo renderer for tests and benchmarks of the visual odometry: the camera
// sits inside a textured box ("room") whose walls, floor and ceiling carry multi-scale value
// noise. Exact ground truth for any camera pose, deterministic from a seed, no dependencies
// beyond Eigen and the camera library. Header-only so that benchmarks can use it too.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include <Eigen/Core>

#include "mav/camera/stereo.h"
#include "mav/geometry/se3.h"

namespace mav::localization::synthetic {

// EuRoC-like rectified rig: 752x480, f = 458 px, 11 cm baseline.
inline camera::RectifiedStereo EurocLikeRig() {
  camera::RectifiedStereo rig;
  rig.width = 752;
  rig.height = 480;
  rig.fx = rig.fy = 458.0;
  rig.cx = 367.5;
  rig.cy = 248.5;
  rig.baseline = 0.11;
  return rig;
}

class SyntheticRoom {
 public:
  // Box [lo, hi] in world coordinates (metres); the camera must stay inside.
  explicit SyntheticRoom(uint64_t seed = 7, const Eigen::Vector3d& lo = {-3.0, -1.5, -2.0},
                         const Eigen::Vector3d& hi = {3.0, 1.5, 5.0})
      : lo_(lo), hi_(hi) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<float> uni(-1.f, 1.f);
    std::vector<float> raw(kSize * kSize);
    for (float& x : raw) x = uni(rng);
    // Separable [1 4 6 4 1]/16 blur with wrap-around: smooth at texel scale, no seams.
    tex_.assign(kSize * kSize, 0.f);
    std::vector<float> tmp(kSize * kSize);
    const float k[5] = {1.f / 16, 4.f / 16, 6.f / 16, 4.f / 16, 1.f / 16};
    for (int y = 0; y < kSize; ++y)
      for (int x = 0; x < kSize; ++x) {
        float s = 0;
        for (int i = -2; i <= 2; ++i) s += k[i + 2] * raw[y * kSize + ((x + i) & kMask)];
        tmp[y * kSize + x] = s;
      }
    for (int y = 0; y < kSize; ++y)
      for (int x = 0; x < kSize; ++x) {
        float s = 0;
        for (int i = -2; i <= 2; ++i) s += k[i + 2] * tmp[((y + i) & kMask) * kSize + x];
        tex_[y * kSize + x] = s;
      }
  }

  // Distance along the ray (origin o, direction d, world frame) to the box.
  double RayLength(const Eigen::Vector3d& o, const Eigen::Vector3d& d) const {
    double best = 1e30;
    for (int a = 0; a < 3; ++a) {
      if (std::abs(d[a]) < 1e-12) continue;
      const double t = ((d[a] > 0 ? hi_[a] : lo_[a]) - o[a]) / d[a];
      if (t > 0 && t < best) best = t;
    }
    return best;
  }

  // Depth (z in the camera frame) of the surface seen at left pixel (u, v).
  double DepthAt(const camera::RectifiedStereo& rig, const geometry::SE3& T_world_cam, double u,
                 double v) const {
    const Eigen::Vector3d d = T_world_cam.RotationMatrix() *
                              Eigen::Vector3d((u - rig.cx) / rig.fx, (v - rig.cy) / rig.fy, 1.0);
    return RayLength(T_world_cam.Translation(), d);  // the ray's z component is 1
  }

  // Intensity seen along a ray (origin o, direction d, both world frame) from inside the box.
  float Shade(const Eigen::Vector3d& o, const Eigen::Vector3d& d) const {
    double best = 1e30;
    int axis = 0;
    for (int a = 0; a < 3; ++a) {
      if (std::abs(d[a]) < 1e-12) continue;
      const double t = ((d[a] > 0 ? hi_[a] : lo_[a]) - o[a]) / d[a];
      if (t > 0 && t < best) {
        best = t;
        axis = a;
      }
    }
    const Eigen::Vector3d p = o + best * d;
    const int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
    const double off = (d[axis] > 0 ? 1.7 : 0.0) + 3.1 * axis;  // a different patch per wall
    const double s = p[a1] + off, t = p[a2] + 2 * off;
    // Three octaves: 1.5 cm, 6 cm and 24 cm texels.
    const float v = 0.9f * Sample(s / 0.015, t / 0.015) + 0.7f * Sample(s / 0.06 + 91, t / 0.06) +
                    0.6f * Sample(s / 0.24 + 17, t / 0.24 + 53);
    return 128.f + 170.f * v;
  }

  // Renders the rectified pair seen from T_world_cam (the left camera). Optional Gaussian noise
  // (grey levels) from `noise_seed`.
  void Render(const camera::RectifiedStereo& rig, const geometry::SE3& T_world_cam,
              std::vector<uint8_t>* left, std::vector<uint8_t>* right, double noise_sigma = 0,
              uint64_t noise_seed = 1) const {
    const Eigen::Matrix3d R = T_world_cam.RotationMatrix();
    const Eigen::Vector3d& o_left = T_world_cam.Translation();
    const Eigen::Vector3d o_right = T_world_cam * Eigen::Vector3d(rig.baseline, 0, 0);
    std::mt19937_64 rng(noise_seed);
    std::normal_distribution<float> noise(0.f, static_cast<float>(noise_sigma));
    for (int image = 0; image < 2; ++image) {
      std::vector<uint8_t>* out = image == 0 ? left : right;
      const Eigen::Vector3d& o = image == 0 ? o_left : o_right;
      out->resize(static_cast<size_t>(rig.width) * rig.height);
      for (int v = 0; v < rig.height; ++v)
        for (int u = 0; u < rig.width; ++u) {
          const Eigen::Vector3d d =
              R * Eigen::Vector3d((u - rig.cx) / rig.fx, (v - rig.cy) / rig.fy, 1.0);
          float g = Shade(o, d);
          if (noise_sigma > 0) g += noise(rng);
          (*out)[static_cast<size_t>(v) * rig.width + u] =
              static_cast<uint8_t>(std::clamp(std::lround(g), 0L, 255L));
        }
    }
  }

 private:
  static constexpr int kSize = 512, kMask = kSize - 1;
  // Bilinear lookup with wrap-around, smoothstep-weighted for C1 continuity.
  float Sample(double x, double y) const {
    const double fx = std::floor(x), fy = std::floor(y);
    const int x0 = static_cast<int>(static_cast<int64_t>(fx) & kMask);
    const int y0 = static_cast<int>(static_cast<int64_t>(fy) & kMask);
    const int x1 = (x0 + 1) & kMask, y1 = (y0 + 1) & kMask;
    double ax = x - fx, ay = y - fy;
    ax = ax * ax * (3 - 2 * ax);
    ay = ay * ay * (3 - 2 * ay);
    const float top =
        static_cast<float>((1 - ax) * tex_[y0 * kSize + x0] + ax * tex_[y0 * kSize + x1]);
    const float bot =
        static_cast<float>((1 - ax) * tex_[y1 * kSize + x0] + ax * tex_[y1 * kSize + x1]);
    return static_cast<float>((1 - ay) * top + ay * bot);
  }

  Eigen::Vector3d lo_, hi_;
  std::vector<float> tex_;
};

}  // namespace mav::localization::synthetic
