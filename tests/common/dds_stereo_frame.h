#pragma once
// A small mono8 stereo sample as a service's DDS reader receives it, with a correct CRC-32: the
// start of the tests of the readers' integrity check. It owns the pixels the sample points at.

#include <cstdint>
#include <vector>

#include "mav_sensors.h"
#include "services/common/dds_codec.h"

namespace mav::test_support {

class DdsStereoFrame {
 public:
  // `width` x `height` pixels, every left pixel `left_value`, every right one `right_value`.
  DdsStereoFrame(uint32_t width, uint32_t height, uint8_t left_value, uint8_t right_value)
      : left_(width * height, left_value), right_(width * height, right_value) {
    frame_.width = width;
    frame_.height = height;
    frame_.encoding = mav_dds_PIXEL_FORMAT_MONO8;
    frame_.left._buffer = left_.data();
    frame_.left._length = static_cast<uint32_t>(left_.size());
    frame_.right._buffer = right_.data();
    frame_.right._length = static_cast<uint32_t>(right_.size());
    frame_.crc32 =
        service_common::StereoCrc32(left_.data(), left_.size(), right_.data(), right_.size());
  }
  // The sample points into this object: neither copied nor moved.
  DdsStereoFrame(const DdsStereoFrame&) = delete;
  DdsStereoFrame& operator=(const DdsStereoFrame&) = delete;

  mav_dds_StereoFrame& sample() { return frame_; }

 private:
  std::vector<uint8_t> left_, right_;
  mav_dds_StereoFrame frame_{};
};

}  // namespace mav::test_support
