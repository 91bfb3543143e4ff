#pragma once
// Codec pieces every service shares for the DDS data-plane types (protos/dds/*.idl): the stereo
// frame checksum and integrity check, and the fixed-size id strings.

#include <cstddef>
#include <cstdint>

#include "mav_sensors.h"
#include "mav_state.h"

#include "mav/common/status.h"
#include "services/common/proto_codec.h"

namespace mav::service_common {

// CRC-32 (IEEE 802.3, zlib's crc32) over `left` followed by `right`, as the IDL specifies.
uint32_t StereoCrc32(const uint8_t* left, size_t left_size, const uint8_t* right,
                     size_t right_size);

// DataLoss naming the field when the sample is inconsistent: encoding, "left: N bytes, expected
// width*height = M", or "crc32: got X, computed Y".
Status CheckStereoFrame(const mav_dds_StereoFrame& frame);

// A checked frame's pixels, copied out of the (loaned) sample buffers.
dataset::StereoPair StereoFromDds(const mav_dds_StereoFrame& frame);

// "<field>.x: not finite" for the first component that is not.
Status CheckFinite(const mav_dds_Vector3& v, const char* field);

// A pose sample's position and orientation, checked as the IDL says (every service that reads
// poses, the same rule): finite position, quaternion (w first) of norm within 1e-3 of 1, then
// normalised. InvalidArgument "position.y: not finite" / "orientation: norm 1.5, expected a unit
// quaternion". The tracking state is the reader's to judge.
Result<geometry::SE3> PoseFromDds(const mav_dds_Vector3& position,
                                  const mav_dds_Quaternion& orientation);

// Copies a NUL-terminated id into an IDL string<32> field, truncating if needed.
void CopyId(const char* id, char (&out)[33]);

// A pose sample T_world_<child_frame_id> at t_ns for the default vehicle (frame_id "world");
// covariance, tracking state and statistics are left zero for the caller.
mav_dds_PoseWithCovariance PoseToDds(uint64_t sequence, int64_t t_ns, int64_t publish_t_ns,
                                     const char* child_frame_id,
                                     const geometry::SE3& T_world_child);

}  // namespace mav::service_common
