// libFuzzer target: the proto -> domain converters the services run on every request before any
// library sees it (services/*/convert.h, services/common/proto_codec.h). The first byte picks
// the message, the rest is its wire encoding; bytes protobuf cannot parse are not kept.
//
// Every converter must return a value or an error, never crash or trip a sanitizer, and an error
// must be one a client can act on: InvalidArgument (or ResourceExhausted for sizes beyond the
// contract), with a message that starts with a field path and stays bounded whatever the input
// (QuoteForError truncates echoed values: issue 8 defect 4). What converts must be usable: a
// trajectory has a positive finite duration, a pose's quaternion is normalised.

#include <cmath>
#include <string>

#include "fuzz_checks.h"
#include "services/common/proto_codec.h"
#include "services/control/convert.h"
#include "services/planning/convert.h"
#include "services/simulator/convert.h"

namespace {

using namespace mav;

template <typename T>
void CheckConverted(const Result<T>& r) {
  if (r.ok()) return;
  const StatusCode code = r.status().code();
  MAV_CHECK(code == StatusCode::kInvalidArgument || code == StatusCode::kResourceExhausted)
      << r.status().ToString().substr(0, 300);
  MAV_CHECK(!r.status().message().empty());
  MAV_CHECK(r.status().message().size() <= 1024) << r.status().message().substr(0, 300);
}

void CheckTrajectory(const Result<geometry::PolynomialTrajectory>& r) {
  CheckConverted(r);
  if (!r.ok()) return;
  const double duration = r->duration_s();
  MAV_CHECK(std::isfinite(duration) && duration > 0);
  MAV_CHECK(!r->segments().empty());
  // Evaluating must not trip a sanitizer (huge finite coefficients may still overflow to inf:
  // the consumers' checks, not the converter's).
  for (double t : {0.0, 0.5 * duration, duration}) (void)r->Evaluate(t);
}

template <typename M>
bool Parse(const uint8_t* data, size_t size, M* message) {
  return message->ParseFromArray(data, static_cast<int>(size));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return -1;
  const uint8_t which = data[0] % 11;
  ++data;
  --size;
  switch (which) {
    case 0: {
      v1::StereoCalibration m;
      if (!Parse(data, size, &m)) return -1;
      CheckConverted(service_common::CalibrationFromProto(m, "calibration"));
      break;
    }
    case 1: {
      v1::StereoPair m;
      if (!Parse(data, size, &m)) return -1;
      CheckConverted(service_common::StereoFromProto(m, "pair"));
      break;
    }
    case 2: {
      v1::Pose m;
      if (!Parse(data, size, &m)) return -1;
      const Result<geometry::SE3> pose = service_common::PoseFromProto(m, "pose");
      CheckConverted(pose);
      if (pose.ok()) {
        MAV_CHECK(pose->Translation().allFinite());
        MAV_CHECK(std::abs(pose->Rotation().norm() - 1) < 1e-9);
      }
      break;
    }
    case 3: {
      v1::PlanPathRequest m;
      if (!Parse(data, size, &m)) return -1;
      CheckConverted(planning_service::PlanRequestFromProto(m));
      break;
    }
    case 4: {
      v1::BuildRoadmapRequest m;
      if (!Parse(data, size, &m)) return -1;
      CheckConverted(planning_service::RoadmapOptionsFromProto(m));
      break;
    }
    case 5: {
      v1::MapOptions m;
      if (!Parse(data, size, &m)) return -1;
      CheckConverted(planning_service::MapOptionsFromProto(m, "options"));
      break;
    }
    case 6: {
      v1::PolynomialTrajectory m;
      if (!Parse(data, size, &m)) return -1;
      // The one decoder mav-planning and mav-control share.
      CheckTrajectory(service_common::TrajectoryFromProto(m, "trajectory"));
      break;
    }
    case 7: {
      v1::ControlConfigureRequest m;
      if (!Parse(data, size, &m)) return -1;
      CheckConverted(control_service::ConfigFromProto(m));
      break;
    }
    case 8: {
      v1::LoadScenarioRequest m;
      if (!Parse(data, size, &m)) return -1;
      CheckConverted(simulator_service::FromProto(m));
      break;
    }
    case 9: {
      v1::SimulatorStartRequest m;
      if (!Parse(data, size, &m)) return -1;
      CheckConverted(simulator_service::FromProto(m));
      break;
    }
    default: {
      v1::LoadFlightTaskRequest m;
      if (!Parse(data, size, &m)) return -1;
      CheckConverted(simulator_service::FromProto(m));
      break;
    }
  }
  return 0;
}
