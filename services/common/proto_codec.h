#pragma once
// Conversions between common.proto messages and library types that every service needs.

#include "mav/v1/common.pb.h"

#include "mav/camera/pinhole.h"
#include "mav/geometry/se3.h"

namespace mav::services {

void ToProto(const geometry::SE3& pose, v1::Pose* out);
void ToProto(const camera::PinholeRadTan& camera, v1::CameraIntrinsics* out);

}  // namespace mav::services
