#pragma once
// mav.v1 mapping messages <-> the mapping service's domain types (mapper.h). Validation of
// request fields happens here, with messages that start with the field path as the request spells
// it ("boxes[2].min.x: not finite", "resolution_m: ...", "stereo.left.data: ...").

#include <optional>
#include <string>

#include <Eigen/Geometry>

#include "mav/v1/common.pb.h"
#include "mav/v1/mapping.pb.h"
#include "services/common/proto_codec.h"

#include "mav/camera/stereo.h"
#include "mav/common/status.h"
#include "mav/geometry/se3.h"
#include "mav/mapping/collision_eval.h"
#include "services/mapping/mapper.h"

namespace mav::mapping_service {

using service_common::CalibrationFromProto;  // services/common/proto_codec.h
using service_common::PoseFromProto;
using service_common::RigCalibration;
using service_common::ToProto;

// MappingMethod -> library method. UNSPECIFIED: nullopt when `allow_unspecified` (= "the most
// recent build"), else InvalidArgument "<field>: not set ...". Unknown values: InvalidArgument.
Result<std::optional<MappingMethod>> MethodFromProto(v1::MappingMethod method,
                                                     const std::string& field,
                                                     bool allow_unspecified);
v1::MappingMethod ToProto(MappingMethod method);

Result<PoseSource> PoseSourceFromProto(v1::PoseSource source);
v1::PoseSource ToProto(PoseSource source);

// Everything of a StartSessionRequest except the calibration (resolved by the service): keyframe
// rule and limits ("keyframes.min_translation_m: ..."), pose source. `defaults` carries the
// server's settings that the request does not have (queue length, pose wait).
Result<SessionConfig> SessionFromProto(const v1::StartSessionRequest& request,
                                       const SessionConfig& defaults);

using service_common::StereoFromProto;  // a StereoPair message as a FrameInput (pixels copied)

// The shared messages (boxes: "<field>.min.x: not finite", "<field>: min.z 3 > max.z 1") go
// through the one codec.
using service_common::BoxFromProto;
using service_common::ToProto;

// A BuildMapRequest: method (not UNSPECIFIED), resolution_m ([0.01, 2], 0 = 0.05), bounds,
// unknown handling, sparse_mesh options (0 = library default; ranges as in the proto) and the
// octomap options (validated; see docs/services.md for which per-build values are honoured).
Result<BuildRequest> BuildFromProto(const v1::BuildMapRequest& request);

void ToProto(const MapStats& stats, v1::BuildMapResponse* out);
void ToProto(const KeyframeResult& result, v1::InsertKeyframeResponse* out);
void ToProto(const MapperStatus& status, v1::MappingStatus* out);
v1::CollisionState ToProto(mapping::BoxQuery::Answer answer, bool unknown_is_collision);

// The enums of mapping.proto (tests/contract/shared_messages_test.cc checks each table).
inline constexpr auto kMappingMethodCodec =
    service_common::MakeEnumCodec<v1::MappingMethod, MappingMethod>(
        v1::MappingMethod_descriptor,
        {{v1::MAPPING_METHOD_SPARSE_MESH, MappingMethod::kSparseMesh},
         {v1::MAPPING_METHOD_OCTOMAP, MappingMethod::kOctomap}},
        std::nullopt);

// UNSPECIFIED means NONE.
inline constexpr auto kPoseSourceCodec = service_common::MakeEnumCodec<v1::PoseSource, PoseSource>(
    v1::PoseSource_descriptor,
    {{v1::POSE_SOURCE_NONE, PoseSource::kNone},
     {v1::POSE_SOURCE_LOCALIZATION, PoseSource::kLocalization},
     {v1::POSE_SOURCE_GROUND_TRUTH, PoseSource::kGroundTruth}},
    PoseSource::kNone);

// UNSPECIFIED means KEEP_UNKNOWN.
inline constexpr auto kUnknownHandlingCodec =
    service_common::MakeEnumCodec<v1::UnknownHandling, UnknownHandling>(
        v1::UnknownHandling_descriptor,
        {{v1::UNKNOWN_HANDLING_KEEP_UNKNOWN, UnknownHandling::kKeepUnknown},
         {v1::UNKNOWN_HANDLING_AS_OCCUPIED, UnknownHandling::kAsOccupied},
         {v1::UNKNOWN_HANDLING_AS_FREE, UnknownHandling::kAsFree}},
        UnknownHandling::kKeepUnknown);

// UNSPECIFIED means SAFETY.
inline constexpr auto kMapPreferenceCodec =
    service_common::MakeEnumCodec<v1::MapPreference, mapping::MapPreference>(
        v1::MapPreference_descriptor,
        {{v1::MAP_PREFERENCE_SAFETY, mapping::MapPreference::kSafety},
         {v1::MAP_PREFERENCE_MCC, mapping::MapPreference::kMcc}},
        mapping::MapPreference::kSafety);

// UNSPECIFIED means PLY_BINARY.
inline constexpr auto kMeshFormatCodec =
    service_common::MakeEnumCodec<v1::MeshFormat, mapping::PlyEncoding>(
        v1::MeshFormat_descriptor,
        {{v1::MESH_FORMAT_PLY_BINARY, mapping::PlyEncoding::kBinaryLittleEndian},
         {v1::MESH_FORMAT_PLY_ASCII, mapping::PlyEncoding::kAscii}},
        mapping::PlyEncoding::kBinaryLittleEndian);

}  // namespace mav::mapping_service
