// mav-load: a load generator for the stack's services (docs/services.md, "mav-load").
//
//   mav-load planning [--address HOST:PORT] --concurrency C --duration S
//                     [--queries FILE | --map FILE.bt [--seed S] [--count N]]
//                     [--deadline-ms D] [--fail-on-errors] [--require-success] [--max-p99-ms X]
//                     [--save-queries FILE]
//
// `planning`: C threads, each a synchronous client on one shared channel, call
// mav.v1.Planning/PlanPath back to back for S seconds with a deadline of D ms per call, cycling
// through the queries: those of --queries (mav/dataset/planning_queries.h, the format of
// mav-eval planning) or a seeded set drawn with planning::RandomQueries on a local copy of the
// server's map (--map: half with the straight line blocked, half free, 20-40 m apart). Every
// second a line (calls in that second, p50/p99 so far, errors so far); at the end the rate,
// the latency p50/p95/p99/max (nearest rank, mav::SummarizeRuntimes: client-side wall time of
// each call), the replies by plan status and the errors by gRPC code. A thread whose call failed
// (e.g. RESOURCE_EXHAUSTED: more than the server's plans in flight) pauses 1 ms before the next.
// Exit status: 0; 1 when asked to fail (--fail-on-errors: any RPC error; --require-success: any
// reply other than SUCCESS; --max-p99-ms: p99 above it) or the server cannot be reached;
// 2 usage error.

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>

#include "mav/v1/planning.grpc.pb.h"

#include "mav/common/file.h"
#include "mav/common/flags.h"
#include "mav/common/stats.h"
#include "mav/common/time.h"
#include "mav/dataset/planning_queries.h"
#include "mav/planning/planning_map.h"
#include "mav/planning/reference_path.h"
#include "services/common/grpc_status.h"

namespace {

constexpr char kUsage[] =
    "Usage: mav-load planning [--address HOST:PORT] --concurrency C --duration S\n"
    "                         [--queries FILE | --map FILE.bt [--seed S] [--count N]]\n"
    "                         [--deadline-ms D] [--fail-on-errors] [--require-success]\n"
    "                         [--max-p99-ms X] [--save-queries FILE]\n";

int Usage(const std::string& message) {
  std::cerr << "mav-load: " << message << "\n";
  return 2;
}

std::vector<std::vector<Eigen::Vector3d>> RandomSet(const std::string& map_path, uint64_t seed,
                                                    int64_t count, double robot_radius,
                                                    std::string* error) {
  mav::planning::MapOptions options;
  options.robot_radius_m = robot_radius;
  auto map = mav::planning::PlanningMap::LoadFile(map_path, options);
  if (!map.ok()) {
    *error = map.status().ToString();
    return {};
  }
  mav::planning::RandomQueryOptions random;
  random.seed = seed;
  random.blocked = static_cast<int>(count - count / 2);
  random.free = static_cast<int>(count / 2);
  // Kept only when the reference search connects them: every drawn query has a solution.
  auto queries = mav::planning::RandomQueries(**map, random);
  if (!queries.ok()) {
    *error = queries.status().ToString();
    return {};
  }
  std::vector<std::vector<Eigen::Vector3d>> out;
  for (const auto& q : *queries) out.push_back({q.start, q.goal});
  return out;
}

void SetPoint(const Eigen::Vector3d& p, mav::v1::Vector3* out) {
  out->set_x(p.x());
  out->set_y(p.y());
  out->set_z(p.z());
}

const char* PlanStatusName(mav::v1::PlanStatus status) {
  const std::string& name = mav::v1::PlanStatus_Name(status);
  static const std::string kPrefix = "PLAN_STATUS_";
  return name.c_str() + (name.rfind(kPrefix, 0) == 0 ? kPrefix.size() : 0);
}

struct Tally {
  std::mutex mutex;
  std::vector<double> latencies_ms;         // every answered call (8 bytes each)
  std::map<std::string, uint64_t> replies;  // by plan status
  std::map<std::string, uint64_t> errors;   // by gRPC code
  std::string first_error;
  uint64_t calls = 0;
  uint64_t error_count = 0;
};

struct PlanningOptions {
  std::string address = "127.0.0.1:50054";
  std::string queries_path;
  std::string map_path;
  std::string save_path;
  int64_t concurrency = 4;
  int64_t count = 30;
  double duration_s = 10;
  double deadline_ms = 1000;
  double max_p99_ms = 0;
  double robot_radius = 0.5;
  uint64_t seed = 1;
  bool fail_on_errors = false;
  bool require_success = false;
};

// Parses and checks the flags of `planning`. Returns the exit code when the command is finished
// (--help printed, or a usage error), std::nullopt when it should go on.
std::optional<int> ParsePlanningOptions(const std::vector<std::string>& args, PlanningOptions* o) {
  mav::FlagParser flags(kUsage);
  flags.AddString("address", &o->address, "the mav-planning server, host:port");
  flags.AddInt("concurrency", &o->concurrency, "client threads calling at once");
  flags.AddDouble("duration", &o->duration_s, "how long to call, s");
  flags.AddString("queries", &o->queries_path, "query file (sx sy sz gx gy gz [waypoints], #)");
  flags.AddString("map", &o->map_path,
                  "without --queries: draw queries on this .bt (the server's)");
  flags.AddUint64("seed", &o->seed, "seed of the drawn queries");
  flags.AddInt("count", &o->count, "number of drawn queries");
  flags.AddDouble("robot-radius", &o->robot_radius, "robot radius of the drawn queries, m");
  flags.AddString("save-queries", &o->save_path,
                  "write the queries used to FILE (--queries format)");
  flags.AddDouble("deadline-ms", &o->deadline_ms, "deadline of each call, ms");
  flags.AddBool("fail-on-errors", &o->fail_on_errors, "exit 1 on any RPC error");
  flags.AddBool("require-success", &o->require_success, "exit 1 on any reply other than SUCCESS");
  flags.AddDouble("max-p99-ms", &o->max_p99_ms, "exit 1 when p99 exceeds this (0 = no bound)");
  bool help = false;
  if (mav::Status s = flags.Parse(args, nullptr, &help); !s.ok()) return Usage(s.message());
  if (help) {
    std::cout << flags.Help();
    return 0;
  }
  if (o->concurrency < 1 || o->concurrency > 1024) {
    return Usage("--concurrency: must be in [1, 1024]");
  }
  if (!(o->duration_s > 0) || o->duration_s > 86400) {
    return Usage("--duration: must be in (0, 86400] s");
  }
  if (!(o->deadline_ms > 0) || !std::isfinite(o->deadline_ms)) {
    return Usage("--deadline-ms: must be > 0");
  }
  if (!(o->max_p99_ms >= 0) || !std::isfinite(o->max_p99_ms)) {
    return Usage("--max-p99-ms: must be >= 0");
  }
  if (o->queries_path.empty() == o->map_path.empty()) {
    return Usage("give exactly one of --queries FILE or --map FILE.bt");
  }
  if (o->count < 1 || o->count > 100000) return Usage("--count: must be in [1, 100000]");
  return std::nullopt;
}

// The queries of --queries, or those drawn on --map. An error's message is the whole text after
// "mav-load: ".
mav::Result<std::vector<std::vector<Eigen::Vector3d>>> LoadQueries(const PlanningOptions& o) {
  std::vector<std::vector<Eigen::Vector3d>> queries;
  if (!o.queries_path.empty()) {
    MAV_ASSIGN_OR_RETURN(const auto read, mav::dataset::ReadPlanningQueries(o.queries_path));
    for (const auto& q : read) queries.push_back(q.points);
    return queries;
  }
  std::string error;
  queries = RandomSet(o.map_path, o.seed, o.count, o.robot_radius, &error);
  if (queries.empty()) {
    return mav::Status::InvalidArgument("--map: " + (error.empty() ? "no queries drawn" : error));
  }
  return queries;
}

mav::Status SaveQueries(const std::string& path,
                        const std::vector<std::vector<Eigen::Vector3d>>& queries) {
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
  return mav::WriteStringToFileAtomic(path, text);
}

std::vector<mav::v1::PlanPathRequest> MakeRequests(
    const std::vector<std::vector<Eigen::Vector3d>>& queries) {
  std::vector<mav::v1::PlanPathRequest> requests;
  for (const auto& points : queries) {
    mav::v1::PlanPathRequest r;
    SetPoint(points.front(), r.mutable_start());
    SetPoint(points.back(), r.mutable_goal());
    for (size_t i = 1; i + 1 < points.size(); ++i) SetPoint(points[i], r.add_waypoints());
    requests.push_back(r);
  }
  return requests;
}

// What the client threads share: the requests to cycle through, the next one's index, when to
// stop, and the tally they add to.
struct Load {
  std::shared_ptr<grpc::Channel> channel;
  std::vector<mav::v1::PlanPathRequest> requests;
  double deadline_ms = 0;
  int64_t end_ns = 0;
  std::atomic<uint64_t> next{0};
  Tally tally;
};

void Record(const grpc::Status& status, const mav::v1::PlanPathResponse& response, double ms,
            Tally* tally) {
  std::lock_guard<std::mutex> lock(tally->mutex);
  ++tally->calls;
  if (status.ok()) {
    tally->latencies_ms.push_back(ms);
    ++tally->replies[PlanStatusName(response.status())];
    return;
  }
  ++tally->error_count;
  ++tally->errors[mav::service_common::GrpcCodeName(status.error_code())];
  if (tally->first_error.empty()) {
    tally->first_error = std::string(mav::service_common::GrpcCodeName(status.error_code())) +
                         ": " + status.error_message();
  }
}

// One client thread: calls back to back until the end of the run.
void CallUntilEnd(Load* load) {
  auto stub = mav::v1::Planning::NewStub(load->channel);
  while (mav::MonotonicNowNs() < load->end_ns) {
    const mav::v1::PlanPathRequest& request =
        load->requests[load->next.fetch_add(1) % load->requests.size()];
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() +
                         std::chrono::microseconds(static_cast<int64_t>(load->deadline_ms * 1e3)));
    mav::v1::PlanPathResponse response;
    const int64_t call_ns = mav::MonotonicNowNs();
    const grpc::Status status = stub->PlanPath(&context, request, &response);
    const double ms = mav::MsSince(call_ns);
    Record(status, response, ms, &load->tally);
    // A refused client pauses instead of spinning on the server's cores.
    if (!status.ok()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
}

// A line per second until the end: the calls of that second, percentiles of all answered calls
// so far.
void PrintProgress(int64_t start_ns, Load* load) {
  uint64_t last_calls = 0;
  for (int second = 1; mav::MonotonicNowNs() < load->end_ns; ++second) {
    const int64_t wake_ns = std::min(load->end_ns, start_ns + second * mav::kNsPerSecond);
    std::this_thread::sleep_for(std::chrono::nanoseconds(wake_ns - mav::MonotonicNowNs()));
    std::vector<double> so_far;
    uint64_t calls = 0, errors = 0;
    {
      std::lock_guard<std::mutex> lock(load->tally.mutex);
      so_far = load->tally.latencies_ms;
      calls = load->tally.calls;
      errors = load->tally.error_count;
    }
    const mav::RuntimeStats s = mav::SummarizeRuntimes(std::move(so_far));
    std::printf("[%3d s] %6llu calls/s   p50 %7.2f ms   p99 %7.2f ms   errors %llu\n", second,
                static_cast<unsigned long long>(calls - last_calls), s.median_ms, s.p99_ms,
                static_cast<unsigned long long>(errors));
    std::fflush(stdout);
    last_calls = calls;
  }
}

void PrintTotals(const Tally& tally, double elapsed_s, const mav::RuntimeStats& s) {
  std::printf("\ncalls:    %llu in %.2f s = %.1f calls/s (%zu answered = %.1f /s)\n",
              static_cast<unsigned long long>(tally.calls), elapsed_s,
              static_cast<double>(tally.calls) / elapsed_s, tally.latencies_ms.size(),
              static_cast<double>(tally.latencies_ms.size()) / elapsed_s);
  std::printf(
      "latency:  p50 %.2f ms, p95 %.2f ms, p99 %.2f ms, max %.2f ms, mean %.2f ms "
      "(nearest rank, answered calls)\n",
      s.median_ms, s.p95_ms, s.p99_ms, s.max_ms, s.mean_ms);
  std::printf("replies: ");
  for (const auto& [name, n] : tally.replies) {
    std::printf(" %s %llu", name.c_str(), static_cast<unsigned long long>(n));
  }
  std::printf("\nerrors:   %llu", static_cast<unsigned long long>(tally.error_count));
  for (const auto& [name, n] : tally.errors) {
    std::printf("  %s %llu", name.c_str(), static_cast<unsigned long long>(n));
  }
  std::printf("\n");
  if (!tally.first_error.empty()) std::printf("first error: %s\n", tally.first_error.c_str());
}

// The exit status: 1 when any of the conditions asked for failed (each is printed), else 0.
int Verdict(const PlanningOptions& o, const Tally& tally, const mav::RuntimeStats& s) {
  int rc = 0;
  if (o.fail_on_errors && tally.error_count > 0) {
    std::printf("FAIL: %llu errors\n", static_cast<unsigned long long>(tally.error_count));
    rc = 1;
  }
  const uint64_t successes = tally.replies.count("SUCCESS") ? tally.replies.at("SUCCESS") : 0;
  if (o.require_success && successes != tally.latencies_ms.size()) {
    std::printf("FAIL: %llu replies other than SUCCESS\n",
                static_cast<unsigned long long>(tally.latencies_ms.size() - successes));
    rc = 1;
  }
  if (o.max_p99_ms > 0 && s.p99_ms > o.max_p99_ms) {
    std::printf("FAIL: p99 %.2f ms above --max-p99-ms %.2f\n", s.p99_ms, o.max_p99_ms);
    rc = 1;
  }
  if (tally.calls == 0) {
    std::printf("FAIL: no call completed\n");
    rc = 1;
  }
  return rc;
}

int RunPlanning(const std::vector<std::string>& args) {
  PlanningOptions options;
  if (std::optional<int> done = ParsePlanningOptions(args, &options)) return *done;
  auto queries = LoadQueries(options);
  if (!queries.ok()) {
    std::cerr << "mav-load: " << queries.status().message() << "\n";
    return 1;
  }
  if (!options.save_path.empty()) {
    if (mav::Status s = SaveQueries(options.save_path, *queries); !s.ok()) {
      std::cerr << "mav-load: " << s.message() << "\n";
      return 1;
    }
  }
  Load load;
  load.requests = MakeRequests(*queries);
  load.deadline_ms = options.deadline_ms;
  load.channel = grpc::CreateChannel(options.address, grpc::InsecureChannelCredentials());
  if (!load.channel->WaitForConnected(std::chrono::system_clock::now() + std::chrono::seconds(5))) {
    std::cerr << "mav-load: cannot connect to " << options.address << "\n";
    return 1;
  }
  std::printf("mav-load planning: %s, concurrency %lld, %.1f s, %zu queries, deadline %.0f ms\n",
              options.address.c_str(), static_cast<long long>(options.concurrency),
              options.duration_s, load.requests.size(), options.deadline_ms);
  std::fflush(stdout);

  const int64_t start_ns = mav::MonotonicNowNs();
  load.end_ns = start_ns + mav::SecondsToNs(options.duration_s);
  std::vector<std::thread> workers;
  for (int64_t w = 0; w < options.concurrency; ++w) workers.emplace_back(CallUntilEnd, &load);
  PrintProgress(start_ns, &load);
  for (std::thread& t : workers) t.join();
  const double elapsed_s = mav::SecondsSince(start_ns);

  const mav::RuntimeStats s = mav::SummarizeRuntimes(load.tally.latencies_ms);
  PrintTotals(load.tally, elapsed_s, s);
  return Verdict(options, load.tally, s);
}

}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string> words(argv + 1, argv + argc);
  const std::string command = words.empty() ? "" : words.front();
  if (command == "planning") return RunPlanning({words.begin() + 1, words.end()});
  if (command == "--help" || command == "-h") {
    std::cout << kUsage;
    return 0;
  }
  std::cerr << kUsage;
  return command.empty() ? 2 : Usage("unknown command '" + command + "' (known: planning)");
}
