#include "clients/mavctl/plan_commands.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <sstream>

#include "mav/v1/planning.grpc.pb.h"

#include "clients/mavctl/connection.h"
#include "mav/common/file.h"
#include "mav/common/parse.h"
#include "mav/common/text.h"
#include "mav/transport/flags.h"

namespace mav::mavctl {

namespace {

using transport::FlagParser;

constexpr int64_t kPlanningPort = 50054;
constexpr char kPlanningPortEnv[] = "MAV_PLANNING_PORT";
// UploadMap chunks (common.proto: servers accept up to 4 MiB).
constexpr size_t kUploadChunkBytes = 1 << 20;

constexpr char kPlanUsage[] =
    "Usage: mavctl plan <subcommand> [flags]   (mavctl plan <subcommand> --help for its flags)\n"
    "  plan load (--file PATH | --mapping HOST:PORT [--method sparse-mesh|octomap] |\n"
    "             --upload FILE.bt) [--robot-radius M] [--unknown-free] [--max-distance M]\n"
    "             [--bounds x0,y0,z0,x1,y1,z1] [--distance-method exact|edt3d]\n"
    "  plan roadmap [--milestones N] [--budget S] [--seed S] [--margin M]\n"
    "               [--validity-resolution M] [--save FILE.mavprm] | --load FILE.mavprm\n"
    "  plan path --start x,y,z --goal x,y,z [--via \"x,y,z;x,y,z\"] [--max-speed V] ...\n"
    "  plan legs --points \"x,y,z;x,y,z;...\"\n"
    "  plan get PLAN_ID\n"
    "  plan sample PLAN_ID [--dt S] [--out FILE.csv]\n"
    "  plan status\n"
    "Common flags: --address A (127.0.0.1), --port P (50054, env MAV_PLANNING_PORT),\n"
    "--timeout S (RPC deadline, 10 s; plan load and plan roadmap 120 s).\n";

struct Connection : mavctl::Connection {
  Connection() : mavctl::Connection(kPlanningPort, kPlanningPortEnv) {}
};

int Usage(const std::string& message) {
  std::cerr << "mavctl: " << message << "\n";
  return 2;
}

std::unique_ptr<v1::Planning::Stub> Connect(const Connection& connection) {
  return v1::Planning::NewStub(MakeChannel(connection));
}

std::string Fixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", digits, v);
  return buf;
}

// `n` comma-separated finite numbers; InvalidArgument naming the flag.
Result<std::vector<double>> ParseVector(std::string_view text, size_t n, const std::string& flag) {
  const std::vector<std::string_view> fields = SplitFields(text, ',');
  if (fields.size() != n) {
    return Status::InvalidArgument(flag + ": " + QuoteForError(text) + " is not " +
                                   std::to_string(n) + " comma-separated numbers");
  }
  std::vector<double> v;
  for (std::string_view f : fields) {
    MAV_ASSIGN_OR_RETURN(const double x, ParseDouble(Trim(f), flag));
    if (!std::isfinite(x)) return Status::InvalidArgument(flag + ": not finite");
    v.push_back(x);
  }
  return v;
}

v1::Vector3 MakePoint(double x, double y, double z) {
  v1::Vector3 p;
  p.set_x(x);
  p.set_y(y);
  p.set_z(z);
  return p;
}

// Points "x,y,z;x,y,z;..." (at least `min_points`); InvalidArgument naming the flag.
Result<std::vector<v1::Vector3>> ParsePoints(const std::string& text, const std::string& flag,
                                             size_t min_points) {
  std::vector<v1::Vector3> points;
  for (std::string_view item : SplitFields(text, ';')) {
    item = Trim(item);
    if (item.empty()) continue;
    MAV_ASSIGN_OR_RETURN(const std::vector<double> v, ParseVector(item, 3, flag));
    points.push_back(MakePoint(v[0], v[1], v[2]));
  }
  if (points.size() < min_points) {
    return Status::InvalidArgument(flag + ": expected at least " + std::to_string(min_points) +
                                   " point(s) x,y,z");
  }
  return points;
}

std::string PointText(const v1::Vector3& p) {
  char buf[96];
  std::snprintf(buf, sizeof(buf), "(%.2f, %.2f, %.2f)", p.x(), p.y(), p.z());
  return buf;
}

const char* PlanStatusText(v1::PlanStatus status) {
  switch (status) {
    case v1::PLAN_STATUS_SUCCESS:
      return "SUCCESS";
    case v1::PLAN_STATUS_NO_PATH:
      return "NO_PATH";
    case v1::PLAN_STATUS_START_INVALID:
      return "START_INVALID";
    case v1::PLAN_STATUS_GOAL_INVALID:
      return "GOAL_INVALID";
    case v1::PLAN_STATUS_TIMEOUT:
      return "TIMEOUT";
    case v1::PLAN_STATUS_TRAJECTORY_FAILED:
      return "TRAJECTORY_FAILED";
    default:
      return "UNSPECIFIED";
  }
}

std::string BoxText(const v1::Box& b) { return PointText(b.min()) + " .. " + PointText(b.max()); }

void PrintMap(const v1::MapInfo& m) {
  std::cout << "map:       " << m.source() << ", " << m.resolution_m() << " m, "
            << m.octree_leaves() << " leaves, bounds " << BoxText(m.bounds()) << "\n"
            << "planning:  " << BoxText(m.planning_bounds()) << ", robot radius "
            << m.robot_radius_m() << " m; grid " << m.occupied_voxels() << " occupied, "
            << m.free_voxels() << " free, " << m.unknown_voxels() << " unknown cells, "
            << m.memory_bytes() / 1000000 << " MB\n"
            << "time:      load " << Fixed(m.load_ms(), 0) << " ms, distance map "
            << Fixed(m.distance_map_ms(), 0) << " ms; fingerprint " << std::hex << m.fingerprint()
            << std::dec << "\n";
}

void PrintRoadmap(const v1::RoadmapInfo& r) {
  std::cout << "roadmap:   " << r.milestones() << " milestones (largest component "
            << r.largest_component() << "), " << r.edges() << " edges, "
            << r.memory_bytes() / 1000000 << " MB, seed " << r.seed() << ", margin "
            << r.clearance_margin_m() << " m; "
            << (r.load_ms() > 0 ? "loaded in " + Fixed(r.load_ms(), 0) + " ms"
                                : "built in " + Fixed(r.build_s(), 1) + " s")
            << " (" << r.source() << ")\n";
}

void PrintPlan(const v1::PlanPathResponse& r) {
  std::cout << "status:    " << PlanStatusText(r.status())
            << (r.message().empty() ? "" : ": " + r.message()) << "\n";
  if (r.status() != v1::PLAN_STATUS_SUCCESS) return;
  std::cout << "plan_id:   " << r.plan_id() << (r.used_roadmap() ? "" : " (fresh PRM*)") << "\n"
            << "path:      " << r.path_size() << " points, " << Fixed(r.path_cost().length_m(), 2)
            << " m raw; shortened " << r.shortened_path_size() << " points, "
            << Fixed(r.shortened_cost().length_m(), 2) << " m, cost "
            << Fixed(r.shortened_cost().total(), 2) << "\n";
  for (const v1::Vector3& p : r.shortened_path())
    std::cout << "           " << PointText(p) << "\n";
  const v1::PlanTimings& t = r.timings();
  std::cout << "spline:    " << r.trajectory().segments_size() << " quintic segments, "
            << Fixed(r.trajectory_length_m(), 2) << " m, flight " << Fixed(r.duration_s(), 2)
            << " s, mean " << Fixed(r.mean_speed_mps(), 2) << " m/s, peak "
            << Fixed(r.max_speed_mps(), 2) << " m/s, min clearance "
            << Fixed(r.trajectory_min_clearance_m(), 3) << " m, " << r.trajectory_refits()
            << " refits\n"
            << "time:      " << Fixed(t.total_ms(), 2) << " ms (connect "
            << Fixed(t.connect_ms(), 2) << ", search " << Fixed(t.search_ms(), 2) << ", shorten "
            << Fixed(t.shorten_ms(), 2) << ", speed plan " << Fixed(t.speed_plan_ms(), 2)
            << ", spline " << Fixed(t.spline_ms(), 2) << ", check " << Fixed(t.check_ms(), 2)
            << ")\n";
}

// t,x,y,z,vx,vy,vz,ax,ay,az,yaw
std::string SamplesCsv(const google::protobuf::RepeatedPtrField<v1::TrajectorySample>& samples) {
  std::ostringstream out;
  out << "t,x,y,z,vx,vy,vz,ax,ay,az,yaw\n";
  char line[256];
  for (const v1::TrajectorySample& s : samples) {
    std::snprintf(line, sizeof(line), "%.3f,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f\n",
                  s.t_s(), s.position().x(), s.position().y(), s.position().z(), s.velocity().x(),
                  s.velocity().y(), s.velocity().z(), s.acceleration().x(), s.acceleration().y(),
                  s.acceleration().z(), s.yaw_rad());
    out << line;
  }
  return out.str();
}

int WriteCsv(const std::string& path,
             const google::protobuf::RepeatedPtrField<v1::TrajectorySample>& samples) {
  if (Status s = WriteStringToFileAtomic(path, SamplesCsv(samples)); !s.ok()) {
    std::cerr << "mavctl: " << s.message() << "\n";
    return 1;
  }
  std::cout << "wrote " << path << " (" << samples.size() << " samples)\n";
  return 0;
}

int Load(const std::vector<std::string>& args) {
  Connection connection;
  connection.timeout_s = 120;
  FlagParser flags("mavctl plan load", "Loads the map the planner plans in (drops the roadmap).");
  AddConnectionFlags(&flags, &connection);
  std::string file, mapping, method, upload, bounds, distance_method = "exact";
  double robot_radius = 0, max_distance = 0;
  bool unknown_free = false;
  flags.AddString("file", &file, "an OctoMap .bt on the server");
  flags.AddString("mapping", &mapping, "a mapping service's host:port (its latest map)");
  flags.AddString("method", &method, "with --mapping: sparse-mesh|octomap (default: latest)");
  flags.AddString("upload", &upload, "an OctoMap .bt on this machine, streamed to the server");
  flags.AddDouble("robot-radius", &robot_radius, "m (0 = 0.5)");
  flags.AddBool("unknown-free", &unknown_free, "treat unknown space as free (default: obstacle)");
  flags.AddDouble("max-distance", &max_distance, "distance map saturation, m (0 = 5)");
  flags.AddString("bounds", &bounds, "planning volume x0,y0,z0,x1,y1,z1 (default: the map's)");
  flags.AddString("distance-method", &distance_method, "exact|edt3d");
  ParseOrExit(&flags, &connection, args);
  if (file.empty() + mapping.empty() + upload.empty() != 2) {
    return Usage("plan load needs exactly one of --file, --mapping or --upload");
  }
  v1::MapOptions options;
  options.set_robot_radius_m(robot_radius);
  options.set_unknown_is_free(unknown_free);
  options.set_max_distance_m(max_distance);
  if (!bounds.empty()) {
    Result<std::vector<double>> v = ParseVector(bounds, 6, "--bounds");
    if (!v.ok()) return Usage(v.status().message());
    *options.mutable_bounds()->mutable_min() = MakePoint((*v)[0], (*v)[1], (*v)[2]);
    *options.mutable_bounds()->mutable_max() = MakePoint((*v)[3], (*v)[4], (*v)[5]);
  }
  if (distance_method == "edt3d") {
    options.set_distance_method(v1::DISTANCE_METHOD_DYNAMIC_EDT3D);
  } else if (distance_method != "exact") {
    return Usage("--distance-method: " + QuoteForError(distance_method) + " is not exact or edt3d");
  }
  auto stub = Connect(connection);
  v1::MapInfo info;
  if (!upload.empty()) {
    Result<std::string> bytes = ReadFileToString(upload);
    if (!bytes.ok()) {
      std::cerr << "mavctl: " << bytes.status().message() << "\n";
      return 1;
    }
    if (int rc = CallUnary(connection, "UploadMap", [&](grpc::ClientContext* c) {
          auto writer = stub->UploadMap(c, &info);
          size_t offset = 0;
          do {
            v1::UploadMapRequest message;
            if (offset == 0) *message.mutable_options() = options;
            const size_t n = std::min(kUploadChunkBytes, bytes->size() - offset);
            v1::FileChunk* chunk = message.mutable_chunk();
            chunk->set_offset(offset);
            chunk->set_total_size(bytes->size());
            chunk->set_data(bytes->substr(offset, n));
            offset += n;
            chunk->set_last(offset == bytes->size());
            if (!writer->Write(message)) break;
          } while (offset < bytes->size());
          writer->WritesDone();
          return writer->Finish();
        })) {
      return rc;
    }
  } else {
    v1::LoadMapRequest request;
    *request.mutable_options() = options;
    if (!file.empty()) {
      request.mutable_file()->set_path(file);
    } else {
      request.mutable_mapping()->set_address(mapping);
      if (method == "sparse-mesh") {
        request.mutable_mapping()->set_method(v1::MAPPING_METHOD_REF_SPARSE_MESH);
      } else if (method == "octomap") {
        request.mutable_mapping()->set_method(v1::MAPPING_METHOD_REF_OCTOMAP);
      } else if (!method.empty()) {
        return Usage("--method: " + QuoteForError(method) + " is not sparse-mesh or octomap");
      }
    }
    if (int rc = CallUnary(connection, "LoadMap", [&](grpc::ClientContext* c) {
          return stub->LoadMap(c, request, &info);
        })) {
      return rc;
    }
  }
  PrintMap(info);
  return 0;
}

int Roadmap(const std::vector<std::string>& args) {
  Connection connection;
  connection.timeout_s = 120;
  FlagParser flags("mavctl plan roadmap",
                   "Builds the PRM* roadmap on the loaded map (or loads one with --load).");
  AddConnectionFlags(&flags, &connection);
  uint64_t milestones = 0, seed = 1;
  double budget = 0, margin = -1, validity = 0;
  std::string save, load;
  flags.AddUint64("milestones", &milestones, "milestones (0 = 100000)");
  flags.AddDouble("budget", &budget, "PRM* time budget, s (0 = 45)");
  flags.AddUint64("seed", &seed, "seed of the build");
  flags.AddDouble("margin", &margin, "clearance margin beyond the robot radius, m (default 0.05)");
  flags.AddDouble("validity-resolution", &validity, "motion check step, m (0 = 1 cm)");
  flags.AddString("save", &save, "then save it on the server as FILE.mavprm");
  flags.AddString("load", &load, "load FILE.mavprm (on the server) instead of building");
  ParseOrExit(&flags, &connection, args);
  if (milestones > UINT32_MAX) return Usage("--milestones: too large");
  auto stub = Connect(connection);
  v1::RoadmapInfo info;
  if (!load.empty()) {
    v1::LoadRoadmapRequest request;
    request.set_path(load);
    if (int rc = CallUnary(connection, "LoadRoadmap", [&](grpc::ClientContext* c) {
          return stub->LoadRoadmap(c, request, &info);
        })) {
      return rc;
    }
    PrintRoadmap(info);
    return 0;
  }
  v1::BuildRoadmapRequest request;
  request.set_max_milestones(static_cast<uint32_t>(milestones));
  request.set_time_budget_s(budget);
  request.set_seed(seed);
  request.set_validity_resolution_m(validity);
  if (margin >= 0) request.set_clearance_margin_m(margin);
  if (int rc = CallUnary(connection, "BuildRoadmap", [&](grpc::ClientContext* c) {
        return stub->BuildRoadmap(c, request, &info);
      })) {
    return rc;
  }
  PrintRoadmap(info);
  if (save.empty()) return 0;
  v1::SaveRoadmapRequest save_request;
  save_request.set_path(save);
  if (int rc = CallUnary(connection, "SaveRoadmap", [&](grpc::ClientContext* c) {
        return stub->SaveRoadmap(c, save_request, &info);
      })) {
    return rc;
  }
  std::cout << "saved to " << save << " on the server\n";
  return 0;
}

// The PlanPath flags shared by `plan path` and `plan legs`.
struct PlanFlags {
  double max_speed = 0, max_acceleration = 0, max_lateral = 0, max_jerk = 0, start_yaw = 0;
  double budget = 0, sample_dt = 0;
  std::string yaw = "constant";
  bool no_roadmap = false;

  void Register(FlagParser* flags) {
    flags->AddDouble("max-speed", &max_speed, "m/s (0 = 10)");
    flags->AddDouble("max-acceleration", &max_acceleration, "along the path, m/s^2 (0 = 6)");
    flags->AddDouble("max-lateral", &max_lateral, "lateral acceleration, m/s^2 (0 = 7)");
    flags->AddDouble("max-jerk", &max_jerk, "m/s^3 (0 = 15)");
    flags->AddString("yaw", &yaw, "constant|along-path");
    flags->AddDouble("start-yaw", &start_yaw, "rad");
    flags->AddBool("no-roadmap", &no_roadmap, "a fresh PRM* per leg instead of the roadmap");
    flags->AddDouble("budget", &budget, "without the roadmap: PRM* time per leg, s (0 = 1)");
  }
  Status Fill(v1::PlanPathRequest* r) const {
    r->mutable_limits()->set_max_speed_mps(max_speed);
    r->mutable_limits()->set_max_acceleration_mps2(max_acceleration);
    r->mutable_limits()->set_max_lateral_acceleration_mps2(max_lateral);
    r->mutable_limits()->set_max_jerk_mps3(max_jerk);
    r->set_start_yaw_rad(start_yaw);
    if (yaw == "along-path") {
      r->set_yaw_policy(v1::YAW_POLICY_ALONG_PATH);
    } else if (yaw == "constant") {
      r->set_yaw_policy(v1::YAW_POLICY_CONSTANT);
    } else {
      return Status::InvalidArgument("--yaw: " + QuoteForError(yaw) +
                                     " is not constant or along-path");
    }
    if (no_roadmap) r->set_use_roadmap(false);
    r->set_time_budget_s(budget);
    r->set_sample_dt_s(sample_dt);
    return Status::Ok();
  }
};

int Path(const std::vector<std::string>& args) {
  Connection connection;
  FlagParser flags("mavctl plan path", "Plans start -> waypoints -> goal and prints the plan.");
  AddConnectionFlags(&flags, &connection);
  std::string start, goal, via, out;
  PlanFlags plan;
  flags.AddString("start", &start, "x,y,z (world, m)");
  flags.AddString("goal", &goal, "x,y,z");
  flags.AddString("via", &via, "waypoints \"x,y,z;x,y,z\" visited in order");
  plan.Register(&flags);
  flags.AddDouble("sample-dt", &plan.sample_dt, "samples in the reply every S s (0 = none)");
  flags.AddString("out", &out, "write the samples (--sample-dt, default 0.01) as CSV");
  ParseOrExit(&flags, &connection, args);
  if (start.empty() || goal.empty()) return Usage("plan path needs --start and --goal");
  if (!out.empty() && plan.sample_dt == 0) plan.sample_dt = 0.01;
  v1::PlanPathRequest request;
  Result<std::vector<v1::Vector3>> s = ParsePoints(start, "--start", 1);
  Result<std::vector<v1::Vector3>> g = ParsePoints(goal, "--goal", 1);
  Result<std::vector<v1::Vector3>> w = ParsePoints(via, "--via", 0);
  for (const auto* r : {&s, &g, &w}) {
    if (!r->ok()) return Usage(r->status().message());
  }
  *request.mutable_start() = s->front();
  *request.mutable_goal() = g->front();
  for (const v1::Vector3& p : *w) *request.add_waypoints() = p;
  if (Status st = plan.Fill(&request); !st.ok()) return Usage(st.message());
  auto stub = Connect(connection);
  v1::PlanPathResponse response;
  if (int rc = CallUnary(connection, "PlanPath", [&](grpc::ClientContext* c) {
        return stub->PlanPath(c, request, &response);
      })) {
    return rc;
  }
  PrintPlan(response);
  if (response.status() != v1::PLAN_STATUS_SUCCESS) return 1;
  return out.empty() ? 0 : WriteCsv(out, response.samples());
}

int Legs(const std::vector<std::string>& args) {
  Connection connection;
  FlagParser flags("mavctl plan legs",
                   "Plans each consecutive pair of points (a contest task's legs, e.g. t4_3) and "
                   "prints a table with the paper's figures beside.");
  AddConnectionFlags(&flags, &connection);
  std::string points;
  PlanFlags plan;
  flags.AddString("points", &points, "\"x,y,z;x,y,z;...\" (at least two)");
  plan.Register(&flags);
  ParseOrExit(&flags, &connection, args);
  Result<std::vector<v1::Vector3>> p = ParsePoints(points, "--points", 2);
  if (!p.ok()) return Usage(p.status().message());
  auto stub = Connect(connection);
  std::printf("%-4s %-22s %-22s %-8s %8s %8s %8s %8s %8s %8s\n", "leg", "from", "to", "status",
              "len [m]", "plan[ms]", "fly [s]", "avg[m/s]", "peak", "clr [m]");
  int failures = 0;
  for (size_t i = 0; i + 1 < p->size(); ++i) {
    v1::PlanPathRequest request;
    *request.mutable_start() = (*p)[i];
    *request.mutable_goal() = (*p)[i + 1];
    if (Status st = plan.Fill(&request); !st.ok()) return Usage(st.message());
    v1::PlanPathResponse r;
    if (int rc = CallUnary(connection, "PlanPath", [&](grpc::ClientContext* c) {
          return stub->PlanPath(c, request, &r);
        })) {
      return rc;
    }
    const bool ok = r.status() == v1::PLAN_STATUS_SUCCESS;
    failures += !ok;
    std::printf("%-4zu %-22s %-22s %-8s %8.2f %8.2f %8.2f %8.2f %8.2f %8.3f\n", i + 1,
                PointText((*p)[i]).c_str(), PointText((*p)[i + 1]).c_str(),
                ok ? "OK" : PlanStatusText(r.status()), r.trajectory_length_m(),
                r.timings().total_ms(), r.duration_s(), r.mean_speed_mps(), r.max_speed_mps(),
                r.trajectory_min_clearance_m());
    if (!ok) std::printf("     %s\n", r.message().c_str());
  }
  std::printf(
      "paper (Holzmann et al. 2015, Sec. 3): 35 m planned in 750 ms, flown in 7.55-8.8 s, "
      "4.2 m/s average, 7.7 m/s peak\n");
  return failures > 0 ? 1 : 0;
}

int Get(const std::vector<std::string>& args) {
  Connection connection;
  FlagParser flags("mavctl plan get PLAN_ID", "Prints a previous plan (the last 16 are kept).");
  AddConnectionFlags(&flags, &connection);
  const std::vector<std::string> positional = ParseOrExit(&flags, &connection, args, true);
  if (positional.size() != 1) return Usage("plan get needs one PLAN_ID");
  v1::GetPlanRequest request;
  request.set_plan_id(positional[0]);
  auto stub = Connect(connection);
  v1::PlanPathResponse response;
  if (int rc = CallUnary(connection, "GetPlan", [&](grpc::ClientContext* c) {
        return stub->GetPlan(c, request, &response);
      })) {
    return rc;
  }
  PrintPlan(response);
  return 0;
}

int Sample(const std::vector<std::string>& args) {
  Connection connection;
  FlagParser flags("mavctl plan sample PLAN_ID",
                   "Samples a plan's spline as CSV (t,x,y,z,vx,vy,vz,ax,ay,az,yaw).");
  AddConnectionFlags(&flags, &connection);
  double dt = 0.01;
  std::string out;
  flags.AddDouble("dt", &dt, "step, s");
  flags.AddString("out", &out, "write to FILE.csv (default: stdout)");
  const std::vector<std::string> positional = ParseOrExit(&flags, &connection, args, true);
  if (positional.size() != 1) return Usage("plan sample needs one PLAN_ID");
  v1::SampleTrajectoryRequest request;
  request.set_plan_id(positional[0]);
  request.set_dt_s(dt);
  auto stub = Connect(connection);
  v1::SampleTrajectoryResponse response;
  if (int rc = CallUnary(connection, "SampleTrajectory", [&](grpc::ClientContext* c) {
        return stub->SampleTrajectory(c, request, &response);
      })) {
    return rc;
  }
  if (out.empty()) {
    std::cout << SamplesCsv(response.samples());
    return 0;
  }
  return WriteCsv(out, response.samples());
}

int StatusCommand(const std::vector<std::string>& args) {
  Connection connection;
  FlagParser flags("mavctl plan status", "Map, roadmap, long operation and plan statistics.");
  AddConnectionFlags(&flags, &connection);
  ParseOrExit(&flags, &connection, args);
  auto stub = Connect(connection);
  v1::PlanningStatus s;
  if (int rc = CallUnary(connection, "GetRoadmapStatus", [&](grpc::ClientContext* c) {
        return stub->GetRoadmapStatus(c, v1::GetRoadmapStatusRequest(), &s);
      })) {
    return rc;
  }
  if (s.map_loaded()) {
    PrintMap(s.map());
  } else {
    std::cout << "map:       none\n";
  }
  if (s.roadmap_ready()) {
    PrintRoadmap(s.roadmap());
  } else {
    std::cout << "roadmap:   none\n";
  }
  if (s.busy()) {
    std::cout << "busy:      " << s.operation() << ": " << s.build_progress().stage() << " "
              << Fixed(100 * s.build_progress().fraction(), 0) << " %, "
              << Fixed(s.build_progress().elapsed_s(), 1) << " s\n";
  }
  if (!s.last_error().empty()) std::cout << "last error: " << s.last_error() << "\n";
  const v1::RuntimeStats& t = s.planning_ms();
  std::cout << "plans:     " << s.plans() << " answered, " << s.plans_succeeded() << " succeeded, "
            << s.plans_rejected() << " rejected (in flight " << s.plans_in_flight() << " of "
            << s.max_plans_in_flight() << "), " << s.plans_failed() << " failed; "
            << s.plans_stored() << " of " << s.plan_history() << " kept\n"
            << "time:      median " << Fixed(t.median_ms(), 2) << " ms, p95 "
            << Fixed(t.p95_ms(), 2) << ", p99 " << Fixed(t.p99_ms(), 2) << ", max "
            << Fixed(t.max_ms(), 2) << " (last " << t.count() << ")\n";
  return 0;
}

}  // namespace

int PlanCommand(const std::vector<std::string>& args) {
  if (args.empty() || args[0] == "--help" || args[0] == "-h") {
    std::cout << kPlanUsage;
    return args.empty() ? 2 : 0;
  }
  const std::string& sub = args[0];
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  if (sub == "load") return Load(rest);
  if (sub == "roadmap") return Roadmap(rest);
  if (sub == "path") return Path(rest);
  if (sub == "legs") return Legs(rest);
  if (sub == "get") return Get(rest);
  if (sub == "sample") return Sample(rest);
  if (sub == "status") return StatusCommand(rest);
  std::cerr << "mavctl: unknown plan subcommand '" << sub << "'\n" << kPlanUsage;
  return 2;
}

}  // namespace mav::mavctl
