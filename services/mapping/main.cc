// mav-mapping: the Mapping gRPC service (control plane) building maps from mav/sensors/stereo and
// a pose stream (mav/localization/pose or mav/sim/ground_truth) on Cyclone DDS (data plane).
// docs/services.md lists flags and environment.

#include <iostream>

#include "mav/common/log.h"
#include "mav/transport/dds.h"
#include "mav/transport/flags.h"
#include "mav/transport/grpc_server.h"
#include "services/mapping/convert.h"
#include "services/mapping/dds_io.h"
#include "services/mapping/mapper.h"
#include "services/mapping/mapping_service.h"

namespace {

constexpr int64_t kDefaultPort = 50053;
constexpr char kPortEnv[] = "MAV_MAPPING_PORT";

int Fail(const std::string& message) {
  std::cerr << "mav-mapping: " << message << "\n";
  return 1;
}

int Usage(const std::string& message) {
  std::cerr << "mav-mapping: " << message << "\n";
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  // Before any thread exists, so that every thread inherits the blocked mask (sigwait below).
  mav::transport::BlockShutdownSignals();

  mav::transport::ServerOptions server_options;
  server_options.port = kDefaultPort;
  mav::transport::DdsOptions dds_options;
  mav::mapping_service::MappingServiceOptions service_options;
  std::string pose_source;
  std::string euroc;
  std::string simulator;
  mav::transport::FlagParser flags(
      "mav-mapping",
      "Serves mav.v1.Mapping over gRPC: maps (sparse multi-view meshing, OctoMap baseline) from\n"
      "mav/sensors/stereo and poses (mav/localization/pose or mav/sim/ground_truth) on Cyclone "
      "DDS.");
  mav::transport::AddServerFlags(&flags, &server_options, kPortEnv);
  mav::transport::AddDdsFlags(&flags, &dds_options);
  flags.AddString("pose-source", &pose_source,
                  "optional: start a session at start-up with poses from "
                  "ground-truth|localization|none; needs --euroc or --simulator");
  flags.AddString("euroc", &euroc, "calibration for --pose-source: an EuRoC directory");
  flags.AddString("simulator", &simulator,
                  "calibration for --pose-source: a simulator's host:port");
  flags.AddInt("queue-length", &service_options.queue_length,
               "live keyframes waiting for the worker before the oldest is dropped [1, 1000]");
  flags.AddInt("pose-wait-ms", &service_options.pose_wait_ms,
               "longest a live frame waits for its pose, ms");
  flags.AddInt("max-voxels", &service_options.max_voxels,
               "largest grid BuildMap builds (RESOURCE_EXHAUSTED above)");
  flags.ParseOrExit(argc, argv);
  if (const mav::Status s = mav::transport::ApplyPortEnv(flags, kPortEnv, &server_options);
      !s.ok()) {
    return Usage(s.message());
  }
  if (const mav::Status s = mav::transport::ApplyDdsEnv(flags, &dds_options); !s.ok()) {
    return Usage(s.message());
  }
  std::string why;
  if (!service_options.IsValid(&why)) return Usage(why);

  mav::v1::StartSessionRequest startup;
  if (!pose_source.empty()) {
    if (pose_source == "ground-truth") {
      startup.set_pose_source(mav::v1::POSE_SOURCE_GROUND_TRUTH);
    } else if (pose_source == "localization") {
      startup.set_pose_source(mav::v1::POSE_SOURCE_LOCALIZATION);
    } else if (pose_source == "none") {
      startup.set_pose_source(mav::v1::POSE_SOURCE_NONE);
    } else {
      return Usage("--pose-source: unknown source '" + pose_source +
                   "' (ground-truth|localization|none)");
    }
    if (euroc.empty() == simulator.empty()) {
      return Usage("--pose-source needs exactly one of --euroc or --simulator");
    }
    if (!euroc.empty()) {
      startup.mutable_calibration()->set_euroc_directory(euroc);
    } else {
      startup.mutable_calibration()->set_simulator_address(simulator);
    }
  } else if (!euroc.empty() || !simulator.empty()) {
    return Usage("--euroc/--simulator only go with --pose-source");
  }

  // The DdsIo feeds the mapper: it is created first and destroyed last; the input is switched off
  // before the mapper goes away.
  auto dds = mav::mapping_service::DdsIo::Create(dds_options);
  if (!dds.ok()) return Fail(dds.status().ToString());
  mav::mapping_service::Mapper mapper;
  (*dds)->Attach(&mapper);
  mav::mapping_service::MappingService service(&mapper, dds->get(), service_options);

  if (!pose_source.empty()) {
    mav::v1::MappingStatus status;
    const grpc::Status started = service.ApplyStartSession(startup, &status);
    if (!started.ok()) return Fail("--pose-source: " + started.error_message());
  }

  auto server = mav::transport::GrpcServer::Start(server_options, {&service},
                                                  {mav::v1::Mapping::service_full_name()});
  if (!server.ok()) return Fail(server.status().ToString());
  MAV_LOG(kInfo) << "mav-mapping ready: gRPC " << (*server)->target() << ", DDS domain "
                 << dds_options.domain;

  const int sig = mav::transport::WaitForShutdownSignal();
  MAV_LOG(kInfo) << "signal " << sig << ": shutting down";
  (*server)->Shutdown();
  (void)(*dds)->SetInput(false, mav::mapping_service::PoseSource::kNone);
  mapper.Shutdown();
  MAV_LOG(kInfo) << "received " << (*dds)->frames_received() << " stereo frames and "
                 << (*dds)->poses_received() << " poses";
  return 0;
}
