// mav-mapping: the Mapping gRPC service (control plane) building maps from mav/sensors/stereo and
// a pose stream (mav/localization/pose or mav/sim/ground_truth) on Cyclone DDS (data plane).
// docs/services.md lists flags and environment.

#include "mav/common/log.h"
#include "mav/common/text.h"
#include "mav/transport/service_main.h"
#include "services/common/calibration_source.h"
#include "services/mapping/dds_io.h"
#include "services/mapping/mapper.h"
#include "services/mapping/mapping_service.h"

int main(int argc, char** argv) {
  mav::transport::ServiceRunner runner(
      {"mav-mapping",
       "Serves mav.v1.Mapping over gRPC: maps (sparse multi-view meshing, OctoMap baseline) from\n"
       "mav/sensors/stereo and poses (mav/localization/pose or mav/sim/ground_truth) on Cyclone "
       "DDS.",
       50053, "MAV_MAPPING_PORT"});
  mav::mapping_service::MappingServiceOptions service_options;
  std::string pose_source;
  mav::service_common::CalibrationFlags calibration;
  mav::FlagParser& flags = runner.flags();
  flags.AddString("pose-source", &pose_source,
                  "optional: start a session at start-up with poses from "
                  "ground-truth|localization|none; needs --euroc or --simulator");
  calibration.Register(&flags, "--pose-source");
  flags.AddInt("queue-length", &service_options.queue_length,
               "live keyframes waiting for the worker before the oldest is dropped [1, 1000]");
  flags.AddInt("pose-wait-ms", &service_options.pose_wait_ms,
               "longest a live frame waits for its pose, ms");
  flags.AddInt("max-voxels", &service_options.max_voxels,
               "largest grid BuildMap builds (RESOURCE_EXHAUSTED above)");
  runner.ParseFlagsOrExit(argc, argv);
  std::string why;
  if (!service_options.IsValid(&why)) return runner.Usage(why);

  mav::v1::StartSessionRequest startup;
  if (pose_source == "ground-truth") {
    startup.set_pose_source(mav::v1::POSE_SOURCE_GROUND_TRUTH);
  } else if (pose_source == "localization") {
    startup.set_pose_source(mav::v1::POSE_SOURCE_LOCALIZATION);
  } else if (pose_source == "none") {
    startup.set_pose_source(mav::v1::POSE_SOURCE_NONE);
  } else if (!pose_source.empty()) {
    return runner.Usage("--pose-source: unknown source " + mav::QuoteForError(pose_source) +
                        " (ground-truth|localization|none)");
  }
  auto source = calibration.Source(!pose_source.empty(), "--pose-source");
  if (!source.ok()) return runner.Usage(source.status().message());
  if (source->has_value()) *startup.mutable_calibration() = **source;

  // The DdsIo feeds the mapper: it is created first and destroyed last; the input is switched off
  // before the mapper goes away.
  auto dds = mav::mapping_service::DdsIo::Create(runner.dds_options());
  if (!dds.ok()) return runner.Fail(dds.status());
  mav::mapping_service::Mapper mapper;
  (*dds)->Attach(&mapper);
  mav::mapping_service::MappingService service(&mapper, dds->get(), service_options);

  if (!pose_source.empty()) {
    mav::v1::MappingStatus status;
    const grpc::Status started = service.ApplyStartSession(startup, {}, &status);
    if (!started.ok()) {
      return runner.Fail(mav::Status::InvalidArgument("--pose-source: " + started.error_message()));
    }
  }
  return runner.Serve({&service}, {mav::v1::Mapping::service_full_name()}, [&] {
    (void)(*dds)->SetInput(false);
    mapper.Shutdown();
    MAV_LOG(kInfo) << "received " << (*dds)->frames_received() << " stereo frames and "
                   << (*dds)->poses_received() << " poses";
  });
}
