#pragma once
// CPU ray-casting renderer for one camera of the simulated rig.
//
// Per camera, the viewing ray of every pixel is computed once from the camera model
// (PinholeRadTan::Unproject, so the images carry the model's exact distortion) into a look-up
// table (also stored in 16 x 16 pixel tile order), together with a bounding cone per tile. Per
// frame, the primitives whose bounding spheres (long primitives are split into several) fall
// inside a tile's cone are collected and sorted nearest first; they are intersected with the
// tile's rays 4 or 8 at a time (SSE2 or AVX2: SetSimdLanes), in float precision relative to each
// primitive's centre, and the tile stops as soon as every pixel has a hit nearer than the next
// candidate can be. Shading: albedo (trilinearly filtered texture, texture.h; texel fetches of a
// whole tile are addressed and prefetched before they are blended) times the world's lighting, plus
// emission. No shadows, no inter-reflections, no geometric anti-aliasing (edges of primitives are
// sampled once per pixel centre).
//
// Rendering is const and allocation-free inside the pixel loops; a CameraRenderer can render
// many frames concurrently from several threads. Output is deterministic (same binary, same
// input: same bits), independent of threading.

#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "mav/camera/pinhole.h"
#include "mav/geometry/se3.h"
#include "mav/sim/world.h"

namespace cv {
class Mat;
}

namespace mav::sim {

class CameraRenderer {
 public:
  // The world must have its textures built (World::BuildTextures) and stay unchanged.
  CameraRenderer(std::shared_ptr<const World> world, const camera::PinholeRadTan& camera);
  ~CameraRenderer();
  CameraRenderer(CameraRenderer&&) noexcept;
  CameraRenderer& operator=(CameraRenderer&&) noexcept;

  const camera::PinholeRadTan& camera() const;
  int width() const;
  int height() const;

  // The width of the per-pixel kernels: the widest the CPU has of 16 lanes (AVX-512), 8 (AVX2)
  // and 4 (SSE2), up to `max_lanes` (default: the widest). The images are the same bits at
  // every width (render_test checks it).
  void SetSimdLanes(int max_lanes);
  int simd_lanes() const;

  // Cylinders' texture coordinate around the axis: false (default) a polynomial atan2 that
  // runs in the lanes (within 3e-7 rad of std::atan2); true std::atan2 per pixel, the images
  // pinned before that change (render_test bounds the difference: at most 1 DN).
  void SetExactCylinderAngles(bool exact);

  // Scene radiance per pixel (row-major, width*height; 1.0 = a white surface under full light)
  // seen from T_world_cam. `range` (optional) receives the distance along the ray in metres
  // (+infinity where nothing was hit).
  void RenderRadiance(const geometry::SE3& T_world_cam, std::vector<float>* radiance,
                      std::vector<float>* range = nullptr) const;

  // Sub-frame integration for motion blur: the mean of RenderRadiance over the given poses
  // (sampled uniformly over the shutter interval by the caller).
  void RenderIntegrated(const std::vector<geometry::SE3>& T_world_cam_samples,
                        std::vector<float>* radiance) const;

  // Motion blur by reprojection (the fast alternative to RenderIntegrated): `sharp` and `range`
  // were rendered at T_world_cam_mid (mid-shutter). Each pixel's surface point (ray * range) is
  // projected, with the camera model, into the cameras at shutter open and close; the blurred
  // value is the mean of `sharp` sampled (bilinearly) along the resulting image-motion segment,
  // i.e. the sub-frame integral for a static scene with motion linear over the shutter. Up to
  // `max_samples` samples, about one per pixel of motion (4, 8 or 16 pixels at a time).
  // Approximate at occlusion boundaries (the hidden background is not known).
  void BlurByReprojection(const std::vector<float>& sharp, const std::vector<float>& range,
                          const geometry::SE3& T_world_cam_mid,
                          const geometry::SE3& T_world_cam_open,
                          const geometry::SE3& T_world_cam_close, int max_samples,
                          std::vector<float>* blurred) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Image formation: v = round(clamp(255 * gain * radiance + n, 0, 255)) with n ~ N(0, sigma^2)
// approximated by a scaled sum of four uniforms (Irwin-Hall: the four bytes of a 32-bit
// counter-based hash of (noise_key, pixel index)): deterministic and independent of thread
// scheduling.
// Writes a CV_8UC1 image of width x height. `max_lanes`: as CameraRenderer::SetSimdLanes (the
// same bytes at every width).
void FormImage(const std::vector<float>& radiance, int width, int height, double gain,
               double noise_sigma, uint64_t noise_key, cv::Mat* image, int max_lanes = 16);

namespace internal {
// The renderer's atan2 (CameraRenderer::SetExactCylinderAngles), one value, for tests.
float LaneAtan2(float y, float x);
}  // namespace internal

}  // namespace mav::sim
