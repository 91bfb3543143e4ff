#pragma once
// Internal helpers shared by the sparse and dense odometry: input validation.

#include <sstream>

#include <opencv2/core/mat.hpp>

#include "mav/camera/stereo.h"
#include "mav/common/status.h"

namespace mav::localization::internal {

// InvalidArgument naming `name` ("left"/"right") for an empty, non-CV_8UC1 or wrongly sized image.
inline Status CheckImage(const char* name, const cv::Mat& image,
                         const camera::RectifiedStereo& rig) {
  std::ostringstream msg;
  msg << name << ": ";
  if (image.empty()) {
    msg << "empty image";
  } else if (image.type() != CV_8UC1) {
    msg << "expected an 8-bit single-channel image (CV_8UC1), got OpenCV type " << image.type();
  } else if (image.cols != rig.width || image.rows != rig.height) {
    msg << "size " << image.cols << "x" << image.rows << " differs from the rig's " << rig.width
        << "x" << rig.height;
  } else {
    return Status::Ok();
  }
  return Status::InvalidArgument(msg.str());
}

}  // namespace mav::localization::internal
