#include "clients/mavctl/localization_commands.h"
#include "clients/mavctl/connection.h"

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <iomanip>
#include <iostream>
#include <memory>

#include "mav/v1/localization.grpc.pb.h"

#include "mav/common/time.h"
#include "mav/dataset/trajectory_io.h"
#include "mav/dataset/types.h"
#include "mav/localization/odometry.h"
#include "mav/transport/flags.h"
#include "mav/transport/grpc_server.h"

namespace mav::mavctl {

namespace {

using transport::FlagParser;

constexpr int64_t kLocalizationPort = 50052;
constexpr char kLocalizationPortEnv[] = "MAV_LOCALIZATION_PORT";

constexpr char kLocUsage[] =
    "Usage: mavctl loc <subcommand> [flags]   (mavctl loc <subcommand> --help for its flags)\n"
    "  loc configure --method sparse-pixel|sparse-subpixel|dense "
    "(--euroc DIR | --simulator HOST:PORT)\n"
    "                [--queue N] [--output-frame body|cam0] [--no-dds]\n"
    "  loc reset [--x X --y Y --z Z]\n"
    "  loc status\n"
    "  loc trajectory --out FILE.tum [--start-t-ns T] [--end-t-ns T]\n"
    "Common flags: --address A (127.0.0.1), --port P (50052, env MAV_LOCALIZATION_PORT),\n"
    "--timeout S (RPC deadline, 10 s).\n";

// The shared connection flags (connection.h) with this service's default port.
struct Connection : mavctl::Connection {
  Connection() : mavctl::Connection(kLocalizationPort, kLocalizationPortEnv) {}
};

std::unique_ptr<v1::Localization::Stub> Connect(const Connection& connection) {
  return v1::Localization::NewStub(MakeChannel(connection));
}

const char* MethodText(v1::LocalizationMethod method) {
  switch (method) {
    case v1::LOCALIZATION_METHOD_SPARSE_PIXEL:
      return "sparse-pixel";
    case v1::LOCALIZATION_METHOD_SPARSE_SUBPIXEL:
      return "sparse-subpixel";
    case v1::LOCALIZATION_METHOD_DENSE:
      return "dense";
    default:
      return "-";
  }
}

const char* StateText(v1::LocalizationServiceState state) {
  switch (state) {
    case v1::LOCALIZATION_SERVICE_STATE_UNCONFIGURED:
      return "UNCONFIGURED";
    case v1::LOCALIZATION_SERVICE_STATE_READY:
      return "READY";
    case v1::LOCALIZATION_SERVICE_STATE_RUNNING:
      return "RUNNING";
    default:
      return "UNSPECIFIED";
  }
}

const char* TrackingText(v1::TrackingState state) {
  switch (state) {
    case v1::TRACKING_STATE_INITIALIZING:
      return "INITIALIZING";
    case v1::TRACKING_STATE_OK:
      return "OK";
    case v1::TRACKING_STATE_LOST:
      return "LOST";
    default:
      return "-";
  }
}

void PrintStatus(const v1::LocalizationStatus& s) {
  std::cout << std::fixed << std::setprecision(3);
  std::cout << "state:      " << StateText(s.state()) << ", method " << MethodText(s.method())
            << ", DDS input " << (s.dds_input() ? "on" : "off") << "\n"
            << "frames:     " << s.frames_processed() << " processed, " << s.frames_dropped()
            << " dropped, " << s.frames_lost() << " lost, " << s.frames_rejected()
            << " rejected; queue " << s.queue_depth() << "/" << s.config().queue_length() << "; "
            << std::setprecision(1) << s.fps() << " fps\n"
            << "processing: mean " << s.processing_ms().mean_ms() << " ms, median "
            << s.processing_ms().median_ms() << " ms, p95 " << s.processing_ms().p95_ms()
            << " ms, max " << s.processing_ms().max_ms() << " ms (" << s.processing_ms().count()
            << " frames)\n";
  if (s.method() == v1::LOCALIZATION_METHOD_DENSE) {
    std::cout << "keyframes:  " << s.keyframes() << "\n";
  }
  if (s.has_last_pose()) {
    const v1::Pose& p = s.last_pose().pose();
    std::cout << std::setprecision(3) << "last pose:  t " << s.last_pose().t_ns() << " ns, T_world_"
              << s.config().output_frame() << " p (" << p.position().x() << ", " << p.position().y()
              << ", " << p.position().z() << ") m, q wxyz (" << p.orientation().w() << ", "
              << p.orientation().x() << ", " << p.orientation().y() << ", " << p.orientation().z()
              << "), tracking " << TrackingText(s.tracking_state());
    if (s.last_pose().covariance_size() == 36) {
      std::cout << ", sigma_x " << std::sqrt(s.last_pose().covariance(0)) << " m (heuristic)";
    }
    std::cout << "\n";
    if (!s.lost_reason().empty()) std::cout << "lost:       " << s.lost_reason() << "\n";
  }
  std::cout.unsetf(std::ios::fixed);
}

int Configure(const std::vector<std::string>& args) {
  Connection connection;
  FlagParser flags("mavctl loc configure",
                   "Configures the localization service (method, calibration source).");
  AddConnectionFlags(&flags, &connection);
  std::string method, euroc, simulator, output_frame;
  int64_t queue = 0, ransac_iterations = 0;
  double inlier_threshold = 0.0;
  bool no_dds = false;
  flags.AddString("method", &method, "sparse-pixel|sparse-subpixel|dense");
  flags.AddString("euroc", &euroc, "calibration: an EuRoC directory on the server");
  flags.AddString("simulator", &simulator, "calibration: a simulator's host:port");
  flags.AddInt("queue", &queue, "input queue length in frames (0 = 2, <= 100)");
  flags.AddString("output-frame", &output_frame, "pose of body (default) or cam0");
  flags.AddBool("no-dds", &no_dds, "do not subscribe to mav/sensors/stereo");
  flags.AddInt("ransac-iterations", &ransac_iterations, "sparse: RANSAC iterations (0 = default)");
  flags.AddDouble("inlier-threshold", &inlier_threshold,
                  "sparse: inlier threshold, px (0 = default)");
  ParseOrExit(&flags, &connection, args);
  const auto parsed = localization::ParseMethod(method);
  if (!parsed.has_value()) {
    std::cerr << "mavctl: --method: '" << method
              << "' is not sparse-pixel, sparse-subpixel or dense\n";
    return 2;
  }
  if (euroc.empty() == simulator.empty()) {
    std::cerr << "mavctl: loc configure needs exactly one of --euroc DIR or --simulator ADDR\n";
    return 2;
  }
  if (queue < 0 || ransac_iterations < 0) {
    std::cerr << "mavctl: --queue/--ransac-iterations: must be >= 0\n";
    return 2;
  }
  v1::LocalizationConfigureRequest request;
  switch (*parsed) {
    case localization::Method::kSparsePixel:
      request.set_method(v1::LOCALIZATION_METHOD_SPARSE_PIXEL);
      break;
    case localization::Method::kSparseSubpixel:
      request.set_method(v1::LOCALIZATION_METHOD_SPARSE_SUBPIXEL);
      break;
    case localization::Method::kDense:
      request.set_method(v1::LOCALIZATION_METHOD_DENSE);
      break;
  }
  if (!euroc.empty()) {
    request.mutable_calibration()->set_euroc_directory(euroc);
  } else {
    request.mutable_calibration()->set_simulator_address(simulator);
  }
  // The server validates the ranges and names the field.
  request.set_queue_length(static_cast<uint32_t>(std::min<int64_t>(queue, UINT32_MAX)));
  request.set_output_frame(output_frame);
  request.set_disable_dds_input(no_dds);
  request.mutable_sparse()->set_ransac_iterations(
      static_cast<uint32_t>(std::min<int64_t>(ransac_iterations, UINT32_MAX)));
  request.mutable_sparse()->set_inlier_threshold_px(inlier_threshold);
  auto stub = Connect(connection);
  v1::LocalizationStatus response;
  if (int rc = CallUnary(connection, "Configure", [&](grpc::ClientContext* c) {
        return stub->Configure(c, request, &response);
      })) {
    return rc;
  }
  std::cout << "configured\n";
  PrintStatus(response);
  return 0;
}

int Reset(const std::vector<std::string>& args) {
  Connection connection;
  FlagParser flags("mavctl loc reset",
                   "Starts a new trajectory (at the given position, else the configured pose).");
  AddConnectionFlags(&flags, &connection);
  double x = 0, y = 0, z = 0;
  flags.AddDouble("x", &x, "initial body position x, m (world)");
  flags.AddDouble("y", &y, "initial body position y, m");
  flags.AddDouble("z", &z, "initial body position z, m");
  ParseOrExit(&flags, &connection, args);
  v1::LocalizationResetRequest request;
  if (flags.WasSet("x") || flags.WasSet("y") || flags.WasSet("z")) {
    request.mutable_initial_pose()->mutable_position()->set_x(x);
    request.mutable_initial_pose()->mutable_position()->set_y(y);
    request.mutable_initial_pose()->mutable_position()->set_z(z);
    request.mutable_initial_pose()->mutable_orientation()->set_w(1.0);
  }
  auto stub = Connect(connection);
  v1::LocalizationStatus response;
  if (int rc = CallUnary(connection, "Reset", [&](grpc::ClientContext* c) {
        return stub->Reset(c, request, &response);
      })) {
    return rc;
  }
  std::cout << "reset\n";
  PrintStatus(response);
  return 0;
}

int GetStatus(const std::vector<std::string>& args) {
  Connection connection;
  FlagParser flags("mavctl loc status", "Prints the localization service's status.");
  AddConnectionFlags(&flags, &connection);
  ParseOrExit(&flags, &connection, args);
  auto stub = Connect(connection);
  v1::LocalizationStatus response;
  if (int rc = CallUnary(connection, "GetStatus", [&](grpc::ClientContext* c) {
        return stub->GetStatus(c, v1::LocalizationGetStatusRequest(), &response);
      })) {
    return rc;
  }
  PrintStatus(response);
  return 0;
}

int Trajectory(const std::vector<std::string>& args) {
  Connection connection;
  FlagParser flags("mavctl loc trajectory",
                   "Downloads the estimated trajectory and writes it as a TUM file\n"
                   "(t[s] x y z qx qy qz qw per line; evo_traj tum FILE reads it).");
  AddConnectionFlags(&flags, &connection);
  std::string out;
  int64_t start_t_ns = 0, end_t_ns = 0;
  flags.AddString("out", &out, "output TUM file");
  flags.AddInt("start-t-ns", &start_t_ns, "first time, ns (0 = from the beginning)");
  flags.AddInt("end-t-ns", &end_t_ns, "last time, ns (0 = to the end)");
  connection.timeout_s = 30.0;
  ParseOrExit(&flags, &connection, args);
  if (out.empty()) {
    std::cerr << "mavctl: loc trajectory needs --out FILE.tum\n";
    return 2;
  }
  v1::GetTrajectoryRequest request;
  request.set_start_t_ns(start_t_ns);
  request.set_end_t_ns(end_t_ns);
  auto stub = Connect(connection);
  grpc::ClientContext context;
  SetDeadline(connection, &context);
  auto reader = stub->GetTrajectory(&context, request);
  std::vector<dataset::StampedPose> poses;
  int lost = 0;
  v1::TrajectoryChunk chunk;
  while (reader->Read(&chunk)) {
    for (const v1::TrajectoryPoint& point : chunk.points()) {
      const v1::Pose& p = point.pose().pose();
      dataset::StampedPose pose;
      pose.t_ns = point.pose().t_ns();
      pose.T_world_body =
          geometry::SE3(Eigen::Quaterniond(p.orientation().w(), p.orientation().x(),
                                           p.orientation().y(), p.orientation().z()),
                        Eigen::Vector3d(p.position().x(), p.position().y(), p.position().z()));
      poses.push_back(pose);
      if (point.tracking_state() == v1::TRACKING_STATE_LOST) ++lost;
    }
  }
  const grpc::Status status = reader->Finish();
  if (!status.ok()) return ReportRpcError(connection, "GetTrajectory", status);
  const Status written = dataset::WriteTumTrajectory(out, poses);
  if (!written.ok()) {
    std::cerr << "mavctl: " << written.ToString() << "\n";
    return 1;
  }
  std::cout << "wrote " << out << " (" << poses.size() << " poses, " << lost << " lost)\n";
  return 0;
}

}  // namespace

int LocalizationCommand(const std::vector<std::string>& args) {
  if (args.empty() || args[0] == "--help" || args[0] == "-h") {
    std::cout << kLocUsage;
    return args.empty() ? 2 : 0;
  }
  const std::string& sub = args[0];
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  if (sub == "configure") return Configure(rest);
  if (sub == "reset") return Reset(rest);
  if (sub == "status") return GetStatus(rest);
  if (sub == "trajectory") return Trajectory(rest);
  std::cerr << "mavctl: unknown loc subcommand '" << sub << "'\n" << kLocUsage;
  return 2;
}

}  // namespace mav::mavctl
