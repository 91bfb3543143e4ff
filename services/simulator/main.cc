// mav-simulator: the Simulator gRPC service (control plane) replaying a rendered preset or a
// recorded EuRoC directory on Cyclone DDS (data plane): mav/sensors/stereo, mav/sensors/imu and
// mav/sim/ground_truth; in flight mode it flies a contest task on mav/control/actuators and
// publishes the IMU, the pose sensors (mav/localization/pose) and the ground truth.
// docs/services.md lists flags and environment.

#include <filesystem>

#include "mav/sim/scenario_source.h"
#include "mav/transport/service_main.h"
#include "services/simulator/dds_io.h"
#include "services/simulator/simulator_service.h"

int main(int argc, char** argv) {
  mav::transport::ServiceRunner runner(
      {"mav-simulator",
       "Serves mav.v1.Simulator over gRPC and publishes mav/sensors/stereo, mav/sensors/imu and\n"
       "mav/sim/ground_truth on Cyclone DDS; in flight mode it steps a multicopter on\n"
       "mav/control/actuators and also publishes the pose sensors on mav/localization/pose.",
       50051, "MAV_SIMULATOR_PORT"});
  std::string preset;
  int64_t frames = 0;
  std::string euroc;
  std::string flight_task;
  bool lockstep = false;
  int64_t flight_seed = 1;
  mav::simulator_service::SimulatorServiceOptions options;
  runner.flags().AddString("preset", &preset, "optional: load this preset at start-up");
  runner.flags().AddInt("frames", &frames, "frames of --preset (0 = full length)");
  runner.flags().AddString("euroc", &euroc, "optional: load this EuRoC directory at start-up");
  runner.flags().AddInt("max-occupancy-memory-mb", &options.max_occupancy_memory_mb,
                        "memory GetGroundTruthOccupancy calls may use at once, MiB");
  runner.flags().AddString("flight-task", &flight_task,
                           "optional: load this flight task at start-up (t3_1 ... t4_3, or a "
                           "task file .yaml); StartFlight starts it");
  runner.flags().AddBool("lockstep", &lockstep,
                         "--flight-task: lock-step (wait for each step's actuator command) "
                         "instead of real time");
  runner.flags().AddInt("flight-seed", &flight_seed, "--flight-task: sensor noise seed");
  runner.flags().AddString("plant-map", &options.plant_map_path,
                           "the OctoMap of the built-in t4_3 (power plant)");
  std::string render_priority = "normal";
  runner.flags().AddString("render-priority", &render_priority,
                           "normal|idle: idle renders the replay's frames only on CPU time no "
                           "other thread wants (SCHED_IDLE; for real-time playback)");
  runner.ParseFlagsOrExit(argc, argv);
  // Its large blocks are rendered pairs and their DDS samples, recycled at frame rate.
  mav::transport::KeepLargeSampleBuffers();
  if (render_priority == "idle") {
    options.render_priority = mav::sim::FramePrefetcher::Priority::kIdle;
  } else if (render_priority != "normal") {
    return runner.Usage("--render-priority: '" + render_priority + "' is not one of normal|idle");
  }
  if (!preset.empty() && !euroc.empty()) return runner.Usage("--preset and --euroc are exclusive");
  if (flight_task.empty() && (lockstep || runner.flags().WasSet("flight-seed"))) {
    return runner.Usage("--lockstep/--flight-seed need --flight-task");
  }
  if (flight_seed < 0) return runner.Usage("--flight-seed: must be >= 0");
  std::string why;
  if (!options.IsValid(&why)) return runner.Usage(why);

  auto sink = mav::simulator_service::DdsStreamSink::Create(runner.dds_options());
  if (!sink.ok()) return runner.Fail(sink.status());
  mav::simulator_service::SimulatorService service(sink->get(), options, sink->get());
  if (!preset.empty() || !euroc.empty()) {
    mav::sim::PresetRequest request;
    request.name = preset;
    request.frames = frames;
    auto source = !preset.empty() ? mav::sim::OpenPreset(request) : mav::sim::OpenEuroc(euroc);
    if (!source.ok()) return runner.Fail(source.status());
    if (mav::Status s = service.player().Load(std::move(*source)); !s.ok()) return runner.Fail(s);
  }
  if (!flight_task.empty()) {
    mav::v1::LoadFlightTaskRequest request;
    if (std::filesystem::path(flight_task).extension() == ".yaml") {
      request.set_path(flight_task);
    } else {
      request.set_builtin(flight_task);
    }
    request.set_lockstep(lockstep);
    request.set_seed(static_cast<uint64_t>(flight_seed));
    mav::v1::FlightStatus status;
    const grpc::Status loaded = service.ApplyLoadFlightTask(request, {}, &status);
    if (!loaded.ok()) {
      return runner.Fail(mav::Status::InvalidArgument("--flight-task: " + loaded.error_message()));
    }
  }
  return runner.Serve({&service}, {mav::v1::Simulator::service_full_name()},
                      [&] { service.Shutdown(); });
}
