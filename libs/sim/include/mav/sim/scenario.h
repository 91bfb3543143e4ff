#pragma once
// A Scenario is one simulated data set: a world, a trajectory through it, a stereo rig and an
// IMU. Everything is a deterministic function of (preset, seed): rendering frame k twice gives
// bit-identical images, so frames can be rendered in parallel and out of order.
//
// Time starts at t0_ns (a fixed, EuRoC-like epoch) and frames are at 20 Hz:
//   FrameTimeNs(k) = t0_ns + k * 50'000'000.
// IMU samples and ground-truth states are at 200 Hz over [FrameTimeNs(0), FrameTimeNs(N-1)].

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "mav/camera/stereo.h"
#include "mav/common/status.h"
#include "mav/dataset/occupancy_grid.h"
#include "mav/dataset/types.h"

namespace cv {
class Mat;
}

namespace mav::sim {

class World;

struct ScenarioOptions {
  // One of PresetNames(): room-easy, room-medium, room-hard, plant.
  std::string preset = "room-easy";
  // Number of stereo frames; <= 0 means the preset's full length (EuRoC-like, 1559-2839).
  int64_t frames = 0;
  uint64_t seed = 1;
  // true: an ideal rectified pinhole pair (no distortion, no relative rotation).
  // false: EuRoC's raw calibration (radial-tangential distortion, small rotation cam0->cam1).
  bool rectified = false;
  // The reference rendering of cylinders (ImageEffects::exact_cylinder_angles): slower; the
  // images pinned before the renderer's own atan2 (render_test).
  bool exact_cylinder_angles = false;

  bool IsValid(std::string* why) const;
};

// The preset names, in a stable order.
const std::vector<std::string>& PresetNames();

class Scenario {
 public:
  // InvalidArgument naming the field ("preset: unknown preset 'x' (known: ...)", "frames: ...").
  static Result<Scenario> Create(const ScenarioOptions& options);

  const ScenarioOptions& options() const;
  const World& world() const;
  // The rig the images are rendered with (also written to sensor.yaml).
  const camera::StereoCalibration& calibration() const;
  const dataset::ImuNoise& imu_noise() const;

  int64_t num_frames() const;
  int64_t FrameTimeNs(int64_t frame) const;
  double camera_rate_hz() const { return 20.0; }
  double imu_rate_hz() const { return 200.0; }

  // Renders frame `frame` (0 <= frame < num_frames()) as two 752x480 CV_8UC1 images.
  // Thread-safe; deterministic.
  void RenderStereo(int64_t frame, cv::Mat* left, cv::Mat* right) const;

  // Exact state of the body (IMU) frame at any time inside the span (analytic spline).
  dataset::GroundTruthState StateAt(int64_t t_ns) const;
  // Noisy IMU samples (white noise + bias random walk with imu_noise()) at 200 Hz over the span.
  std::vector<dataset::ImuSample> ImuSamples() const;
  // Noise-free IMU reading (analytic derivatives of the trajectory) at t_ns.
  dataset::ImuSample IdealImuAt(int64_t t_ns) const;
  // Ground-truth states at 200 Hz over the span (biases as used by ImuSamples()).
  std::vector<dataset::GroundTruthState> GroundTruth() const;

  // Ground-truth occupancy of the world at `resolution` metres (sim::ComputeOccupancy), and the
  // geometry it would have (to refuse a huge request before computing it).
  dataset::OccupancyGrid ComputeOccupancy(double resolution) const;
  dataset::GridGeometry OccupancyGeometry(double resolution) const;

  Scenario(Scenario&&) noexcept;
  Scenario& operator=(Scenario&&) noexcept;
  ~Scenario();

 private:
  struct Impl;
  explicit Scenario(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace mav::sim
