#pragma once
// mav.v1 localization messages <-> the localization service's domain types (localizer.h).
// Validation of request fields happens here, with messages that start with the field path as the
// request spells it ("sparse.ransac_iterations: ...", "stereo.left.data: ...").

#include <string>

#include "mav/v1/common.pb.h"
#include "mav/v1/localization.pb.h"
#include "services/common/proto_codec.h"

#include "mav/camera/stereo.h"
#include "mav/common/status.h"
#include "mav/geometry/se3.h"
#include "services/localization/localizer.h"

namespace mav::localization_service {

// LocalizationMethod -> Method. InvalidArgument "method: ..." for UNSPECIFIED or an unknown value.
Result<Method> MethodFromProto(v1::LocalizationMethod method);
v1::LocalizationMethod ToProto(Method method);

// Everything of a LocalizationConfigureRequest except the calibration (resolved by the service
// from its source): method, sparse/dense options (0 = library default; ranges as in the proto),
// initial_pose, output_frame, queue_length. InvalidArgument naming the field.
Result<LocalizerConfig> ConfigFromProto(const v1::LocalizationConfigureRequest& request);

using service_common::StereoFromProto;  // pixels copied; sizes checked by the Localizer

using service_common::CalibrationFromProto;
using service_common::PoseFromProto;
using service_common::RigCalibration;
using service_common::ToProto;  // geometry::SE3 -> v1::Pose, intrinsics
void ToProto(const RigPose& pose, v1::PoseWithCovariance* out);
void ToProto(const RigPose& pose, v1::ProcessStereoPairResponse* out);
void ToProto(const RigPose& pose, v1::TrajectoryPoint* out);
void ToProto(const camera::StereoCalibration& calibration, bool rectified,
             v1::StereoCalibration* out);
// The effective configuration: library defaults filled in, the calibration inline.
void ToProto(const LocalizerConfig& config, v1::LocalizationConfigureRequest* out);
// `dds_input`: whether the service is subscribed to mav/sensors/stereo.
void ToProto(const LocalizerStatus& status, bool dds_input, v1::LocalizationStatus* out);
v1::TrackingState ToProto(ReportedState state);
v1::LocalizationServiceState ToProto(LocalizerState state);

// The enum of localization.proto (tests/contract/shared_messages_test.cc checks the table).
// UNSPECIFIED is refused: the method has no default.
inline constexpr auto kMethodCodec = service_common::MakeEnumCodec<v1::LocalizationMethod, Method>(
    v1::LocalizationMethod_descriptor,
    {{v1::LOCALIZATION_METHOD_SPARSE_PIXEL, Method::kSparsePixel},
     {v1::LOCALIZATION_METHOD_SPARSE_SUBPIXEL, Method::kSparseSubpixel},
     {v1::LOCALIZATION_METHOD_DENSE, Method::kDense}},
    std::nullopt);

}  // namespace mav::localization_service
