#pragma once
// Conversions between common.proto messages and library types that every service needs.

#include "mav/v1/common.pb.h"

#include <cstdint>
#include <string>

#include <opencv2/core/mat.hpp>

#include "mav/camera/pinhole.h"
#include "mav/camera/stereo.h"
#include "mav/common/stats.h"
#include "mav/common/status.h"
#include "mav/dataset/stereo_pair.h"
#include "mav/geometry/se3.h"

namespace mav::service_common {

// The shortest text of a number for messages ("0.05", "1e+15").
std::string Number(double v);

void ToProto(const geometry::SE3& pose, v1::Pose* out);
void ToProto(const RuntimeStats& stats, v1::RuntimeStats* out);
void ToProto(const camera::PinholeRadTan& camera, v1::CameraIntrinsics* out);

// A Pose validated as common.proto says: finite position, quaternion norm within 1e-3 of 1
// (then normalised). InvalidArgument "<field>.position: not finite" / "<field>.orientation: ...".
Result<geometry::SE3> PoseFromProto(const v1::Pose& pose, const std::string& field);

// One camera's intrinsics; InvalidArgument naming "<field>.intrinsics...".
Result<camera::PinholeRadTan> CameraFromProto(const v1::CameraCalibration& camera,
                                              const std::string& field);

// A stereo rig from the proto; `field` prefixes error messages ("calibration.calibration").
// InvalidArgument naming the field: missing camera, non-positive size or focal length, non-unit
// quaternion, cameras of different sizes, zero baseline.
struct RigCalibration {
  camera::StereoCalibration calibration;
  bool rectified = false;
};
Result<RigCalibration> CalibrationFromProto(const v1::StereoCalibration& proto,
                                            const std::string& field);

// A StereoPair's pixels, copied. InvalidArgument naming "<field>.left" etc.: empty image,
// encoding not MONO8, data size != width*height, left/right sizes differ. Sizes against a
// calibration are the caller's to check.
Result<dataset::StereoPair> StereoFromProto(const v1::StereoPair& pair, const std::string& field);

}  // namespace mav::service_common
