#pragma once
// The load loop every mav-load command shares (docs/services.md, "mav-load"): C calls in flight
// on one shared channel, back to back for S seconds with a deadline per call, either from C
// threads each a synchronous client (--client sync) or from gRPC's own threads with its callback
// API (--client async: no thread waits, a call's completion starts the next); a line per second; at
// the end the rate, the latency percentiles, the replies by what they said, the errors by gRPC
// code, the calls per backend (balanced targets), the server's CPU time and memory (--cpu-pid) and
// the verdict; --json FILE writes the totals. A command supplies its flags, its setup and one call
// function (CallFunction).

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <grpcpp/channel.h>
#include <grpcpp/client_context.h>
#include <grpcpp/support/status.h>

#include "clients/common/channel.h"
#include "mav/common/flags.h"
#include "mav/common/stats.h"
#include "mav/common/status.h"

namespace mav::load {

// The flags of every command.
struct CommonOptions {
  std::string address;  // HOST:PORT or a target naming several backends (channel.h)
  int64_t concurrency = 4;
  double duration_s = 10;
  double deadline_ms = 1000;
  double max_p99_ms = 0;
  bool fail_on_errors = false;
  // After the n-th failed call in a row (reset by an answered one), a random pause in
  // [0, min(backoff_max_ms, backoff_base_ms x 2^(n-1))] ms: exponential backoff with full jitter.
  // backoff_max_ms 0: a fixed 1 ms pause instead.
  double backoff_base_ms = 10;
  double backoff_max_ms = 1000;
  // false: a call made while the server is down waits for it (gRPC's wait_for_ready) until its
  // deadline, so a dead server costs one failed call per client and deadline, not thousands.
  bool fail_fast = false;
  std::string client = "sync";  // --client: sync | async (LoadRun::async_call)
  std::string json_path;        // --json: the totals as JSON
  std::string cpu_pids;         // --cpu-pid: "PID[,PID...]" of the server processes
};

// Adds the common flags (--address defaults to 127.0.0.1:`default_port`).
void AddCommonFlags(FlagParser* flags, CommonOptions* options, int default_port);

// Parses `args` into the flags: --help prints the usage and gives 0, a bad flag or value prints
// "mav-load: --flag: ..." and gives 2; std::nullopt when the command should go on.
std::optional<int> ParseFlags(FlagParser* flags, const std::vector<std::string>& args,
                              const CommonOptions& options);

// `name` without `prefix` when it starts with it: a reply name from a proto enum value's name,
// e.g. WithoutPrefix(v1::PlanStatus_Name(s), "PLAN_STATUS_") == "SUCCESS".
std::string WithoutPrefix(const std::string& name, const std::string& prefix);

// "mav-load: <message>" on stderr; returns 2 (Usage) or 1 (Fail).
int Usage(const std::string& message);
int Fail(const std::string& message);

// The channel of --address, connected within 5 s: InvalidArgument "--address: ..." for a target
// channel.h refuses; Unavailable "cannot connect to <address>" when no backend answers.
Result<std::shared_ptr<grpc::Channel>> Connect(const CommonOptions& options,
                                               const std::string& service);

// What a call returned, as tallied: the reply's category (a plan status, a tracking state, FREE /
// COLLISION, a control mode) and whether its latency measures the service (false: a reply the
// load itself provoked, such as localization's OUT_OF_ORDER; counted, not in the percentiles).
struct Reply {
  std::string name = "OK";
  bool timed = true;
};

// One call with `context` (deadline set by the loop); fills *reply when the status is OK.
// Called from every client thread at once.
using CallFunction = std::function<grpc::Status(grpc::ClientContext* context, Reply* reply)>;

// The same call with gRPC's callback API: starts it and returns; `done` runs once with its status
// (on one of gRPC's threads) after *reply is filled when the status is OK. `context` and `reply`
// stay valid until then.
using DoneFunction = std::function<void(const grpc::Status& status)>;
using AsyncCallFunction =
    std::function<void(grpc::ClientContext* context, Reply* reply, DoneFunction done)>;

// What the client threads add up.
struct Tally {
  std::mutex mutex;
  std::vector<double> latencies_ms;          // timed replies (8 bytes each)
  std::vector<double> error_latencies_ms;    // failed calls: how long a refusal took
  std::map<std::string, uint64_t> replies;   // by Reply::name
  std::map<std::string, uint64_t> errors;    // by gRPC code
  std::map<std::string, uint64_t> backends;  // calls by peer address (ClientContext::peer)
  std::vector<std::pair<uint64_t, uint64_t>> per_second;  // answered, failed in each second
  std::string first_error;
  uint64_t calls = 0;
  uint64_t answered = 0;  // calls with status OK
  uint64_t error_count = 0;
};

// A command's own verdict on the totals: one "FAIL: ..." line per failed condition (printed).
using ExtraVerdict = std::function<std::vector<std::string>(const Tally& tally)>;

struct LoadRun {
  std::string command;  // "planning", ...
  std::string what;     // the rest of the header line, e.g. "30 queries"
  std::shared_ptr<grpc::Channel> channel;
  CallFunction call;
  AsyncCallFunction async_call;  // optional: what --client async calls
  ExtraVerdict extra_verdict;    // optional
};

// Runs the load, prints progress and totals, writes --json; returns the exit status: 0, or 1
// when a condition failed (--fail-on-errors, --max-p99-ms, no call completed, extra_verdict) or
// the JSON file cannot be written.
int RunLoad(const CommonOptions& options, const LoadRun& run);

}  // namespace mav::load
