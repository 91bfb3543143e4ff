#pragma once
// A stereo pair with its images. Separate from euroc.h so that only code which handles pixels
// pulls in OpenCV's core header.

#include <cstdint>

#include <opencv2/core/mat.hpp>

#include "mav/dataset/euroc.h"

namespace mav::dataset {

struct StereoPair {
  int64_t t_ns = 0;
  cv::Mat left;   // cam0, CV_8UC1
  cv::Mat right;  // cam1, CV_8UC1
  // True when the pair is already in the rectified geometry (not remapped by a consumer).
  bool rectified = false;
};

}  // namespace mav::dataset
