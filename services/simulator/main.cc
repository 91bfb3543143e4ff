// mav-simulator: the Simulator gRPC service (control plane) replaying a rendered preset or a
// recorded EuRoC directory on Cyclone DDS (data plane): mav/sensors/stereo, mav/sensors/imu and
// mav/sim/ground_truth. docs/services.md lists flags and environment.

#include "mav/sim/scenario_source.h"
#include "mav/transport/service_main.h"
#include "services/simulator/dds_io.h"
#include "services/simulator/simulator_service.h"

int main(int argc, char** argv) {
  mav::transport::ServiceRunner runner(
      {"mav-simulator",
       "Serves mav.v1.Simulator over gRPC and publishes mav/sensors/stereo, mav/sensors/imu and\n"
       "mav/sim/ground_truth on Cyclone DDS.",
       50051, "MAV_SIMULATOR_PORT"});
  std::string preset;
  int64_t frames = 0;
  std::string euroc;
  mav::simulator_service::SimulatorServiceOptions options;
  runner.flags().AddString("preset", &preset, "optional: load this preset at start-up");
  runner.flags().AddInt("frames", &frames, "frames of --preset (0 = full length)");
  runner.flags().AddString("euroc", &euroc, "optional: load this EuRoC directory at start-up");
  runner.flags().AddInt("max-occupancy-memory-mb", &options.max_occupancy_memory_mb,
                        "memory GetGroundTruthOccupancy calls may use at once, MiB");
  runner.ParseFlagsOrExit(argc, argv);
  if (!preset.empty() && !euroc.empty()) return runner.Usage("--preset and --euroc are exclusive");
  std::string why;
  if (!options.IsValid(&why)) return runner.Usage(why);

  auto sink = mav::simulator_service::DdsStreamSink::Create(runner.dds_options());
  if (!sink.ok()) return runner.Fail(sink.status());
  mav::simulator_service::SimulatorService service(sink->get(), options);
  if (!preset.empty() || !euroc.empty()) {
    mav::sim::PresetRequest request;
    request.name = preset;
    request.frames = frames;
    auto source = !preset.empty() ? mav::sim::OpenPreset(request) : mav::sim::OpenEuroc(euroc);
    if (!source.ok()) return runner.Fail(source.status());
    if (mav::Status s = service.player().Load(std::move(*source)); !s.ok()) return runner.Fail(s);
  }
  return runner.Serve({&service}, {mav::v1::Simulator::service_full_name()},
                      [&] { service.player().Shutdown(); });
}
