#include "services/common/dds_codec.h"

#include <cmath>
#include <cstring>
#include <string>

#include <zlib.h>

namespace mav::service_common {

uint32_t StereoCrc32(const uint8_t* left, size_t left_size, const uint8_t* right,
                     size_t right_size) {
  uLong crc = crc32(0L, Z_NULL, 0);
  crc = crc32_z(crc, left, left_size);
  crc = crc32_z(crc, right, right_size);
  return static_cast<uint32_t>(crc);
}

Status CheckFinite(const mav_dds_Vector3& v, const char* field) {
  if (!std::isfinite(v.x)) return Status::InvalidArgument(std::string(field) + ".x: not finite");
  if (!std::isfinite(v.y)) return Status::InvalidArgument(std::string(field) + ".y: not finite");
  if (!std::isfinite(v.z)) return Status::InvalidArgument(std::string(field) + ".z: not finite");
  return Status::Ok();
}

Result<geometry::SE3> PoseFromDds(const mav_dds_Vector3& position,
                                  const mav_dds_Quaternion& orientation) {
  MAV_RETURN_IF_ERROR(CheckFinite(position, "position"));
  const mav_dds_Quaternion& q = orientation;
  const double norm = std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
  if (!std::isfinite(norm) || std::abs(norm - 1.0) > 1e-3) {
    return Status::InvalidArgument("orientation: norm " + Number(norm) +
                                   ", expected a unit quaternion (w first)");
  }
  // SE3 normalizes only a quaternion that is not unit to rounding: a unit one passes bit for bit.
  return geometry::SE3(Eigen::Quaterniond(q.w, q.x, q.y, q.z),
                       Eigen::Vector3d(position.x, position.y, position.z));
}

Status CheckStereoFrame(const mav_dds_StereoFrame& frame) {
  const std::string where = "stereo frame " + std::to_string(frame.sequence_number) + ": ";
  if (frame.encoding != mav_dds_PIXEL_FORMAT_MONO8) {
    return Status::DataLoss(where + "encoding: expected MONO8");
  }
  if (frame.width == 0 || frame.height == 0) return Status::DataLoss(where + "width/height: zero");
  const uint64_t expected = static_cast<uint64_t>(frame.width) * frame.height;
  if (frame.left._length != expected) {
    return Status::DataLoss(where + "left: " + std::to_string(frame.left._length) +
                            " bytes, expected width*height = " + std::to_string(expected));
  }
  if (frame.right._length != expected) {
    return Status::DataLoss(where + "right: " + std::to_string(frame.right._length) +
                            " bytes, expected width*height = " + std::to_string(expected));
  }
  const uint32_t crc =
      StereoCrc32(frame.left._buffer, frame.left._length, frame.right._buffer, frame.right._length);
  if (crc != frame.crc32) {
    return Status::DataLoss(where + "crc32: got " + std::to_string(frame.crc32) + ", computed " +
                            std::to_string(crc));
  }
  return Status::Ok();
}

dataset::StereoPair StereoFromDds(const mav_dds_StereoFrame& frame) {
  dataset::StereoPair out;
  out.t_ns = frame.t_ns;
  out.rectified = frame.rectified;
  const int rows = static_cast<int>(frame.height);
  const int cols = static_cast<int>(frame.width);
  // The loaned buffers go back to DDS after the take: copy.
  out.left = cv::Mat(rows, cols, CV_8UC1, frame.left._buffer).clone();
  out.right = cv::Mat(rows, cols, CV_8UC1, frame.right._buffer).clone();
  return out;
}

void CopyId(const char* id, char (&out)[33]) {
  std::strncpy(out, id, sizeof(out) - 1);
  out[sizeof(out) - 1] = '\0';
}

mav_dds_PoseWithCovariance PoseToDds(uint64_t sequence, int64_t t_ns, int64_t publish_t_ns,
                                     const char* child_frame_id,
                                     const geometry::SE3& T_world_child) {
  mav_dds_PoseWithCovariance out{};
  out.vehicle_id = mav_dds_kDefaultVehicleId;
  out.sequence_number = sequence;
  out.t_ns = t_ns;
  out.publish_t_ns = publish_t_ns;
  CopyId("world", out.frame_id);
  CopyId(child_frame_id, out.child_frame_id);
  const Eigen::Vector3d& t = T_world_child.Translation();
  out.position = {t.x(), t.y(), t.z()};
  const Eigen::Quaterniond& q = T_world_child.Rotation();
  out.orientation = {q.w(), q.x(), q.y(), q.z()};
  return out;
}

}  // namespace mav::service_common
