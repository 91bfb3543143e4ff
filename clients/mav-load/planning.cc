// mav-load planning: mav.v1.Planning/PlanPath, cycling through the queries of --queries
// (mav/dataset/planning_queries.h, the format of mav-eval planning) or a seeded set drawn with
// planning::RandomQueries on a local copy of the server's map (--map: half with the straight line
// blocked, half free, 20-40 m apart, each connected by the reference search). Replies are tallied
// by plan status; --require-success fails the run on any reply other than SUCCESS.

#include <atomic>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "mav/v1/planning.grpc.pb.h"

#include "clients/mav-load/commands.h"
#include "clients/mav-load/load.h"
#include "mav/common/file.h"
#include "mav/dataset/planning_queries.h"
#include "mav/planning/planning_map.h"
#include "mav/planning/reference_path.h"

namespace mav::load {

namespace {

constexpr char kUsage[] =
    "mav-load planning [--address HOST:PORT|TARGET] --concurrency C --duration S\n"
    "                         (--queries FILE | --map FILE.bt [--seed S] [--count N])\n"
    "                         [--deadline-ms D] [--fail-on-errors] [--require-success]\n"
    "                         [--max-p99-ms X] [--save-queries FILE] [--json FILE]\n"
    "                         [--cpu-pid PID]\n\n"
    "Calls mav.v1.Planning/PlanPath back to back, cycling through the queries; replies by plan\n"
    "status.";

using Queries = std::vector<std::vector<Eigen::Vector3d>>;

struct PlanningOptions {
  CommonOptions common;
  std::string queries_path;
  std::string map_path;
  std::string save_path;
  int64_t count = 30;
  double robot_radius = 0.5;
  uint64_t seed = 1;
  bool require_success = false;
};

// Parses and checks the flags. Returns the exit code when the command is finished (--help
// printed, or a usage error), std::nullopt when it should go on.
std::optional<int> ParseOptions(const std::vector<std::string>& args, PlanningOptions* o) {
  FlagParser flags(kUsage);
  AddCommonFlags(&flags, &o->common, 50054);
  flags.AddString("queries", &o->queries_path, "query file (sx sy sz [waypoints] gx gy gz, #)");
  flags.AddString("map", &o->map_path,
                  "without --queries: draw queries on this .bt (the server's)");
  flags.AddUint64("seed", &o->seed, "seed of the drawn queries");
  flags.AddInt("count", &o->count, "number of drawn queries", 1, 100000);
  flags.AddDouble("robot-radius", &o->robot_radius, "robot radius of the drawn queries, m", 0, 100);
  flags.AddString("save-queries", &o->save_path,
                  "write the queries used to FILE (--queries format)");
  flags.AddBool("require-success", &o->require_success, "exit 1 on any reply other than SUCCESS");
  if (std::optional<int> done = ParseFlags(&flags, args, o->common)) return done;
  if (o->queries_path.empty() == o->map_path.empty()) {
    return Usage("--queries / --map: give exactly one of --queries FILE or --map FILE.bt");
  }
  return std::nullopt;
}

Result<Queries> RandomSet(const PlanningOptions& o) {
  planning::MapOptions options;
  options.robot_radius_m = o.robot_radius;
  MAV_ASSIGN_OR_RETURN(auto map, planning::PlanningMap::LoadFile(o.map_path, options));
  planning::RandomQueryOptions random;
  random.seed = o.seed;
  random.blocked = static_cast<int>(o.count - o.count / 2);
  random.free = static_cast<int>(o.count / 2);
  // Kept only when the reference search connects them: every drawn query has a solution.
  MAV_ASSIGN_OR_RETURN(const auto drawn, planning::RandomQueries(*map, random));
  Queries out;
  for (const auto& q : drawn) out.push_back({q.start, q.goal});
  return out;
}

// The queries of --queries, or those drawn on --map. An error's message is the whole text after
// "mav-load: ".
Result<Queries> LoadQueries(const PlanningOptions& o) {
  Queries queries;
  if (!o.queries_path.empty()) {
    MAV_ASSIGN_OR_RETURN(const auto read, dataset::ReadPlanningQueries(o.queries_path));
    for (const auto& q : read) queries.push_back(q.points);
    return queries;
  }
  Result<Queries> drawn = RandomSet(o);
  if (!drawn.ok()) return Status::InvalidArgument("--map: " + drawn.status().ToString());
  if (drawn->empty()) return Status::InvalidArgument("--map: no queries drawn");
  return drawn;
}

Status SaveQueries(const std::string& path, const Queries& queries) {
  std::string text = "# sx sy sz [waypoints] gx gy gz (mav-load planning --save-queries)\n";
  char number[32];
  for (const auto& points : queries) {
    for (const Eigen::Vector3d& p : points) {
      for (int a = 0; a < 3; ++a) {
        std::snprintf(number, sizeof(number), "%.4f ", p[a]);
        text += number;
      }
    }
    text.back() = '\n';
  }
  return WriteStringToFileAtomic(path, text);
}

void SetPoint(const Eigen::Vector3d& p, v1::Vector3* out) {
  out->set_x(p.x());
  out->set_y(p.y());
  out->set_z(p.z());
}

std::vector<v1::PlanPathRequest> MakeRequests(const Queries& queries) {
  std::vector<v1::PlanPathRequest> requests;
  for (const auto& points : queries) {
    v1::PlanPathRequest r;
    SetPoint(points.front(), r.mutable_start());
    SetPoint(points.back(), r.mutable_goal());
    for (size_t i = 1; i + 1 < points.size(); ++i) SetPoint(points[i], r.add_waypoints());
    requests.push_back(r);
  }
  return requests;
}

std::string PlanStatusName(v1::PlanStatus status) {
  return WithoutPrefix(v1::PlanStatus_Name(status), "PLAN_STATUS_");
}

}  // namespace

int RunPlanning(const std::vector<std::string>& args) {
  PlanningOptions options;
  if (std::optional<int> done = ParseOptions(args, &options)) return *done;
  Result<Queries> queries = LoadQueries(options);
  if (!queries.ok()) return Fail(queries.status().message());
  if (!options.save_path.empty()) {
    if (Status s = SaveQueries(options.save_path, *queries); !s.ok()) return Fail(s.message());
  }
  Result<std::shared_ptr<grpc::Channel>> channel = Connect(options.common, "mav.v1.Planning");
  if (!channel.ok()) return Fail(channel.status().message());

  struct Calls {
    std::shared_ptr<v1::Planning::Stub> stub;
    std::vector<v1::PlanPathRequest> requests;
    std::atomic<uint64_t> next{0};
  };
  auto calls = std::make_shared<Calls>();
  calls->stub = v1::Planning::NewStub(*channel);
  calls->requests = MakeRequests(*queries);
  LoadRun run;
  run.command = "planning";
  run.what = std::to_string(calls->requests.size()) + " queries";
  run.channel = *channel;
  run.call = [calls](grpc::ClientContext* context, Reply* reply) {
    const v1::PlanPathRequest& request =
        calls->requests[calls->next.fetch_add(1) % calls->requests.size()];
    v1::PlanPathResponse response;
    grpc::Status status = calls->stub->PlanPath(context, request, &response);
    if (status.ok()) reply->name = PlanStatusName(response.status());
    return status;
  };
  run.async_call = [calls](grpc::ClientContext* context, Reply* reply, DoneFunction done) {
    const v1::PlanPathRequest& request =
        calls->requests[calls->next.fetch_add(1) % calls->requests.size()];
    auto response = std::make_shared<v1::PlanPathResponse>();
    calls->stub->async()->PlanPath(
        context, &request, response.get(),
        [response, reply, done = std::move(done)](const grpc::Status& status) {
          if (status.ok()) reply->name = PlanStatusName(response->status());
          done(status);
        });
  };
  if (options.require_success) {
    run.extra_verdict = [](const Tally& tally) {
      const auto it = tally.replies.find("SUCCESS");
      const uint64_t successes = it == tally.replies.end() ? 0 : it->second;
      std::vector<std::string> out;
      if (successes != tally.answered) {
        out.push_back(std::to_string(tally.answered - successes) + " replies other than SUCCESS");
      }
      return out;
    };
  }
  return RunLoad(options.common, run);
}

}  // namespace mav::load
