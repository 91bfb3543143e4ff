#pragma once
// The one codec for the messages several services exchange (common.proto's vectors, boxes and
// poses, planning.proto's polynomial trajectories and yaw policy, stereo pairs and calibrations):
// one decoder per message with one set of rules, so a message is accepted or refused the same
// way, in the same words, by every service that takes it (tests/contract/shared_messages_test.cc).
// Refusals are InvalidArgument naming the field path from the `field` the caller passes
// ("trajectory.segments[3].duration_s: must be > 0 and finite, got 0").

#include "mav/v1/common.pb.h"
#include "mav/v1/planning.pb.h"

#include <cstdint>
#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "mav/camera/pinhole.h"
#include "mav/camera/stereo.h"
#include "mav/common/stats.h"
#include "mav/common/status.h"
#include "mav/dataset/stereo_pair.h"
#include "mav/geometry/polynomial_trajectory.h"
#include "mav/geometry/se3.h"
#include "services/common/proto_enum.h"

namespace mav::service_common {

// The shortest text of a number for messages ("0.05", "1e+15").
std::string Number(double v);

// ---- common.proto ------------------------------------------------------------------------------

// A finite vector; "<field>.x: not finite".
Result<Eigen::Vector3d> VectorFromProto(const v1::Vector3& v, const std::string& field);
void ToProto(const Eigen::Vector3d& v, v1::Vector3* out);

// An axis-aligned box with finite corners and min <= max on every axis ("<field>.min.y: not
// finite", "<field>: min.x 2 > max.x 1"). A caller that needs volume checks it on top.
Result<Eigen::AlignedBox3d> BoxFromProto(const v1::Box& box, const std::string& field);
void ToProto(const Eigen::AlignedBox3d& box, v1::Box* out);

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

// ---- planning.proto: trajectories ---------------------------------------------------------------

// UNSPECIFIED means CONSTANT.
inline constexpr auto kYawPolicyCodec = MakeEnumCodec<v1::YawPolicy, geometry::YawPolicy>(
    v1::YawPolicy_descriptor,
    {{v1::YAW_POLICY_CONSTANT, geometry::YawPolicy::kConstant},
     {v1::YAW_POLICY_ALONG_PATH, geometry::YawPolicy::kAlongPath},
     {v1::YAW_POLICY_SEGMENT, geometry::YawPolicy::kSegment}},
    geometry::YawPolicy::kConstant);

// At most this many segments per trajectory (a 4 MiB message holds about 20 000).
inline constexpr int kMaxTrajectorySegments = 10000;

// A trajectory as planning.proto describes it. Refused, naming the field: no segments or more
// than kMaxTrajectorySegments ("<field>.segments"), an unknown yaw policy ("<field>.yaw_policy"),
// a start yaw not finite, a segment's duration not > 0 and finite
// ("<field>.segments[i].duration_s"), not 6 finite coefficients per axis ("<field>.segments[i].x",
// "...x[k]"), yaw coefficients neither 0 nor 6 or not finite, SEGMENT yaw without them, and a
// total `duration_s` (0 = not given) that is not the sum of the segments' durations.
Result<geometry::PolynomialTrajectory> TrajectoryFromProto(const v1::PolynomialTrajectory& proto,
                                                           const std::string& field);
void ToProto(const geometry::PolynomialTrajectory& trajectory, v1::PolynomialTrajectory* out);

}  // namespace mav::service_common
