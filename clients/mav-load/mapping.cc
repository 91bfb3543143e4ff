// mav-load mapping: mav.v1.Mapping/QueryCollision with robot-sized boxes (--half-extent, 0.5 m)
// at seeded random positions inside the bounds of the server's map, --boxes per call (1). The
// map must exist: mav-load first asks GetStatus and stops with a message when the service has
// none, unless --build-room K builds one before the load through the service's own RPCs
// (StartSession with the rig inline and no DDS input, K forced keyframes of room-easy rendered in
// process, every 10th frame with its ground-truth pose, then BuildMap --map-method): that
// discards the service's session and maps. Replies are tallied per call: COLLISION when a box
// of the call collides, else UNKNOWN when one touches unknown space, else FREE.

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "mav/v1/mapping.grpc.pb.h"

#include "clients/mav-load/commands.h"
#include "clients/mav-load/frames.h"
#include "clients/mav-load/load.h"
#include "mav/common/time.h"
#include "services/common/grpc_status.h"
#include "services/common/proto_codec.h"

namespace mav::load {

namespace {

constexpr char kUsage[] =
    "mav-load mapping [--address HOST:PORT|TARGET] --concurrency C --duration S\n"
    "                        [--build-room K [--map-method sparse-mesh|octomap]]\n"
    "                        [--method latest|sparse-mesh|octomap] [--boxes N]\n"
    "                        [--half-extent M] [--seed S] [--unknown-is-collision]\n"
    "                        [--deadline-ms D] [--fail-on-errors] [--max-p99-ms X]\n"
    "                        [--json FILE] [--cpu-pid PID]\n\n"
    "Calls mav.v1.Mapping/QueryCollision back to back with seeded random boxes inside the map's\n"
    "bounds. The service must have a map (GetStatus), or --build-room K builds one first from K\n"
    "room-easy keyframes rendered in process (this discards the service's session and maps).\n"
    "Replies per call: COLLISION, UNKNOWN or FREE.";

constexpr int kRequestPool = 512;  // distinct requests cycled through

struct MappingOptions {
  CommonOptions common;
  int64_t build_room = 0;
  std::string map_method = "sparse-mesh";
  std::string method = "latest";
  int64_t boxes = 1;
  double half_extent_m = 0.5;
  uint64_t seed = 1;
  bool unknown_is_collision = false;
};

std::optional<v1::MappingMethod> MethodOf(const std::string& name) {
  if (name == "latest") return v1::MAPPING_METHOD_UNSPECIFIED;
  if (name == "sparse-mesh") return v1::MAPPING_METHOD_SPARSE_MESH;
  if (name == "octomap") return v1::MAPPING_METHOD_OCTOMAP;
  return std::nullopt;
}

std::optional<int> ParseOptions(const std::vector<std::string>& args, MappingOptions* o) {
  FlagParser flags(kUsage);
  AddCommonFlags(&flags, &o->common, 50053);
  flags.AddInt("build-room", &o->build_room,
               "first build a map from K room-easy keyframes (0 = use the server's map)", 0, 200);
  flags.AddString("map-method", &o->map_method, "--build-room's method: sparse-mesh|octomap");
  flags.AddString("method", &o->method, "the map queried: latest|sparse-mesh|octomap");
  flags.AddInt("boxes", &o->boxes, "boxes per call", 1, 50000);
  flags.AddDouble("half-extent", &o->half_extent_m, "half the side of a box, m", 0.01, 100);
  flags.AddUint64("seed", &o->seed, "seed of the boxes");
  flags.AddBool("unknown-is-collision", &o->unknown_is_collision,
                "the request's unknown_is_collision");
  if (std::optional<int> done = ParseFlags(&flags, args, o->common)) return done;
  if (!MethodOf(o->method)) {
    return Usage("--method: '" + o->method + "' (known: latest, sparse-mesh, octomap)");
  }
  if (o->map_method == "latest" || !MethodOf(o->map_method)) {
    return Usage("--map-method: '" + o->map_method + "' (known: sparse-mesh, octomap)");
  }
  return std::nullopt;
}

std::chrono::system_clock::time_point In(int seconds) {
  return std::chrono::system_clock::now() + std::chrono::seconds(seconds);
}

Status RpcError(const MappingOptions& o, const std::string& rpc, const grpc::Status& s) {
  return Status::Unavailable(rpc + " at " + o.common.address +
                             " failed: " + service_common::GrpcCodeName(s.error_code()) + ": " +
                             s.error_message());
}

Status InsertKeyframes(const MappingOptions& o, const StereoFrames& frames,
                       v1::Mapping::Stub* stub) {
  for (size_t k = 0; k < frames.t_ns.size(); ++k) {
    v1::InsertKeyframeRequest request;
    request.mutable_stereo()->set_t_ns(frames.t_ns[k]);
    SetStereoImages(frames, k, request.mutable_stereo());
    service_common::ToProto(frames.T_world_body[k], request.mutable_t_world_body());
    request.set_force(true);
    grpc::ClientContext context;
    context.set_deadline(In(60));
    v1::InsertKeyframeResponse response;
    const grpc::Status s = stub->InsertKeyframe(&context, request, &response);
    if (!s.ok()) return RpcError(o, "InsertKeyframe", s);
  }
  return Status::Ok();
}

// --build-room: a fresh session, K keyframes, one build.
Status BuildRoom(const MappingOptions& o, v1::Mapping::Stub* stub) {
  FrameSelection selection;
  selection.frames = o.build_room;
  selection.stride = 10;
  selection.rectified = true;
  const int64_t start_ns = MonotonicNowNs();
  MAV_ASSIGN_OR_RETURN(const StereoFrames frames, LoadFrames(selection));
  if (frames.T_world_body.empty()) return Status::Internal("--build-room: no ground-truth poses");
  v1::StartSessionRequest session;
  SetCalibration(frames, session.mutable_calibration()->mutable_calibration());
  session.set_pose_source(v1::POSE_SOURCE_NONE);
  session.set_disable_dds_input(true);
  grpc::ClientContext context;
  context.set_deadline(In(30));
  v1::MappingStatus status;
  if (grpc::Status s = stub->StartSession(&context, session, &status); !s.ok()) {
    return RpcError(o, "StartSession", s);
  }
  MAV_RETURN_IF_ERROR(InsertKeyframes(o, frames, stub));
  v1::BuildMapRequest build;
  build.set_method(*MethodOf(o.map_method));
  grpc::ClientContext build_context;
  build_context.set_deadline(In(300));
  v1::BuildMapResponse built;
  if (grpc::Status s = stub->BuildMap(&build_context, build, &built); !s.ok()) {
    return RpcError(o, "BuildMap", s);
  }
  std::printf("built:    %s map of %u keyframes of %s in %.1f s (server: %.0f ms)\n",
              o.map_method.c_str(), built.keyframes(), frames.source.c_str(),
              SecondsSince(start_ns), built.timing().total_ms());
  return Status::Ok();
}

// The bounds of the queried map (the union of the maps' bounds for "latest"); FailedPrecondition
// when the service has no such map.
Result<Eigen::AlignedBox3d> MapBounds(const MappingOptions& o, v1::Mapping::Stub* stub) {
  grpc::ClientContext context;
  context.set_deadline(In(10));
  v1::MappingStatus status;
  if (grpc::Status s = stub->GetStatus(&context, v1::MappingGetStatusRequest(), &status); !s.ok()) {
    return RpcError(o, "GetStatus", s);
  }
  const v1::MappingMethod wanted = *MethodOf(o.method);
  Eigen::AlignedBox3d bounds;  // empty
  for (const v1::BuildMapResponse& map : status.maps()) {
    if (wanted != v1::MAPPING_METHOD_UNSPECIFIED && map.method() != wanted) continue;
    Result<Eigen::AlignedBox3d> box =
        service_common::BoxFromProto(map.occupancy().bounds(), "bounds");
    if (box.ok()) bounds.extend(*box);
  }
  if (bounds.isEmpty()) {
    return Status::FailedPrecondition(
        o.common.address + " has no " + (o.method == "latest" ? "" : o.method + " ") +
        "map: build one first (mavctl map start/build), or give --build-room K");
  }
  return bounds;
}

std::vector<v1::QueryCollisionRequest> RandomRequests(const MappingOptions& o,
                                                      const Eigen::AlignedBox3d& bounds) {
  std::mt19937_64 rng(o.seed);
  const Eigen::Vector3d half = Eigen::Vector3d::Constant(o.half_extent_m);
  std::vector<v1::QueryCollisionRequest> requests(kRequestPool);
  for (v1::QueryCollisionRequest& request : requests) {
    request.set_method(*MethodOf(o.method));
    request.set_unknown_is_collision(o.unknown_is_collision);
    for (int64_t b = 0; b < o.boxes; ++b) {
      Eigen::Vector3d centre;
      for (int a = 0; a < 3; ++a) {
        const double lo = bounds.min()[a] + half[a], hi = bounds.max()[a] - half[a];
        centre[a] = lo < hi ? std::uniform_real_distribution<double>(lo, hi)(rng)
                            : 0.5 * (bounds.min()[a] + bounds.max()[a]);
      }
      service_common::ToProto(Eigen::AlignedBox3d(centre - half, centre + half),
                              request.add_boxes());
    }
  }
  return requests;
}

// A reply's name: COLLISION when a box collides, else UNKNOWN when one touches unknown space, else
// FREE.
const char* Verdict(const v1::QueryCollisionResponse& response) {
  return response.collisions() > 0 ? "COLLISION" : response.unknown() > 0 ? "UNKNOWN" : "FREE";
}

}  // namespace

int RunMapping(const std::vector<std::string>& args) {
  MappingOptions options;
  if (std::optional<int> done = ParseOptions(args, &options)) return *done;
  Result<std::shared_ptr<grpc::Channel>> channel = Connect(options.common, "mav.v1.Mapping");
  if (!channel.ok()) return Fail(channel.status().message());
  std::shared_ptr<v1::Mapping::Stub> stub = v1::Mapping::NewStub(*channel);
  if (options.build_room > 0) {
    if (Status s = BuildRoom(options, stub.get()); !s.ok()) return Fail(s.message());
  }
  Result<Eigen::AlignedBox3d> bounds = MapBounds(options, stub.get());
  if (!bounds.ok()) return Fail(bounds.status().message());
  std::printf("map:      %s, bounds (%.2f, %.2f, %.2f) .. (%.2f, %.2f, %.2f) m\n",
              options.method.c_str(), bounds->min().x(), bounds->min().y(), bounds->min().z(),
              bounds->max().x(), bounds->max().y(), bounds->max().z());
  auto requests = std::make_shared<const std::vector<v1::QueryCollisionRequest>>(
      RandomRequests(options, *bounds));
  auto next = std::make_shared<std::atomic<uint64_t>>(0);

  LoadRun run;
  run.command = "mapping";
  char what[96];
  std::snprintf(what, sizeof(what), "%lld box(es) of %.2f m per call",
                static_cast<long long>(options.boxes), 2 * options.half_extent_m);
  run.what = what;
  run.channel = *channel;
  run.call = [stub, requests, next](grpc::ClientContext* context, Reply* reply) {
    const v1::QueryCollisionRequest& request = (*requests)[next->fetch_add(1) % requests->size()];
    v1::QueryCollisionResponse response;
    grpc::Status status = stub->QueryCollision(context, request, &response);
    if (status.ok()) reply->name = Verdict(response);
    return status;
  };
  run.async_call = [stub, requests, next](grpc::ClientContext* context, Reply* reply,
                                          DoneFunction done) {
    const v1::QueryCollisionRequest& request = (*requests)[next->fetch_add(1) % requests->size()];
    auto response = std::make_shared<v1::QueryCollisionResponse>();
    stub->async()->QueryCollision(
        context, &request, response.get(),
        [response, reply, done = std::move(done)](const grpc::Status& status) {
          if (status.ok()) reply->name = Verdict(*response);
          done(status);
        });
  };
  return RunLoad(options.common, run);
}

}  // namespace mav::load
