// mav-simulator: the Simulator gRPC service (control plane) publishing stereo frames, IMU samples
// and ground truth on Cyclone DDS (data plane). docs/services.md lists flags and environment.

#include <cstdlib>
#include <iostream>

#include "mav/common/log.h"
#include "mav/transport/dds.h"
#include "mav/transport/flags.h"
#include "mav/transport/grpc_server.h"
#include "services/simulator/dds_io.h"
#include "services/simulator/simulator_service.h"

namespace {

constexpr int64_t kDefaultPort = 50051;
constexpr char kPortEnv[] = "MAV_SIMULATOR_PORT";

int Fail(const mav::Status& status) {
  std::cerr << "mav-simulator: " << status.ToString() << "\n";
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  // Before any thread exists, so that every thread inherits the blocked mask (sigwait below).
  mav::transport::BlockShutdownSignals();

  mav::transport::ServerOptions server_options;
  server_options.port = kDefaultPort;
  mav::transport::DdsOptions dds_options;
  std::string preset;
  int64_t frames = 0;
  std::string euroc;
  mav::transport::FlagParser flags(
      "mav-simulator",
      "Serves mav.v1.Simulator over gRPC and publishes mav/sensors/stereo, mav/sensors/imu and\n"
      "mav/sim/ground_truth on Cyclone DDS.");
  mav::transport::AddServerFlags(&flags, &server_options, kPortEnv);
  mav::transport::AddDdsFlags(&flags, &dds_options);
  flags.AddString("preset", &preset, "optional: load this preset at start-up");
  flags.AddInt("frames", &frames, "frames of --preset (0 = full length)");
  flags.AddString("euroc", &euroc, "optional: load this EuRoC directory at start-up");
  flags.ParseOrExit(argc, argv);
  if (const mav::Status s = mav::transport::ApplyPortEnv(flags, kPortEnv, &server_options);
      !s.ok()) {
    std::cerr << "mav-simulator: " << s.message() << "\n";
    return 2;
  }
  if (const mav::Status s = mav::transport::ApplyDdsEnv(flags, &dds_options); !s.ok()) {
    std::cerr << "mav-simulator: " << s.message() << "\n";
    return 2;
  }
  if (!preset.empty() && !euroc.empty()) {
    std::cerr << "mav-simulator: --preset and --euroc are exclusive\n";
    return 2;
  }

  auto sink = mav::simulator_service::DdsStreamSink::Create(dds_options);
  if (!sink.ok()) return Fail(sink.status());
  mav::simulator_service::SimulatorService service(sink->get());

  if (!preset.empty() || !euroc.empty()) {
    mav::simulator_service::PresetRequest request;
    request.name = preset;
    request.frames = frames;
    auto source =
        !preset.empty() ? mav::simulator_service::OpenPreset(request) : mav::simulator_service::OpenEuroc(euroc);
    if (!source.ok()) return Fail(source.status());
    service.player().Load(std::move(*source));
  }

  auto server = mav::transport::GrpcServer::Start(server_options, {&service},
                                                  {mav::v1::Simulator::service_full_name()});
  if (!server.ok()) return Fail(server.status());
  MAV_LOG(kInfo) << "mav-simulator ready: gRPC " << (*server)->target() << ", DDS domain "
                 << dds_options.domain;

  const int sig = mav::transport::WaitForShutdownSignal();
  MAV_LOG(kInfo) << "signal " << sig << ": shutting down";
  (*server)->Shutdown();
  return 0;
}
