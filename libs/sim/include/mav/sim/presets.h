#pragma once
// The simulator's presets: a world, a motion profile, a data-set length and the image
// "difficulty knobs" (see docs/simulator.md).
//
//   room-easy    EuRoC Vicon-room-like 8 x 8 x 3 m room, slow smooth motion, 2839 frames,
//                mild exposure drift, low noise, no motion blur.
//   room-medium  same room plus lamps (saturated regions) and some poorly textured surfaces,
//                faster motion, 1559 frames, stronger exposure changes, blur (4 ms shutter).
//   room-hard    same room plus a bright window, a dark curtain (under-exposed), more poorly
//                textured surfaces, jerky motion with a lot of rotation, 2079 frames, strong
//                exposure swings, blur (8 ms shutter), more noise.
//   plant        50 x 50 x 40 m industrial site (tanks, pipes, towers, walls, buildings),
//                long fast flight, 2000 frames.
//
// The layout of a preset's world does not depend on the seed (so every seed shares one
// ground-truth occupancy); the seed changes textures, trajectory, exposure phase and noise.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "mav/common/status.h"
#include "mav/sim/trajectory.h"
#include "mav/sim/world.h"

namespace mav::sim {

// Image-formation difficulty knobs.
// Motion blur: with shutter_s > 0 the image integrates over the shutter interval (sub-frame
// integration along the trajectory), by one of two methods (exact_blur).
struct ImageEffects {
  double base_gain = 1.0;  // 8-bit value = 255 * gain * radiance (+ noise)
  // Smooth global exposure changes: gain(t) = base_gain * (1 + amplitude * s(t)) with s a sum
  // of two sinusoids of periods gain_period_s and 0.37 gain_period_s (|s| <= 1), seeded phases.
  double gain_amplitude = 0.0;
  double gain_period_s = 20.0;
  double noise_sigma = 0.0;  // sensor noise, DN (8-bit levels), Gaussian
  // Motion blur: the shutter is open for shutter_s around each frame time; the image is the
  // mean of sub-frame renders at evenly spaced times over it. The number of sub-frames adapts to
  // the image motion (about one per blur_pixels_per_sample pixels of motion), capped at
  // max_blur_samples. 0 = no blur.
  double shutter_s = 0.0;
  int max_blur_samples = 1;
  double blur_pixels_per_sample = 1.5;
  // false (default): blur by reprojection (CameraRenderer::BlurByReprojection): one render at
  // mid-shutter plus a per-pixel integral along the exact image motion of the pixel's surface
  // point, up to reprojection_max_samples samples (cheap; approximate at occlusion boundaries).
  // true: the mean of up to max_blur_samples full sub-frame renders (exact but slow).
  bool exact_blur = false;
  int reprojection_max_samples = 8;
  // Cylinders' texture angle: false (default) a polynomial atan2 in the renderer's lanes; true
  // std::atan2 per pixel, the reference (CameraRenderer::SetExactCylinderAngles).
  bool exact_cylinder_angles = false;

  // Exposure gain at time t_s since the first frame.
  double GainAt(double t_s, uint64_t seed) const;
};

struct Preset {
  std::string name;
  int64_t full_frames = 0;
  MotionProfile profile = MotionProfile::kEasy;
  std::shared_ptr<World> world;  // textures not yet built
  Eigen::AlignedBox3d flight_bounds;
  double min_clearance = 0.6;
  Eigen::Vector3d look_at = Eigen::Vector3d::Zero();
  ImageEffects effects;
};

// The known preset names, in a stable order.
const std::vector<std::string>& PresetNames();

// InvalidArgument "preset: unknown preset 'x' (known: room-easy, room-medium, room-hard, plant)".
Result<Preset> MakePreset(const std::string& name);

// The worlds themselves (exposed for tests, benchmarks and tools).
struct RoomStyle {
  double poor_texture_contrast = 0.25;  // contrast of the "poorly textured" surfaces
  int poor_surfaces = 0;                // 0: none, 1: ceiling + one wall, 2: also the floor
  bool lamps = false;                   // emissive ceiling/wall lamps (saturate)
  bool window = false;                  // large bright window on a wall (saturates)
  bool dark_curtain = false;            // very dark panel (under-exposed)
};
std::shared_ptr<World> BuildRoomWorld(const RoomStyle& style);
std::shared_ptr<World> BuildPlantWorld();

}  // namespace mav::sim
