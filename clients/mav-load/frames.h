#pragma once
// Stereo frames for the localization and mapping loads: rendered in process from a simulator
// preset (sim::OpenPreset, the images mav-simulator publishes) or read from an EuRoC ASL
// directory (sim::OpenEuroc), with the rig's calibration and, when the source has it, the
// ground-truth body pose of each frame.

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "mav/v1/common.pb.h"

#include "mav/camera/stereo.h"
#include "mav/common/status.h"
#include "mav/geometry/se3.h"

namespace mav::load {

struct FrameSelection {
  std::string preset = "room-easy";  // used when `euroc` is empty
  std::string euroc;                 // an EuRoC ASL directory
  int64_t frames = 40;               // how many frames to keep
  int64_t stride = 1;                // keep every stride-th frame of the source
  uint64_t seed = 1;                 // the preset's seed
  bool rectified = false;            // preset: an ideal rectified rig instead of EuRoC's raw one
};

struct StereoFrames {
  std::string source;  // "room-easy (seed 1)" or the directory
  camera::StereoCalibration calibration;
  bool rectified = false;
  int64_t period_ns = 50'000'000;  // between kept frames
  std::vector<int64_t> t_ns;
  std::vector<cv::Mat> left, right;         // CV_8UC1
  std::vector<geometry::SE3> T_world_body;  // one per frame, or empty without ground truth
};

// Renders (two threads) or reads the selected frames. InvalidArgument naming the flag
// ("--frames", "--euroc", ...) or the source's own error.
Result<StereoFrames> LoadFrames(const FrameSelection& selection);

void SetImage(const cv::Mat& image, v1::Image* out);
// Frame k's images and `rectified` flag (t_ns is left to the caller).
void SetStereoImages(const StereoFrames& frames, size_t k, v1::StereoPair* out);
void SetCalibration(const StereoFrames& frames, v1::StereoCalibration* out);

}  // namespace mav::load
