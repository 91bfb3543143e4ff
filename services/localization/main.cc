// mav-localization: the Localization gRPC service (control plane) running stereo visual odometry
// on mav/sensors/stereo and publishing mav/localization/pose on Cyclone DDS (data plane).
// docs/services.md lists flags and environment.

#include <iostream>

#include "mav/common/log.h"
#include "mav/localization/odometry.h"
#include "mav/transport/dds.h"
#include "mav/transport/flags.h"
#include "mav/transport/grpc_server.h"
#include "services/localization/convert.h"
#include "services/localization/dds_io.h"
#include "services/localization/localization_service.h"
#include "services/localization/pipeline.h"

namespace {

constexpr int64_t kDefaultPort = 50052;
constexpr char kPortEnv[] = "MAV_LOCALIZATION_PORT";

int Fail(const std::string& message) {
  std::cerr << "mav-localization: " << message << "\n";
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  // Before any thread exists, so that every thread inherits the blocked mask (sigwait below).
  mav::transport::BlockShutdownSignals();

  mav::transport::ServerOptions server_options;
  server_options.port = kDefaultPort;
  mav::transport::DdsOptions dds_options;
  std::string method;
  std::string euroc;
  std::string simulator;
  mav::transport::FlagParser flags(
      "mav-localization",
      "Serves mav.v1.Localization over gRPC: stereo visual odometry on mav/sensors/stereo,\n"
      "poses on mav/localization/pose (Cyclone DDS).");
  mav::transport::AddServerFlags(&flags, &server_options, kPortEnv);
  mav::transport::AddDdsFlags(&flags, &dds_options);
  flags.AddString("method", &method,
                  "optional: configure at start-up with this method "
                  "(sparse-pixel|sparse-subpixel|dense); needs --euroc or --simulator");
  flags.AddString("euroc", &euroc, "calibration for --method: an EuRoC directory");
  flags.AddString("simulator", &simulator, "calibration for --method: a simulator's host:port");
  flags.ParseOrExit(argc, argv);
  if (const mav::Status s = mav::transport::ApplyPortEnv(flags, kPortEnv, &server_options);
      !s.ok()) {
    std::cerr << "mav-localization: " << s.message() << "\n";
    return 2;
  }
  if (const mav::Status s = mav::transport::ApplyDdsEnv(flags, &dds_options); !s.ok()) {
    std::cerr << "mav-localization: " << s.message() << "\n";
    return 2;
  }
  mav::v1::LocalizationConfigureRequest startup;
  if (!method.empty()) {
    const auto parsed = mav::localization::ParseMethod(method);
    if (!parsed.has_value()) {
      std::cerr << "mav-localization: --method: unknown method '" << method
                << "' (sparse-pixel|sparse-subpixel|dense)\n";
      return 2;
    }
    if (euroc.empty() == simulator.empty()) {
      std::cerr << "mav-localization: --method needs exactly one of --euroc or --simulator\n";
      return 2;
    }
    startup.set_method(mav::localization_service::ToProto(*parsed));
    if (!euroc.empty()) {
      startup.mutable_calibration()->set_euroc_directory(euroc);
    } else {
      startup.mutable_calibration()->set_simulator_address(simulator);
    }
  } else if (!euroc.empty() || !simulator.empty()) {
    std::cerr << "mav-localization: --euroc/--simulator only go with --method\n";
    return 2;
  }

  // The DdsIo publishes the localizer's poses and feeds it live frames: it is created first and
  // destroyed last; the input is switched off before the localizer goes away.
  auto dds = mav::localization_service::DdsIo::Create(dds_options);
  if (!dds.ok()) return Fail(dds.status().ToString());
  mav::localization_service::Localizer localizer(dds->get());
  (*dds)->Attach(&localizer);
  mav::localization_service::LocalizationService service(&localizer, dds->get());

  if (!method.empty()) {
    mav::v1::LocalizationStatus status;
    const grpc::Status configured = service.ApplyConfigure(startup, &status);
    if (!configured.ok()) return Fail("--method: " + configured.error_message());
  }

  auto server = mav::transport::GrpcServer::Start(server_options, {&service},
                                                  {mav::v1::Localization::service_full_name()});
  if (!server.ok()) return Fail(server.status().ToString());
  MAV_LOG(kInfo) << "mav-localization ready: gRPC " << (*server)->target() << ", DDS domain "
                 << dds_options.domain;

  const int sig = mav::transport::WaitForShutdownSignal();
  MAV_LOG(kInfo) << "signal " << sig << ": shutting down";
  (*server)->Shutdown();
  (void)(*dds)->SetStereoInput(false);
  localizer.Shutdown();
  MAV_LOG(kInfo) << "received " << (*dds)->frames_received() << " stereo frames and "
                 << (*dds)->imu_samples_received() << " IMU samples, published "
                 << (*dds)->poses_published() << " poses";
  return 0;
}
