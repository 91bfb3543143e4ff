#include "mav/sim/stereo_rig.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <opencv2/core.hpp>

#include "mav/common/check.h"
#include "mav/sim/renderer.h"
#include "mav/sim/world.h"
#include "random.h"

namespace mav::sim {

StereoRigRenderer::StereoRigRenderer(std::shared_ptr<const World> world,
                                     const camera::StereoCalibration& rig,
                                     const ImageEffects& effects, uint64_t seed,
                                     double min_clearance_m)
    : world_(std::move(world)),
      rig_(rig),
      effects_(effects),
      seed_(seed),
      min_clearance_m_(min_clearance_m) {
  MAV_CHECK(world_ != nullptr);
  cameras_[0] = std::make_unique<CameraRenderer>(world_, rig_.cam0);
  cameras_[1] = std::make_unique<CameraRenderer>(world_, rig_.cam1);
  for (auto& camera : cameras_) camera->SetExactCylinderAngles(effects_.exact_cylinder_angles);
}

StereoRigRenderer::~StereoRigRenderer() = default;
StereoRigRenderer::StereoRigRenderer(StereoRigRenderer&&) noexcept = default;
StereoRigRenderer& StereoRigRenderer::operator=(StereoRigRenderer&&) noexcept = default;

int StereoRigRenderer::width() const { return cameras_[0]->width(); }
int StereoRigRenderer::height() const { return cameras_[0]->height(); }

void StereoRigRenderer::Render(int64_t frame, double t_s, const PoseAt& T_world_body_at,
                               cv::Mat* left, cv::Mat* right) const {
  MAV_CHECK(left != nullptr && right != nullptr);
  const ImageEffects& fx = effects_;
  const double gain = fx.GainAt(t_s, seed_);
  const std::array<const geometry::SE3*, 2> T_body_cam = {&rig_.T_body_cam0, &rig_.T_body_cam1};
  std::array<cv::Mat*, 2> out = {left, right};
  std::vector<float> radiance, range, blurred;
  auto form = [&](int c, const std::vector<float>& image) {
    const uint64_t key = internal::HashCombine(
        internal::HashCombine(seed_, static_cast<uint64_t>(frame)), 0xca0ULL + c);
    FormImage(image, cameras_[c]->width(), cameras_[c]->height(), gain, fx.noise_sigma, key,
              out[c]);
  };
  const geometry::SE3 T_mid = T_world_body_at(0.0);
  if (fx.shutter_s <= 0) {
    for (int c = 0; c < 2; ++c) {
      cameras_[c]->RenderRadiance(T_mid * *T_body_cam[c], &radiance);
      form(c, radiance);
    }
    return;
  }
  const geometry::SE3 T_open = T_world_body_at(-fx.shutter_s / 2);
  const geometry::SE3 T_close = T_world_body_at(fx.shutter_s / 2);
  if (!fx.exact_blur) {
    for (int c = 0; c < 2; ++c) {
      const geometry::SE3& T_bc = *T_body_cam[c];
      cameras_[c]->RenderRadiance(T_mid * T_bc, &radiance, &range);
      cameras_[c]->BlurByReprojection(radiance, range, T_mid * T_bc, T_open * T_bc, T_close * T_bc,
                                      fx.reprojection_max_samples, &blurred);
      form(c, blurred);
    }
    return;
  }
  // Exact: full sub-frame renders, their number adapted to the image motion over the shutter
  // (rotation and translation at the closest plausible depth, the preset's clearance).
  const double angle = geometry::AngleBetween(T_open.Rotation(), T_close.Rotation());
  const double shift =
      (T_close.Translation() - T_open.Translation()).norm() / std::max(min_clearance_m_, 0.3);
  const double pixels = (angle + shift) * rig_.cam0.fx;
  const int samples = std::clamp(static_cast<int>(std::ceil(pixels / fx.blur_pixels_per_sample)), 1,
                                 std::max(1, fx.max_blur_samples));
  std::vector<geometry::SE3> T_world_body;
  for (int i = 0; i < samples; ++i) {
    const double dt = samples == 1 ? 0.0 : ((i + 0.5) / samples - 0.5) * fx.shutter_s;
    T_world_body.push_back(T_world_body_at(dt));
  }
  for (int c = 0; c < 2; ++c) {
    std::vector<geometry::SE3> poses;
    poses.reserve(T_world_body.size());
    for (const geometry::SE3& T : T_world_body) poses.push_back(T * *T_body_cam[c]);
    cameras_[c]->RenderIntegrated(poses, &radiance);
    form(c, radiance);
  }
}

}  // namespace mav::sim
