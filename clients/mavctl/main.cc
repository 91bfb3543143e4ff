// mavctl: command-line client of the MAV stack's services (docs/services.md).
//
//   mavctl sim load --preset room-easy --frames 100 | --euroc DIR
//   mavctl sim start --rate 1.0 | --fast  [--loop] [--wait-subscribers N]
//   mavctl sim pause | sim step N | sim status | sim calibration
//   mavctl sim occupancy --out FILE [--resolution 0.05] [--format bt|mavocc]
//   mavctl health [--port P] [--service NAME]
//   mavctl listen [--topic stereo|imu|ground_truth|all] [--frames N] [--timeout S]
//                 [--wake listener|waitset] [--keep-last N] [--dds-shm]
//   mavctl sim flight load|run|pause|status   (the simulator's flight mode)
//   mavctl ctl configure|arm|disarm|hover|trajectory|gains|state|status   (mav-control)
//   mavctl plan load|roadmap|path|legs|get|sample|status   (mav-planning)
//   mavctl mission run --mission FILE ...   (a mission through the services, mission_commands.h)
//
// Every RPC has a deadline (--timeout, default 10 s). Exit status: 0 success, 1 the call failed
// (message on stderr names the address and the status), 2 usage error.

#include <cmath>
#include <cstdio>
#include <exception>
#include <fstream>
#include <functional>
#include <iomanip>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "mav/v1/simulator.grpc.pb.h"

#include "clients/mavctl/connection.h"
#include "clients/mavctl/control_commands.h"
#include "clients/mavctl/listen.h"
#include "clients/mavctl/localization_commands.h"
#include "clients/mavctl/mapping_commands.h"
#include "clients/mavctl/mission_commands.h"
#include "clients/mavctl/plan_commands.h"
#include "mav/common/file.h"
#include "mav/common/parse.h"
#include "mav/common/time.h"
#include "mav/transport/dds.h"
#include "mav/transport/flags.h"
#include "mav/transport/grpc_server.h"
#include "mav/transport/service_main.h"

namespace {

using mav::transport::FlagParser;

constexpr int64_t kSimulatorPort = 50051;
constexpr char kSimulatorPortEnv[] = "MAV_SIMULATOR_PORT";

constexpr char kUsage[] =
    "Usage: mavctl <command> [flags]   (mavctl <command> --help for its flags)\n"
    "Commands:\n"
    "  sim load --preset NAME [--frames N] [--seed S] [--rectified] | --euroc DIR\n"
    "  sim start --rate FACTOR | --fast  [--loop] [--wait-subscribers N] [--wait-timeout S]\n"
    "  sim pause\n"
    "  sim step N\n"
    "  sim status\n"
    "  sim calibration\n"
    "  sim occupancy --out FILE [--resolution M] [--format bt|mavocc]\n"
    "  health [--port P] [--service NAME]\n"
    "  listen [--topic stereo|imu|ground_truth|all] [--frames N] [--timeout S]\n"
    "         [--wake listener|waitset] [--keep-last N] [--dds-shm]\n"
    "  loc configure --method sparse-pixel|sparse-subpixel|dense [--euroc DIR | --simulator ADDR]\n"
    "  loc reset | loc status | loc trajectory --out FILE.tum   (port 50052)\n"
    "  map start|reset|insert|build|occupancy|query|mesh|status  (mavctl map --help; port 50053)\n"
    "  sim flight load|run|pause|status  (mavctl sim flight --help; the flight mode)\n"
    "  ctl configure|arm|disarm|hover|trajectory|gains|state|status  (mavctl ctl --help; 50055)\n"
    "  plan load|roadmap|path|legs|get|sample|status  (mavctl plan --help; port 50054)\n"
    "  mission run --mission FILE [--seed S] [--pose-source vo|contest|truth] [--out DIR]\n"
    "              [--json FILE]   (a mission through all the services; mavctl mission run "
    "--help)\n"
    "Common flags of sim/health: --address A (127.0.0.1), --port P (50051, env\n"
    "MAV_SIMULATOR_PORT), --timeout S (RPC deadline, 10 s).\n";

// The shared connection flags (connection.h) with this service's default port.
struct Connection : mav::mavctl::Connection {
  Connection() : mav::mavctl::Connection(kSimulatorPort, kSimulatorPortEnv) {}
};
using mav::mavctl::AddConnectionFlags;
using mav::mavctl::ParseOrExit;
using mav::mavctl::ReportRpcError;
using mav::mavctl::SetDeadline;

std::shared_ptr<grpc::Channel> Connect(const Connection& connection) {
  return mav::mavctl::MakeChannel(connection);
}

const char* StateName(mav::v1::SimulatorState state) {
  switch (state) {
    case mav::v1::SIMULATOR_STATE_IDLE:
      return "IDLE";
    case mav::v1::SIMULATOR_STATE_LOADED:
      return "LOADED";
    case mav::v1::SIMULATOR_STATE_RUNNING:
      return "RUNNING";
    case mav::v1::SIMULATOR_STATE_PAUSED:
      return "PAUSED";
    case mav::v1::SIMULATOR_STATE_FINISHED:
      return "FINISHED";
    default:
      return "UNSPECIFIED";
  }
}

void PrintSummary(const mav::v1::ScenarioSummary& s) {
  std::cout << "scenario:   " << s.name() << (s.is_preset() ? " (preset, seed " : " (EuRoC")
            << (s.is_preset() ? std::to_string(s.seed()) + ")" : ")") << "\n"
            << "frames:     " << s.frames() << " (" << s.image_width() << "x" << s.image_height()
            << (s.rectified() ? ", rectified" : ", raw") << ", " << s.camera_rate_hz() << " Hz)\n"
            << "imu:        " << s.imu_samples() << " samples at " << s.imu_rate_hz() << " Hz\n"
            << "time:       " << s.start_t_ns() << " .. " << s.end_t_ns() << " ns (" << std::fixed
            << std::setprecision(2) << mav::NsToSeconds(s.end_t_ns() - s.start_t_ns()) << " s)\n"
            << "ground truth: " << (s.has_ground_truth() ? "yes" : "no") << ", occupancy "
            << (s.has_ground_truth_occupancy() ? "yes" : "no") << "\n";
  std::cout.unsetf(std::ios::fixed);
}

void PrintStatus(const mav::v1::SimulatorStatus& s) {
  std::cout << "state:      " << StateName(s.state()) << "\n";
  if (s.has_scenario()) PrintSummary(s.scenario());
  std::cout << std::fixed << std::setprecision(2);
  std::cout << "next frame: " << s.next_frame() << ", published: " << s.frames_published()
            << " frames, " << s.imu_samples_published() << " imu, " << s.ground_truth_published()
            << " ground truth\n"
            << "pacing:     "
            << (s.as_fast_as_subscribers()
                    ? std::string("as fast as subscribers")
                    : "real-time factor " + std::to_string(s.real_time_factor()))
            << (s.loop() ? ", loop" : "") << "; achieved " << s.achieved_rate_hz() << " Hz\n"
            << "dds:        domain " << s.dds_domain() << ", stereo subscribers "
            << s.stereo_subscribers() << ", imu subscribers " << s.imu_subscribers()
            << (s.dds_shared_memory() ? ", stereo in shared memory" : "") << "\n"
            << "render:     mean " << s.render_ms().mean_ms() << " ms, p95 "
            << s.render_ms().p95_ms() << " ms (" << s.render_ms().count() << ")\n"
            << "publish:    mean " << s.publish_ms().mean_ms() << " ms, p95 "
            << s.publish_ms().p95_ms() << " ms\n";
  if (!s.last_error().empty()) std::cout << "last error: " << s.last_error() << "\n";
  std::cout.unsetf(std::ios::fixed);
}

// One simulator RPC answered with its status (Start, Pause, Step, GetStatus), which is printed.
// Returns the exit code.
int CallForStatus(const Connection& connection, const std::string& rpc,
                  const std::function<grpc::Status(mav::v1::Simulator::Stub*, grpc::ClientContext*,
                                                   mav::v1::SimulatorStatus*)>& call) {
  auto stub = mav::v1::Simulator::NewStub(Connect(connection));
  mav::v1::SimulatorStatus response;
  if (int rc = CallUnary(connection, rpc,
                         [&](grpc::ClientContext* c) { return call(stub.get(), c, &response); })) {
    return rc;
  }
  PrintStatus(response);
  return 0;
}

// The `sim` subcommands below get the parser with the connection flags already added, add their
// own flags, and return the exit code.

int SimLoad(FlagParser* flags, Connection* connection, const std::vector<std::string>& args) {
  std::string preset, euroc;
  int64_t frames = 0, seed = 1;
  bool rectified = false;
  flags->AddString("preset", &preset, "preset name (room-easy|room-medium|room-hard|plant)");
  flags->AddInt("frames", &frames, "stereo frames (0 = full preset)");
  flags->AddInt("seed", &seed, "renderer/IMU seed");
  flags->AddBool("rectified", &rectified, "ideal rectified pair instead of EuRoC's raw rig");
  flags->AddString("euroc", &euroc, "EuRoC ASL directory on the server");
  ParseOrExit(flags, connection, args);
  if (preset.empty() == euroc.empty()) {
    std::cerr << "mavctl: sim load needs exactly one of --preset NAME or --euroc DIR\n";
    return 2;
  }
  mav::v1::LoadScenarioRequest request;
  if (!preset.empty()) {
    request.mutable_preset()->set_name(preset);
    request.mutable_preset()->set_frames(frames);
    request.mutable_preset()->set_seed(static_cast<uint64_t>(seed));
    request.mutable_preset()->set_rectified(rectified);
  } else {
    request.mutable_euroc()->set_directory(euroc);
  }
  auto stub = mav::v1::Simulator::NewStub(Connect(*connection));
  mav::v1::LoadScenarioResponse response;
  if (int rc = CallUnary(*connection, "LoadScenario", [&](grpc::ClientContext* c) {
        return stub->LoadScenario(c, request, &response);
      })) {
    return rc;
  }
  std::cout << "loaded\n";
  PrintSummary(response.scenario());
  return 0;
}

int SimStart(FlagParser* flags, Connection* connection, const std::vector<std::string>& args) {
  double rate = 0.0, wait_timeout = 0.0;
  bool fast = false, loop = false;
  int64_t wait_subscribers = 0;
  flags->AddDouble("rate", &rate, "real-time factor (1.0 = 20 Hz frames)");
  flags->AddBool("fast", &fast, "as fast as the stereo subscribers acknowledge");
  flags->AddBool("loop", &loop, "restart from frame 0 after the last frame");
  flags->AddInt("wait-subscribers", &wait_subscribers,
                "wait for this many stereo subscribers before the first frame");
  flags->AddDouble("wait-timeout", &wait_timeout, "how long to wait for them, s (0 = 5 s)");
  ParseOrExit(flags, connection, args);
  if (flags->WasSet("rate") == fast) {
    std::cerr << "mavctl: sim start needs exactly one of --rate FACTOR or --fast\n";
    return 2;
  }
  if (wait_subscribers < 0) {
    std::cerr << "mavctl: --wait-subscribers: must be >= 0\n";
    return 2;
  }
  mav::v1::SimulatorStartRequest request;
  if (fast) {
    request.set_as_fast_as_subscribers(true);
  } else {
    request.set_real_time_factor(rate);  // the server validates (> 0, finite)
  }
  request.set_loop(loop);
  request.set_wait_for_subscribers(static_cast<uint32_t>(wait_subscribers));
  request.set_wait_timeout_s(wait_timeout);
  return CallForStatus(*connection, "Start", [&](auto* stub, auto* c, auto* response) {
    return stub->Start(c, request, response);
  });
}

int SimStep(FlagParser* flags, Connection* connection, const std::vector<std::string>& args) {
  const std::vector<std::string> positional = ParseOrExit(flags, connection, args, true);
  if (positional.size() != 1) {
    std::cerr << "mavctl: sim step needs one argument N (frames)\n";
    return 2;
  }
  auto n = mav::ParseInt64(positional[0], "step N");
  if (!n.ok() || *n < 1 || *n > UINT32_MAX) {
    std::cerr << "mavctl: step N: '" << positional[0] << "' is not a frame count >= 1\n";
    return 2;
  }
  mav::v1::SimulatorStepRequest request;
  request.set_frames(static_cast<uint32_t>(*n));
  return CallForStatus(*connection, "Step", [&](auto* stub, auto* c, auto* response) {
    return stub->Step(c, request, response);
  });
}

int SimCalibration(FlagParser* flags, Connection* connection,
                   const std::vector<std::string>& args) {
  ParseOrExit(flags, connection, args);
  auto stub = mav::v1::Simulator::NewStub(Connect(*connection));
  mav::v1::GetCalibrationResponse response;
  if (int rc = CallUnary(*connection, "GetCalibration", [&](grpc::ClientContext* c) {
        return stub->GetCalibration(c, mav::v1::GetCalibrationRequest(), &response);
      })) {
    return rc;
  }
  std::cout << response.DebugString();
  return 0;
}

int SimOccupancy(FlagParser* flags, Connection* connection, const std::vector<std::string>& args) {
  std::string out, format = "bt";
  double resolution = 0.05;
  flags->AddString("out", &out, "output file");
  flags->AddDouble("resolution", &resolution, "voxel edge, m");
  flags->AddString("format", &format, "bt (OctoMap) or mavocc");
  ParseOrExit(flags, connection, args);
  if (out.empty()) {
    std::cerr << "mavctl: sim occupancy needs --out FILE\n";
    return 2;
  }
  if (format != "bt" && format != "mavocc") {
    std::cerr << "mavctl: --format: '" << format << "' is not bt|mavocc\n";
    return 2;
  }
  mav::v1::GetGroundTruthOccupancyRequest request;
  request.set_resolution_m(resolution);
  request.set_format(format == "bt" ? mav::v1::OCCUPANCY_FORMAT_OCTOMAP_BT
                                    : mav::v1::OCCUPANCY_FORMAT_MAVOCC);
  auto stub = mav::v1::Simulator::NewStub(Connect(*connection));
  std::string bytes;
  if (int rc = DownloadChunks<mav::v1::OccupancyChunk>(
          *connection, "GetGroundTruthOccupancy",
          [&](grpc::ClientContext* c) { return stub->GetGroundTruthOccupancy(c, request); },
          [](const mav::v1::OccupancyChunk& m) -> const mav::v1::FileChunk& { return m.chunk(); },
          &bytes)) {
    return rc;
  }
  if (mav::Status s = mav::WriteStringToFileAtomic(out, bytes); !s.ok()) {
    std::cerr << "mavctl: " << s.message() << "\n";
    return 1;
  }
  std::cout << "wrote " << out << " (" << bytes.size() << " bytes)\n";
  return 0;
}

int SimCommand(const std::vector<std::string>& args) {
  if (args.empty()) {
    std::cerr << "mavctl: sim needs a subcommand: load|start|pause|step|status|calibration|"
                 "occupancy|flight\n";
    return 2;
  }
  const std::string& sub = args[0];
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  if (sub == "flight") return mav::mavctl::FlightCommand(rest);
  Connection connection;
  FlagParser flags("mavctl sim " + sub, "");
  AddConnectionFlags(&flags, &connection);

  if (sub == "load") return SimLoad(&flags, &connection, rest);
  if (sub == "start") return SimStart(&flags, &connection, rest);
  if (sub == "pause") {
    ParseOrExit(&flags, &connection, rest);
    return CallForStatus(connection, "Pause", [](auto* stub, auto* c, auto* response) {
      return stub->Pause(c, mav::v1::SimulatorPauseRequest(), response);
    });
  }
  if (sub == "status") {
    ParseOrExit(&flags, &connection, rest);
    return CallForStatus(connection, "GetStatus", [](auto* stub, auto* c, auto* response) {
      return stub->GetStatus(c, mav::v1::SimulatorGetStatusRequest(), response);
    });
  }
  if (sub == "step") return SimStep(&flags, &connection, rest);
  if (sub == "calibration") return SimCalibration(&flags, &connection, rest);
  if (sub == "occupancy") return SimOccupancy(&flags, &connection, rest);
  std::cerr << "mavctl: unknown sim subcommand '" << sub << "'\n" << kUsage;
  return 2;
}

int HealthCommand(const std::vector<std::string>& args) {
  Connection connection;
  std::string service;
  FlagParser flags("mavctl health", "grpc.health.v1 Check of a service");
  AddConnectionFlags(&flags, &connection);
  flags.AddString("service", &service, "service name (\"\" = the whole server)");
  ParseOrExit(&flags, &connection, args);
  auto result = mav::transport::CheckHealth(
      Connect(connection), service,
      std::chrono::milliseconds(static_cast<int64_t>(connection.timeout_s * 1000)));
  if (!result.ok()) {
    std::cerr << "mavctl: cannot check health of " << connection.Target() << ": "
              << result.status().message() << "\n";
    return 1;
  }
  std::cout << connection.Target() << (service.empty() ? "" : " " + service) << ": "
            << mav::transport::HealthStatusName(*result) << "\n";
  return *result == mav::transport::HealthStatus::kServing ? 0 : 1;
}

int ListenCommand(const std::vector<std::string>& args) {
  mav::mavctl::ListenOptions options;
  bool quiet = false;
  FlagParser flags("mavctl listen",
                   "Subscribes to the simulator's DDS streams, verifies every stereo frame's\n"
                   "checksum and sequence number, and prints what arrived. Exit 0 when the\n"
                   "target was reached with no missing or corrupt frame.");
  flags.AddString("topic", &options.topic, "stereo|imu|ground_truth|all");
  flags.AddInt("frames", &options.frames,
               "stop after N stereo frames (samples for imu/ground_truth); 0 = until --timeout");
  flags.AddDouble("timeout", &options.timeout_s, "give up after S seconds");
  flags.AddBool("quiet", &quiet, "no progress lines");
  flags.AddString("wake", &options.wake,
                  "listener: take stereo frames on DDS's receive thread (lowest latency); "
                  "waitset: on this thread, woken by a waitset");
  flags.AddInt("keep-last", &options.keep_last,
               "stereo reader's history: 0 = keep all (a slow reader throttles the writer), "
               "1..256 = the last N (older untaken frames are lost and counted missing); "
               "default: keep all, or 16 with --dds-shm (shared memory carries only keep-last "
               "readers)",
               0, 256);
  mav::transport::AddDdsFlags(&flags, &options.dds);
  ParseOrExit(&flags, nullptr, args);
  if (const mav::Status s = mav::transport::ApplyDdsEnv(flags, &options.dds); !s.ok()) {
    std::cerr << "mavctl: " << s.message() << "\n";
    return 2;
  }
  options.progress = !quiet;
  std::string why;
  if (!options.IsValid(&why)) {
    std::cerr << "mavctl: " << why << "\n";
    return 2;
  }
  mav::transport::KeepLargeSampleBuffers();  // a take allocates each 722 KB frame anew
  auto report = mav::mavctl::Listen(options, std::cerr);
  if (!report.ok()) {
    std::cerr << "mavctl: listen: " << report.status().ToString() << "\n";
    return 1;
  }
  mav::mavctl::PrintReport(options, *report, std::cout);
  return mav::mavctl::ReportPassed(options, *report) ? 0 : 1;
}

int Run(int argc, char** argv) {
  if (argc < 2 || std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h") {
    std::cout << kUsage;
    return argc < 2 ? 2 : 0;
  }
  const std::string command = argv[1];
  const std::vector<std::string> args(argv + 2, argv + argc);
  if (command == "sim") return SimCommand(args);
  if (command == "health") return HealthCommand(args);
  if (command == "listen") return ListenCommand(args);
  if (command == "loc") return mav::mavctl::LocalizationCommand(args);
  if (command == "map") return mav::mavctl::MappingCommand(args);
  if (command == "ctl") return mav::mavctl::ControlCommand(args);
  if (command == "plan") return mav::mavctl::PlanCommand(args);
  if (command == "mission") return mav::mavctl::MissionCommand(args);
  std::cerr << "mavctl: unknown command '" << command << "'\n" << kUsage;
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  // Our code reports errors as values; what is left is std::bad_alloc and the like from the
  // standard library and gRPC: say so and exit non-zero instead of aborting.
  try {
    return Run(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "mavctl: " << e.what() << "\n";
    return 1;
  }
}
