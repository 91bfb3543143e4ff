#include "clients/mavctl/mapping_commands.h"
#include "clients/mavctl/connection.h"

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>

#include <opencv2/core/mat.hpp>

#include "mav/v1/mapping.grpc.pb.h"

#include "mav/common/file.h"
#include "mav/common/parse.h"
#include "mav/common/text.h"
#include "mav/common/time.h"
#include "mav/dataset/png.h"
#include "mav/transport/flags.h"
#include "mav/transport/grpc_server.h"

namespace mav::mavctl {

namespace {

using transport::FlagParser;

constexpr int64_t kMappingPort = 50053;
constexpr char kMappingPortEnv[] = "MAV_MAPPING_PORT";

constexpr char kMapUsage[] =
    "Usage: mavctl map <subcommand> [flags]   (mavctl map <subcommand> --help for its flags)\n"
    "  map start (--simulator HOST:PORT | --euroc DIR) [--pose-source ground-truth|localization|"
    "none]\n"
    "            [--min-translation M] [--min-rotation DEG] [--max-keyframes N] [--features N]"
    " [--no-dds]\n"
    "  map reset\n"
    "  map insert --left L.png --right R.png --t-ns T --pose x,y,z,qw,qx,qy,qz [--rectified]"
    " [--force]\n"
    "  map build --method sparse-mesh|octomap [--resolution M] [--bounds x0,y0,z0,x1,y1,z1]\n"
    "            [--unknown keep|occupied|free]\n"
    "  map occupancy --out FILE.bt [--method sparse-mesh|octomap] [--format bt|mavocc]\n"
    "  map query --box x0,y0,z0,x1,y1,z1 [--method sparse-mesh|octomap] "
    "[--unknown-is-collision]\n"
    "  map mesh --out FILE.ply [--ascii]\n"
    "  map status\n"
    "Common flags: --address A (127.0.0.1), --port P (50053, env MAV_MAPPING_PORT),\n"
    "--timeout S (RPC deadline, 10 s; map build 120 s).\n";

// The shared connection flags (connection.h) with this service's default port.
struct Connection : mavctl::Connection {
  Connection() : mavctl::Connection(kMappingPort, kMappingPortEnv) {}
};

int Usage(const std::string& message) {
  std::cerr << "mavctl: " << message << "\n";
  return 2;
}

std::unique_ptr<v1::Mapping::Stub> Connect(const Connection& connection) {
  return v1::Mapping::NewStub(MakeChannel(connection));
}

// Box from "x0,y0,z0,x1,y1,z1" (the server validates min <= max).
Result<v1::Box> ParseBox(const std::string& text, const std::string& flag) {
  MAV_ASSIGN_OR_RETURN(std::vector<double> v, ParseNumbers(text, 6, flag));
  v1::Box box;
  box.mutable_min()->set_x(v[0]);
  box.mutable_min()->set_y(v[1]);
  box.mutable_min()->set_z(v[2]);
  box.mutable_max()->set_x(v[3]);
  box.mutable_max()->set_y(v[4]);
  box.mutable_max()->set_z(v[5]);
  return box;
}

Result<v1::MappingMethod> ParseMethod(const std::string& text, bool allow_empty) {
  if (text == "sparse-mesh") return v1::MAPPING_METHOD_SPARSE_MESH;
  if (text == "octomap") return v1::MAPPING_METHOD_OCTOMAP;
  if (text.empty() && allow_empty) return v1::MAPPING_METHOD_UNSPECIFIED;
  return Status::InvalidArgument("--method: " + QuoteForError(text) +
                                 " is not sparse-mesh or octomap");
}

const char* MethodText(v1::MappingMethod method) {
  switch (method) {
    case v1::MAPPING_METHOD_SPARSE_MESH:
      return "sparse-mesh";
    case v1::MAPPING_METHOD_OCTOMAP:
      return "octomap";
    default:
      return "-";
  }
}

const char* PoseSourceText(v1::PoseSource source) {
  switch (source) {
    case v1::POSE_SOURCE_LOCALIZATION:
      return "localization";
    case v1::POSE_SOURCE_GROUND_TRUTH:
      return "ground-truth";
    default:
      return "none";
  }
}

void PrintBuild(const v1::BuildMapResponse& r) {
  const v1::OccupancyStats& o = r.occupancy();
  const v1::MappingTiming& t = r.timing();
  std::cout << std::fixed << std::setprecision(2);
  std::cout << MethodText(r.method()) << ": " << r.keyframes() << " keyframes, " << r.points()
            << " points";
  if (r.method() == v1::MAPPING_METHOD_SPARSE_MESH) {
    std::cout << ", " << r.tetrahedra() << " tetrahedra, mesh " << r.mesh_vertices()
              << " vertices / " << r.mesh_faces() << " faces";
  }
  std::cout << "\ngrid " << o.resolution_m() << " m, (" << o.bounds().min().x() << ", "
            << o.bounds().min().y() << ", " << o.bounds().min().z() << ") .. ("
            << o.bounds().max().x() << ", " << o.bounds().max().y() << ", " << o.bounds().max().z()
            << ") m: " << o.occupied_voxels() << " occupied, " << o.free_voxels() << " free, "
            << o.unknown_voxels() << " unknown voxels\n";
  std::cout << std::setprecision(1) << "time: total " << t.total_ms() << " ms (features "
            << t.features_ms() << ", dense stereo " << t.dense_stereo_ms() << ", delaunay "
            << t.delaunay_ms() << ", graph cut " << t.graph_cut_ms() << ", surface "
            << t.surface_ms() << ", insertion " << t.insertion_ms() << ", rasterize "
            << t.rasterize_ms() << ")\n";
  std::cout.unsetf(std::ios::fixed);
}

void PrintStatus(const v1::MappingStatus& s) {
  std::cout << std::fixed << std::setprecision(1);
  std::cout << "session:   " << (s.session_active() ? "active" : "none") << ", poses from "
            << PoseSourceText(s.pose_source()) << "\n"
            << "frames:    " << s.frames_seen() << " seen, " << s.frames_without_pose()
            << " without pose\n"
            << "keyframes: " << s.keyframes() << ", " << s.points() << " sparse points; "
            << "processing mean " << s.keyframe_ms().mean_ms() << " ms, p95 "
            << s.keyframe_ms().p95_ms() << " ms\n"
            << "worker:    " << (s.worker_busy() ? "busy" : "idle") << ", " << s.queue_depth()
            << " waiting\n";
  if (s.building()) {
    std::cout << "building:  " << s.build_progress().stage() << " ("
              << 100.0 * s.build_progress().fraction() << " %, " << s.build_progress().elapsed_s()
              << " s)\n";
  }
  std::cout.unsetf(std::ios::fixed);
  for (const v1::BuildMapResponse& map : s.maps()) {
    std::cout << "map ";
    PrintBuild(map);
  }
}

int Start(const std::vector<std::string>& args) {
  Connection connection;
  FlagParser flags("mavctl map start", "Starts a fresh mapping session.");
  AddConnectionFlags(&flags, &connection);
  std::string euroc, simulator, pose_source = "ground-truth";
  double min_translation = 0, min_rotation = 0;
  int64_t max_keyframes = 0, features = 0;
  bool no_dds = false;
  flags.AddString("simulator", &simulator, "calibration: a simulator's host:port");
  flags.AddString("euroc", &euroc, "calibration: an EuRoC directory on the server");
  flags.AddString("pose-source", &pose_source, "ground-truth|localization|none");
  flags.AddDouble("min-translation", &min_translation, "keyframe rule, m (0 = 0.25)");
  flags.AddDouble("min-rotation", &min_rotation, "keyframe rule, deg (0 = 10)");
  flags.AddInt("max-keyframes", &max_keyframes, "keyframe limit (0 = 5000)");
  flags.AddInt("features", &features, "sparse points per keyframe (0 = 100)");
  flags.AddBool("no-dds", &no_dds, "do not subscribe to DDS (InsertKeyframe only)");
  ParseOrExit(&flags, &connection, args);
  if (euroc.empty() == simulator.empty()) {
    return Usage("map start needs exactly one of --simulator HOST:PORT or --euroc DIR");
  }
  v1::StartSessionRequest request;
  if (!euroc.empty()) {
    request.mutable_calibration()->set_euroc_directory(euroc);
  } else {
    request.mutable_calibration()->set_simulator_address(simulator);
  }
  if (pose_source == "ground-truth") {
    request.set_pose_source(v1::POSE_SOURCE_GROUND_TRUTH);
  } else if (pose_source == "localization") {
    request.set_pose_source(v1::POSE_SOURCE_LOCALIZATION);
  } else if (pose_source == "none") {
    request.set_pose_source(v1::POSE_SOURCE_NONE);
  } else {
    return Usage("--pose-source: " + QuoteForError(pose_source) +
                 " is not ground-truth, localization or none");
  }
  if (max_keyframes < 0 || features < 0) {
    return Usage("--max-keyframes/--features: must be >= 0");
  }
  request.mutable_keyframes()->set_min_translation_m(min_translation);
  request.mutable_keyframes()->set_min_rotation_deg(min_rotation);
  request.mutable_keyframes()->set_max_keyframes(static_cast<uint32_t>(max_keyframes));
  request.mutable_keyframes()->set_features_per_keyframe(static_cast<uint32_t>(features));
  request.set_disable_dds_input(no_dds);
  auto stub = Connect(connection);
  v1::MappingStatus status;
  if (int rc = CallUnary(connection, "StartSession", [&](grpc::ClientContext* c) {
        return stub->StartSession(c, request, &status);
      })) {
    return rc;
  }
  PrintStatus(status);
  return 0;
}

int Insert(const std::vector<std::string>& args) {
  Connection connection;
  FlagParser flags("mavctl map insert",
                   "Offers one stereo pair (PNG files, 8-bit grey) with its pose T_world_body.");
  AddConnectionFlags(&flags, &connection);
  std::string left_path, right_path, pose_text;
  int64_t t_ns = 0;
  bool rectified = false, force = false;
  flags.AddString("left", &left_path, "left image (cam0), PNG");
  flags.AddString("right", &right_path, "right image (cam1), PNG");
  flags.AddInt("t-ns", &t_ns, "time stamp, ns");
  flags.AddString("pose", &pose_text, "T_world_body as x,y,z,qw,qx,qy,qz");
  flags.AddBool("rectified", &rectified, "the images are already rectified");
  flags.AddBool("force", &force, "a keyframe regardless of the pose-change rule");
  ParseOrExit(&flags, &connection, args);
  if (left_path.empty() || right_path.empty() || pose_text.empty()) {
    return Usage("map insert needs --left, --right and --pose");
  }
  Result<std::vector<double>> pose = ParseNumbers(pose_text, 7, "--pose");
  if (!pose.ok()) return Usage(pose.status().message());
  v1::InsertKeyframeRequest request;
  request.mutable_stereo()->set_t_ns(t_ns);
  request.mutable_stereo()->set_rectified(rectified);
  for (const auto& [path, image] :
       {std::pair<std::string, v1::Image*>{left_path, request.mutable_stereo()->mutable_left()},
        std::pair<std::string, v1::Image*>{right_path,
                                           request.mutable_stereo()->mutable_right()}}) {
    const Result<cv::Mat> read = dataset::ReadPngFile(path, dataset::PngDecode::kToGrey);
    if (!read.ok()) {
      std::cerr << "mavctl: cannot read the image (must be a PNG): " << read.status().message()
                << "\n";
      return 1;
    }
    const cv::Mat& mat = *read;
    image->set_width(static_cast<uint32_t>(mat.cols));
    image->set_height(static_cast<uint32_t>(mat.rows));
    image->set_encoding(v1::IMAGE_ENCODING_MONO8);
    std::string* data = image->mutable_data();
    data->resize(mat.total());
    for (int r = 0; r < mat.rows; ++r) {
      std::copy(mat.ptr<char>(r), mat.ptr<char>(r) + mat.cols, data->begin() + r * mat.cols);
    }
  }
  const std::vector<double>& p = *pose;
  v1::Pose* t = request.mutable_t_world_body();
  t->mutable_position()->set_x(p[0]);
  t->mutable_position()->set_y(p[1]);
  t->mutable_position()->set_z(p[2]);
  t->mutable_orientation()->set_w(p[3]);
  t->mutable_orientation()->set_x(p[4]);
  t->mutable_orientation()->set_y(p[5]);
  t->mutable_orientation()->set_z(p[6]);
  request.set_force(force);
  auto stub = Connect(connection);
  v1::InsertKeyframeResponse response;
  if (int rc = CallUnary(connection, "InsertKeyframe", [&](grpc::ClientContext* c) {
        return stub->InsertKeyframe(c, request, &response);
      })) {
    return rc;
  }
  if (response.accepted()) {
    std::cout << "keyframe " << response.keyframe_index() << ": " << response.features()
              << " features, " << response.points_total() << " points in the map, "
              << response.processing_ms() << " ms\n";
  } else {
    std::cout << "not a keyframe (moved less than the keyframe rule; --force inserts it)\n";
  }
  return 0;
}

int Build(const std::vector<std::string>& args) {
  Connection connection;
  connection.timeout_s = 120.0;
  FlagParser flags("mavctl map build", "Builds the map from the session's keyframes.");
  AddConnectionFlags(&flags, &connection);
  std::string method, bounds, unknown = "keep", prefer = "safety";
  double resolution = 0;
  flags.AddString("method", &method, "sparse-mesh|octomap");
  flags.AddString("prefer", &prefer,
                  "sparse-mesh: safety (fewer missed collisions, the default) or mcc (the "
                  "paper's weights)");
  flags.AddDouble("resolution", &resolution, "voxel edge, m (0 = 0.05)");
  flags.AddString("bounds", &bounds, "grid extent x0,y0,z0,x1,y1,z1 (default: around the map)");
  flags.AddString("unknown", &unknown, "unobserved voxels: keep|occupied|free");
  ParseOrExit(&flags, &connection, args);
  Result<v1::MappingMethod> parsed = ParseMethod(method, false);
  if (!parsed.ok()) return Usage(parsed.status().message());
  v1::BuildMapRequest request;
  request.set_method(*parsed);
  request.set_resolution_m(resolution);
  if (!bounds.empty()) {
    Result<v1::Box> box = ParseBox(bounds, "--bounds");
    if (!box.ok()) return Usage(box.status().message());
    *request.mutable_bounds() = *box;
  }
  if (unknown == "keep") {
    request.set_unknown(v1::UNKNOWN_HANDLING_KEEP_UNKNOWN);
  } else if (unknown == "occupied") {
    request.set_unknown(v1::UNKNOWN_HANDLING_AS_OCCUPIED);
  } else if (unknown == "free") {
    request.set_unknown(v1::UNKNOWN_HANDLING_AS_FREE);
  } else {
    return Usage("--unknown: " + QuoteForError(unknown) + " is not keep, occupied or free");
  }
  if (prefer == "safety") {
    request.set_prefer(v1::MAP_PREFERENCE_SAFETY);
  } else if (prefer == "mcc") {
    request.set_prefer(v1::MAP_PREFERENCE_MCC);
  } else {
    return Usage("--prefer: " + QuoteForError(prefer) + " is not safety or mcc");
  }
  auto stub = Connect(connection);
  v1::BuildMapResponse response;
  if (int rc = CallUnary(connection, "BuildMap", [&](grpc::ClientContext* c) {
        return stub->BuildMap(c, request, &response);
      })) {
    return rc;
  }
  PrintBuild(response);
  return 0;
}

int Occupancy(const std::vector<std::string>& args) {
  Connection connection;
  connection.timeout_s = 30.0;
  FlagParser flags("mavctl map occupancy", "Downloads the occupancy map of the last build.");
  AddConnectionFlags(&flags, &connection);
  std::string out_path, method, format = "bt";
  flags.AddString("out", &out_path, "output file (.bt or .mavocc)");
  flags.AddString("method", &method, "sparse-mesh|octomap (default: the most recent build)");
  flags.AddString("format", &format, "bt|mavocc");
  ParseOrExit(&flags, &connection, args);
  if (out_path.empty()) return Usage("map occupancy needs --out FILE");
  Result<v1::MappingMethod> parsed = ParseMethod(method, true);
  if (!parsed.ok()) return Usage(parsed.status().message());
  if (format != "bt" && format != "mavocc") {
    return Usage("--format: " + QuoteForError(format) + " is not bt or mavocc");
  }
  v1::GetOccupancyRequest request;
  request.set_method(*parsed);
  request.set_format(format == "bt" ? v1::OCCUPANCY_FORMAT_OCTOMAP_BT
                                    : v1::OCCUPANCY_FORMAT_MAVOCC);
  auto stub = Connect(connection);
  std::string bytes;
  double resolution = 0;
  if (int rc = DownloadChunks<v1::OccupancyChunk>(
          connection, "GetOccupancy",
          [&](grpc::ClientContext* c) { return stub->GetOccupancy(c, request); },
          [](const v1::OccupancyChunk& m) -> const v1::FileChunk& { return m.chunk(); }, &bytes,
          [&](const v1::OccupancyChunk& m) {
            if (m.chunk().offset() == 0) resolution = m.resolution_m();
          })) {
    return rc;
  }
  if (Status s = WriteStringToFileAtomic(out_path, bytes); !s.ok()) {
    std::cerr << "mavctl: " << s.message() << "\n";
    return 1;
  }
  std::cout << "wrote " << out_path << " (" << bytes.size() << " bytes, " << resolution << " m)\n";
  return 0;
}

int Query(const std::vector<std::string>& args) {
  Connection connection;
  FlagParser flags("mavctl map query", "Collision check of a box against the last built map.");
  AddConnectionFlags(&flags, &connection);
  std::string box_text, method;
  bool unknown_is_collision = false;
  flags.AddString("box", &box_text, "x0,y0,z0,x1,y1,z1 (world frame, m)");
  flags.AddString("method", &method, "sparse-mesh|octomap (default: the most recent build)");
  flags.AddBool("unknown-is-collision", &unknown_is_collision,
                "report UNKNOWN as COLLISION (the paper's convention)");
  ParseOrExit(&flags, &connection, args);
  if (box_text.empty()) return Usage("map query needs --box x0,y0,z0,x1,y1,z1");
  Result<v1::Box> box = ParseBox(box_text, "--box");
  if (!box.ok()) return Usage(box.status().message());
  Result<v1::MappingMethod> parsed = ParseMethod(method, true);
  if (!parsed.ok()) return Usage(parsed.status().message());
  v1::QueryCollisionRequest request;
  request.set_method(*parsed);
  *request.add_boxes() = *box;
  request.set_unknown_is_collision(unknown_is_collision);
  auto stub = Connect(connection);
  v1::QueryCollisionResponse response;
  if (int rc = CallUnary(connection, "QueryCollision", [&](grpc::ClientContext* c) {
        return stub->QueryCollision(c, request, &response);
      })) {
    return rc;
  }
  switch (response.states(0)) {
    case v1::COLLISION_STATE_FREE:
      std::cout << "FREE\n";
      break;
    case v1::COLLISION_STATE_COLLISION:
      std::cout << "COLLISION\n";
      break;
    default:
      std::cout << "UNKNOWN\n";
      break;
  }
  return 0;
}

int Mesh(const std::vector<std::string>& args) {
  Connection connection;
  connection.timeout_s = 30.0;
  FlagParser flags("mavctl map mesh", "Downloads the surface mesh of the last sparse-mesh build.");
  AddConnectionFlags(&flags, &connection);
  std::string out_path;
  bool ascii = false;
  flags.AddString("out", &out_path, "output file (.ply)");
  flags.AddBool("ascii", &ascii, "ASCII PLY instead of binary little-endian");
  ParseOrExit(&flags, &connection, args);
  if (out_path.empty()) return Usage("map mesh needs --out FILE.ply");
  v1::ExportMeshRequest request;
  request.set_format(ascii ? v1::MESH_FORMAT_PLY_ASCII : v1::MESH_FORMAT_PLY_BINARY);
  auto stub = Connect(connection);
  std::string bytes;
  if (int rc = DownloadChunks<v1::FileChunk>(
          connection, "ExportMesh",
          [&](grpc::ClientContext* c) { return stub->ExportMesh(c, request); },
          [](const v1::FileChunk& m) -> const v1::FileChunk& { return m; }, &bytes)) {
    return rc;
  }
  if (Status s = WriteStringToFileAtomic(out_path, bytes); !s.ok()) {
    std::cerr << "mavctl: " << s.message() << "\n";
    return 1;
  }
  std::cout << "wrote " << out_path << " (" << bytes.size() << " bytes)\n";
  return 0;
}

int StatusOrReset(const std::string& sub, const std::vector<std::string>& args) {
  Connection connection;
  FlagParser flags("mavctl map " + sub, sub == "reset" ? "Drops keyframes and maps."
                                                       : "Prints the mapping service's state.");
  AddConnectionFlags(&flags, &connection);
  ParseOrExit(&flags, &connection, args);
  auto stub = Connect(connection);
  v1::MappingStatus status;
  if (int rc = CallUnary(
          connection, sub == "reset" ? "Reset" : "GetStatus", [&](grpc::ClientContext* c) {
            return sub == "reset" ? stub->Reset(c, v1::MappingResetRequest(), &status)
                                  : stub->GetStatus(c, v1::MappingGetStatusRequest(), &status);
          })) {
    return rc;
  }
  PrintStatus(status);
  return 0;
}

}  // namespace

int MappingCommand(const std::vector<std::string>& args) {
  if (args.empty() || args[0] == "--help" || args[0] == "-h") {
    (args.empty() ? std::cerr : std::cout) << kMapUsage;
    return args.empty() ? 2 : 0;
  }
  const std::string& sub = args[0];
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  if (sub == "start") return Start(rest);
  if (sub == "reset" || sub == "status") return StatusOrReset(sub, rest);
  if (sub == "insert") return Insert(rest);
  if (sub == "build") return Build(rest);
  if (sub == "occupancy") return Occupancy(rest);
  if (sub == "query") return Query(rest);
  if (sub == "mesh") return Mesh(rest);
  std::cerr << "mavctl: unknown map subcommand '" << sub << "'\n" << kMapUsage;
  return 2;
}

}  // namespace mav::mavctl
