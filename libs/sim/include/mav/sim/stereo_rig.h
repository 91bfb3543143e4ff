#pragma once
// The simulated stereo camera for any motion of its body: the image formation of a preset
// (exposure gain, noise, motion blur; presets.h) for a rig (camera::StereoCalibration) in a
// world. A Scenario renders it along its planned trajectory; a flight renders it along the state
// the simulated vehicle flies (vision in the loop, mav/mission/lockstep_driver.h).
//
//   StereoRigRenderer rig(world, calibration, preset.effects, seed);
//   rig.Render(frame, t_s, [&](double dt_s) { return T_world_body at t_s + dt_s; }, &l, &r);
//
// `T_world_body_at(dt)` gives the rig's body (IMU) frame at an offset from the frame's
// mid-shutter time; it is asked for dt = 0 only without blur, for -+shutter_s / 2 with the
// reprojection blur, and for evenly spaced offsets in between with the exact blur.
// The output depends only on (seed, frame, t_s, the poses): frames can be rendered in any order
// and on any thread.

#include <array>
#include <cstdint>
#include <functional>
#include <memory>

#include "mav/camera/stereo.h"
#include "mav/geometry/se3.h"
#include "mav/sim/presets.h"

namespace cv {
class Mat;
}

namespace mav::sim {

class CameraRenderer;
class World;

class StereoRigRenderer {
 public:
  using PoseAt = std::function<geometry::SE3(double dt_s)>;

  // The world must have its textures built. `min_clearance_m` bounds the depth the exact blur
  // assumes when it chooses its number of sub-frames (the preset's clearance).
  StereoRigRenderer(std::shared_ptr<const World> world, const camera::StereoCalibration& rig,
                    const ImageEffects& effects, uint64_t seed, double min_clearance_m);
  ~StereoRigRenderer();
  StereoRigRenderer(StereoRigRenderer&&) noexcept;
  StereoRigRenderer& operator=(StereoRigRenderer&&) noexcept;

  // Frame `frame` at t_s (seconds since the first frame: the exposure drift's clock) as two
  // CV_8UC1 images of the rig's size. Thread-safe.
  void Render(int64_t frame, double t_s, const PoseAt& T_world_body_at, cv::Mat* left,
              cv::Mat* right) const;

  const camera::StereoCalibration& calibration() const { return rig_; }
  const ImageEffects& effects() const { return effects_; }
  int width() const;
  int height() const;

 private:
  std::shared_ptr<const World> world_;
  camera::StereoCalibration rig_;
  ImageEffects effects_;
  uint64_t seed_;
  double min_clearance_m_;
  std::array<std::unique_ptr<CameraRenderer>, 2> cameras_;
};

}  // namespace mav::sim
