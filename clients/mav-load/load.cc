#include "clients/mav-load/load.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <random>
#include <sstream>
#include <thread>

#include "mav/common/file.h"
#include "mav/common/parse.h"
#include "mav/common/text.h"
#include "mav/common/time.h"
#include "services/common/grpc_status.h"

namespace mav::load {

namespace {

unsigned long long U(uint64_t n) { return static_cast<unsigned long long>(n); }

// ---- the server's process (--cpu-pid) ----------------------------------------------------------

struct ProcessSample {
  bool ok = false;
  std::string error;
  double cpu_s = 0;  // utime + stime
  int64_t vm_hwm_kb = -1;
  int64_t vm_rss_kb = -1;
};

// utime + stime of /proc/PID/stat (fields 14 and 15, after the command name in parentheses),
// VmHWM and VmRSS of /proc/PID/status.
ProcessSample ReadProcess(int64_t pid) {
  ProcessSample s;
  const std::string dir = "/proc/" + std::to_string(pid);
  Result<std::string> stat = ReadFileToString(dir + "/stat");
  Result<std::string> status = ReadFileToString(dir + "/status");
  if (!stat.ok() || !status.ok()) {
    s.error = (!stat.ok() ? stat.status() : status.status()).message();
    return s;
  }
  const size_t paren = stat->rfind(')');
  std::istringstream fields(paren == std::string::npos ? "" : stat->substr(paren + 1));
  std::string field;
  uint64_t utime = 0, stime = 0;
  for (int i = 3; i <= 15 && fields >> field; ++i) {
    if (i == 14) utime = std::strtoull(field.c_str(), nullptr, 10);
    if (i == 15) stime = std::strtoull(field.c_str(), nullptr, 10);
  }
  s.cpu_s = static_cast<double>(utime + stime) / static_cast<double>(sysconf(_SC_CLK_TCK));
  std::istringstream lines(*status);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("VmHWM:", 0) == 0) s.vm_hwm_kb = std::strtoll(line.c_str() + 6, nullptr, 10);
    if (line.rfind("VmRSS:", 0) == 0) s.vm_rss_kb = std::strtoll(line.c_str() + 6, nullptr, 10);
  }
  s.ok = true;
  return s;
}

struct ServerUsage {
  int64_t pid = 0;
  ProcessSample before, after;
};

Result<std::vector<ServerUsage>> ParsePids(const std::string& text) {
  std::vector<ServerUsage> out;
  if (text.empty()) return out;
  for (std::string_view field : SplitFields(text, ',')) {
    MAV_ASSIGN_OR_RETURN(const int64_t pid, ParseInt64(Trim(field), "--cpu-pid"));
    if (pid <= 0) return Status::InvalidArgument("--cpu-pid: " + std::to_string(pid) + " <= 0");
    out.push_back({pid, {}, {}});
  }
  return out;
}

// ---- the load ----------------------------------------------------------------------------------

// What the client threads share.
struct Shared {
  const LoadRun* run = nullptr;
  const CommonOptions* options = nullptr;
  int64_t end_ns = 0;
  Tally tally;
};

void Record(const grpc::Status& status, const Reply& reply, const std::string& peer, double ms,
            Tally* tally) {
  std::lock_guard<std::mutex> lock(tally->mutex);
  ++tally->calls;
  ++tally->backends[peer.empty() ? "(none)" : client::PeerAddress(peer)];
  if (status.ok()) {
    ++tally->answered;
    if (reply.timed) tally->latencies_ms.push_back(ms);
    ++tally->replies[reply.name];
    return;
  }
  const char* code = service_common::GrpcCodeName(status.error_code());
  tally->error_latencies_ms.push_back(ms);
  ++tally->error_count;
  ++tally->errors[code];
  if (tally->first_error.empty()) {
    tally->first_error = std::string(code) + ": " + status.error_message();
  }
}

// The pause after the `failures`-th failed call in a row: 1 ms, or with a cap the full-jitter
// exponential backoff of backoff_base_ms and backoff_max_ms.
std::chrono::microseconds PauseAfterFailure(const CommonOptions& o, int failures,
                                            std::mt19937* random) {
  if (o.backoff_max_ms <= 0) return std::chrono::milliseconds(1);
  const double ceiling_ms =
      std::min(o.backoff_max_ms, o.backoff_base_ms * std::ldexp(1.0, std::min(failures - 1, 30)));
  std::uniform_real_distribution<double> pause_ms(0.0, ceiling_ms);
  return std::chrono::microseconds(static_cast<int64_t>(pause_ms(*random) * 1e3));
}

// A call's deadline (--deadline-ms from now) and whether it waits for a server that is down.
void PrepareContext(const CommonOptions& o, grpc::ClientContext* context) {
  context->set_deadline(std::chrono::system_clock::now() +
                        std::chrono::microseconds(static_cast<int64_t>(o.deadline_ms * 1e3)));
  context->set_wait_for_ready(!o.fail_fast);
}

// One client thread: calls back to back until the end of the run.
void CallUntilEnd(Shared* shared, uint32_t seed) {
  std::mt19937 random(seed);
  int failures = 0;  // in a row
  while (MonotonicNowNs() < shared->end_ns) {
    grpc::ClientContext context;
    PrepareContext(*shared->options, &context);
    Reply reply;
    const int64_t call_ns = MonotonicNowNs();
    const grpc::Status status = shared->run->call(&context, &reply);
    const double ms = MsSince(call_ns);
    Record(status, reply, context.peer(), ms, &shared->tally);
    // A refused client pauses instead of spinning on the server's cores.
    failures = status.ok() ? 0 : failures + 1;
    if (failures > 0) {
      std::this_thread::sleep_for(PauseAfterFailure(*shared->options, failures, &random));
    }
  }
}

// ---- the asynchronous client (--client async) ---------------------------------------------

// Calls that failed wait out their pause here, on one thread, so that no gRPC callback thread
// sleeps: Add(wake, resume) runs `resume` on that thread at `wake` (MonotonicNowNs), in order.
class PauseLine {
 public:
  PauseLine() : thread_([this] { Run(); }) {}
  ~PauseLine() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stopping_ = true;
    }
    changed_.notify_all();
    thread_.join();
  }
  void Add(int64_t wake_ns, std::function<void()> resume) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      waiting_.emplace(wake_ns, std::move(resume));
    }
    changed_.notify_all();
  }

 private:
  void Run() {
    std::unique_lock<std::mutex> lock(mutex_);
    while (!stopping_) {
      if (waiting_.empty()) {
        changed_.wait(lock);
        continue;
      }
      const int64_t wake_ns = waiting_.begin()->first;
      if (MonotonicNowNs() < wake_ns) {
        changed_.wait_for(lock, std::chrono::nanoseconds(wake_ns - MonotonicNowNs()));
        continue;
      }
      std::function<void()> resume = std::move(waiting_.begin()->second);
      waiting_.erase(waiting_.begin());
      lock.unlock();
      resume();
      lock.lock();
    }
  }

  std::mutex mutex_;
  std::condition_variable changed_;
  std::multimap<int64_t, std::function<void()>> waiting_;
  bool stopping_ = false;
  std::thread thread_;  // last: starts once the rest is built
};

// One of the C calls in flight: each completion records the call and starts the next (after a
// failure, from the pause line) until the end of the run, then counts itself out.
class AsyncSlot {
 public:
  AsyncSlot(Shared* shared, PauseLine* pauses, uint32_t seed, std::function<void()> finished)
      : shared_(shared), pauses_(pauses), random_(seed), finished_(std::move(finished)) {}

  void Start() {
    if (MonotonicNowNs() >= shared_->end_ns) {
      finished_();
      return;
    }
    // The previous call's context goes here, inside that call's completion: gRPC holds its own
    // reference to the call until the completion has returned.
    context_ = std::make_unique<grpc::ClientContext>();
    PrepareContext(*shared_->options, context_.get());
    reply_ = Reply();
    call_ns_ = MonotonicNowNs();
    shared_->run->async_call(context_.get(), &reply_,
                             [this](const grpc::Status& status) { Done(status); });
  }

 private:
  void Done(const grpc::Status& status) {
    Record(status, reply_, context_->peer(), MsSince(call_ns_), &shared_->tally);
    failures_ = status.ok() ? 0 : failures_ + 1;
    if (failures_ == 0) {
      Start();
      return;
    }
    const int64_t pause_ns =
        std::chrono::nanoseconds(PauseAfterFailure(*shared_->options, failures_, &random_)).count();
    pauses_->Add(std::min(shared_->end_ns, MonotonicNowNs() + pause_ns), [this] { Start(); });
  }

  Shared* shared_;
  PauseLine* pauses_;
  std::mt19937 random_;
  std::function<void()> finished_;
  std::unique_ptr<grpc::ClientContext> context_;
  Reply reply_;
  int64_t call_ns_ = 0;
  int failures_ = 0;  // in a row
};

// A line per second until the end: the calls of that second, percentiles of all timed replies
// so far.
void PrintProgress(int64_t start_ns, Shared* shared) {
  uint64_t last_answered = 0, last_errors = 0;
  for (int second = 1; MonotonicNowNs() < shared->end_ns; ++second) {
    const int64_t wake_ns = std::min(shared->end_ns, start_ns + second * kNsPerSecond);
    std::this_thread::sleep_for(std::chrono::nanoseconds(wake_ns - MonotonicNowNs()));
    std::vector<double> so_far;
    uint64_t answered = 0, errors = 0;
    {
      std::lock_guard<std::mutex> lock(shared->tally.mutex);
      so_far = shared->tally.latencies_ms;
      answered = shared->tally.answered;
      errors = shared->tally.error_count;
      shared->tally.per_second.push_back({answered - last_answered, errors - last_errors});
    }
    const RuntimeStats s = SummarizeRuntimes(std::move(so_far));
    std::printf("[%3d s] answered %6llu/s   failed %5llu/s   p50 %7.2f ms   p99 %7.2f ms\n", second,
                U(answered - last_answered), U(errors - last_errors), s.median_ms, s.p99_ms);
    std::fflush(stdout);
    last_answered = answered;
    last_errors = errors;
  }
}

// ---- the totals --------------------------------------------------------------------------------

struct Totals {
  double elapsed_s = 0;
  RuntimeStats latency;
  RuntimeStats error_latency;  // of the failed calls
  std::vector<ServerUsage> servers;
};

void PrintServers(const Totals& t) {
  for (const ServerUsage& u : t.servers) {
    if (!u.before.ok || !u.after.ok) {
      std::printf("server:   pid %lld not readable (%s): no CPU figures\n",
                  static_cast<long long>(u.pid),
                  (u.before.ok ? u.after.error : u.before.error).c_str());
      continue;
    }
    const double cpu_s = u.after.cpu_s - u.before.cpu_s;
    std::printf(
        "server:   pid %lld: %.2f s CPU in %.2f s (%.0f %% of one core), VmHWM %lld kB, "
        "VmRSS %lld kB\n",
        static_cast<long long>(u.pid), cpu_s, t.elapsed_s, 100.0 * cpu_s / t.elapsed_s,
        static_cast<long long>(u.after.vm_hwm_kb), static_cast<long long>(u.after.vm_rss_kb));
  }
}

void PrintTotals(const Tally& tally, const Totals& t, bool balanced) {
  const RuntimeStats& s = t.latency;
  std::printf("\ncalls:    %llu in %.2f s = %.1f calls/s (%llu answered = %.1f /s)\n",
              U(tally.calls), t.elapsed_s, static_cast<double>(tally.calls) / t.elapsed_s,
              U(tally.answered), static_cast<double>(tally.answered) / t.elapsed_s);
  std::printf(
      "latency:  p50 %.2f ms, p95 %.2f ms, p99 %.2f ms, max %.2f ms, mean %.2f ms "
      "(nearest rank, %zu timed replies)\n",
      s.median_ms, s.p95_ms, s.p99_ms, s.max_ms, s.mean_ms, tally.latencies_ms.size());
  std::printf("replies: ");
  for (const auto& [name, n] : tally.replies) std::printf(" %s %llu", name.c_str(), U(n));
  std::printf("\nerrors:   %llu", U(tally.error_count));
  for (const auto& [name, n] : tally.errors) std::printf("  %s %llu", name.c_str(), U(n));
  if (tally.error_count > 0) {
    std::printf("  (answered in p50 %.2f ms, p99 %.2f ms)", t.error_latency.median_ms,
                t.error_latency.p99_ms);
  }
  std::printf("\n");
  if (!tally.first_error.empty()) std::printf("first error: %s\n", tally.first_error.c_str());
  if (balanced || tally.backends.size() > 1) {
    std::printf("per backend:");
    const char* separator = " ";
    for (const auto& [peer, n] : tally.backends) {
      std::printf(
          "%s%s %.1f %% (%llu)", separator, peer.c_str(),
          100.0 * static_cast<double>(n) / static_cast<double>(std::max<uint64_t>(1, tally.calls)),
          U(n));
      separator = ", ";
    }
    std::printf("\n");
  }
  PrintServers(t);
}

// The failed conditions, one line each.
std::vector<std::string> Failures(const CommonOptions& o, const LoadRun& run, const Tally& tally,
                                  const RuntimeStats& s) {
  std::vector<std::string> out;
  if (o.fail_on_errors && tally.error_count > 0) {
    out.push_back(std::to_string(tally.error_count) + " errors");
  }
  if (o.max_p99_ms > 0 && s.p99_ms > o.max_p99_ms) {
    char text[96];
    std::snprintf(text, sizeof(text), "p99 %.2f ms above --max-p99-ms %.2f", s.p99_ms,
                  o.max_p99_ms);
    out.push_back(text);
  }
  if (tally.calls == 0) out.push_back("no call completed");
  if (run.extra_verdict) {
    for (std::string& f : run.extra_verdict(tally)) out.push_back(std::move(f));
  }
  return out;
}

// ---- JSON --------------------------------------------------------------------------------------

std::string CountObject(const std::map<std::string, uint64_t>& counts) {
  std::string out = "{";
  for (const auto& [name, n] : counts) {
    out += (out.size() > 1 ? ", " : "") + JsonQuote(name) + ": " + std::to_string(n);
  }
  return out + "}";
}

// [[answered, failed], ...] per second of the run.
std::string PerSecondJson(const Tally& tally) {
  std::string out = "[";
  for (const auto& [answered, failed] : tally.per_second) {
    out += (out.size() > 1 ? ", [" : "[") + std::to_string(answered) + ", " +
           std::to_string(failed) + "]";
  }
  return out + "]";
}

std::string ServersJson(const Totals& t) {
  std::string out = "[";
  for (const ServerUsage& u : t.servers) {
    out += out.size() > 1 ? ", " : "";
    out += "{\"pid\": " + std::to_string(u.pid);
    if (u.before.ok && u.after.ok) {
      out += ", \"cpu_s\": " + JsonNumber(u.after.cpu_s - u.before.cpu_s) +
             ", \"vm_hwm_kb\": " + std::to_string(u.after.vm_hwm_kb) +
             ", \"vm_rss_kb\": " + std::to_string(u.after.vm_rss_kb);
    } else {
      out += ", \"error\": " + JsonQuote(u.before.ok ? u.after.error : u.before.error);
    }
    out += "}";
  }
  return out + "]";
}

std::string TotalsJson(const CommonOptions& o, const LoadRun& run, const Tally& tally,
                       const Totals& t, const std::vector<std::string>& failures) {
  const RuntimeStats& s = t.latency;
  std::string failed = "[";
  for (const std::string& f : failures) failed += (failed.size() > 1 ? ", " : "") + JsonQuote(f);
  failed += "]";
  return "{\n  \"command\": " + JsonQuote(run.command) +
         ",\n  \"target\": " + JsonQuote(o.address) +
         ",\n  \"concurrency\": " + std::to_string(o.concurrency) +
         ",\n  \"duration_s\": " + JsonNumber(t.elapsed_s) +
         ",\n  \"deadline_ms\": " + JsonNumber(o.deadline_ms) +
         ",\n  \"calls\": " + std::to_string(tally.calls) +
         ",\n  \"answered\": " + std::to_string(tally.answered) +
         ",\n  \"timed\": " + std::to_string(tally.latencies_ms.size()) +
         ",\n  \"rate_per_s\": " + JsonNumber(static_cast<double>(tally.calls) / t.elapsed_s) +
         ",\n  \"answered_per_s\": " +
         JsonNumber(static_cast<double>(tally.answered) / t.elapsed_s) +
         ",\n  \"latency_ms\": {\"p50\": " + JsonNumber(s.median_ms) +
         ", \"p95\": " + JsonNumber(s.p95_ms) + ", \"p99\": " + JsonNumber(s.p99_ms) +
         ", \"max\": " + JsonNumber(s.max_ms) + ", \"mean\": " + JsonNumber(s.mean_ms) +
         "},\n  \"replies\": " + CountObject(tally.replies) +
         ",\n  \"errors\": " + CountObject(tally.errors) +
         ",\n  \"error_latency_ms\": {\"p50\": " + JsonNumber(t.error_latency.median_ms) +
         ", \"p99\": " + JsonNumber(t.error_latency.p99_ms) +
         ", \"max\": " + JsonNumber(t.error_latency.max_ms) + "}" +
         ",\n  \"error_count\": " + std::to_string(tally.error_count) +
         ",\n  \"per_backend\": " + CountObject(tally.backends) +
         ",\n  \"per_second\": " + PerSecondJson(tally) + ",\n  \"servers\": " + ServersJson(t) +
         ",\n  \"failures\": " + failed + "\n}\n";
}

}  // namespace

void AddCommonFlags(FlagParser* flags, CommonOptions* o, int default_port) {
  o->address = "127.0.0.1:" + std::to_string(default_port);
  flags->AddString("address", &o->address,
                   "the server, HOST:PORT, or several: ipv4:H:P,H:P,... | H:P,H:P,... (IP "
                   "literals) | dns:///HOST:PORT (round_robin + retries)");
  flags->AddInt("concurrency", &o->concurrency, "client threads calling at once", 1, 1024);
  flags->AddDouble("duration", &o->duration_s, "how long to call, s", 1e-3, 86400);
  flags->AddDouble("deadline-ms", &o->deadline_ms, "deadline of each call, ms", 1e-3, 3.6e6);
  flags->AddString("client", &o->client,
                   "sync: C threads, one blocking call each | async: C calls in flight from "
                   "gRPC's callback API, no thread per call (cheaper: a small call's client "
                   "costs less CPU)");
  flags->AddBool("fail-on-errors", &o->fail_on_errors, "exit 1 on any RPC error");
  flags->AddDouble("backoff-base-ms", &o->backoff_base_ms,
                   "after the n-th failed call in a row, a random pause up to "
                   "min(--backoff-max-ms, this x 2^(n-1)) ms",
                   0.001, 60000);
  flags->AddDouble("backoff-max-ms", &o->backoff_max_ms,
                   "the longest pause after failed calls, ms (0 = a fixed 1 ms pause)", 0, 600000);
  flags->AddBool("fail-fast", &o->fail_fast,
                 "fail a call at once while the server is down (default: wait for it until the "
                 "call's deadline, gRPC's wait_for_ready)");
  flags->AddDouble("max-p99-ms", &o->max_p99_ms, "exit 1 when p99 exceeds this (0 = no bound)", 0,
                   3.6e6);
  flags->AddString("json", &o->json_path, "write the totals to FILE as JSON");
  flags->AddString("cpu-pid", &o->cpu_pids,
                   "PID[,PID...] of the server processes: their CPU time over the run and "
                   "VmHWM/VmRSS at the end (/proc)");
}

std::optional<int> ParseFlags(FlagParser* flags, const std::vector<std::string>& args,
                              const CommonOptions& options) {
  bool help = false;
  if (Status s = flags->Parse(args, nullptr, &help); !s.ok()) return Usage(s.message());
  if (help) {
    std::cout << flags->Help();
    return 0;
  }
  if (Result<client::ChannelTarget> t = client::ParseTarget(options.address); !t.ok()) {
    return Usage("--address: " + t.status().message());
  }
  if (options.client != "sync" && options.client != "async") {
    return Usage("--client: '" + options.client + "' is neither sync nor async");
  }
  if (Result<std::vector<ServerUsage>> pids = ParsePids(options.cpu_pids); !pids.ok()) {
    return Usage(pids.status().message());
  }
  return std::nullopt;
}

std::string WithoutPrefix(const std::string& name, const std::string& prefix) {
  return name.rfind(prefix, 0) == 0 ? name.substr(prefix.size()) : name;
}

int Usage(const std::string& message) {
  std::cerr << "mav-load: " << message << "\n";
  return 2;
}

int Fail(const std::string& message) {
  std::cerr << "mav-load: " << message << "\n";
  return 1;
}

Result<std::shared_ptr<grpc::Channel>> Connect(const CommonOptions& options,
                                               const std::string& service) {
  Result<client::ChannelTarget> target = client::ParseTarget(options.address);
  if (!target.ok()) return Status::InvalidArgument("--address: " + target.status().message());
  std::shared_ptr<grpc::Channel> channel = client::MakeChannel(*target, {service});
  if (!channel->WaitForConnected(std::chrono::system_clock::now() + std::chrono::seconds(5))) {
    return Status::Unavailable("cannot connect to " + options.address);
  }
  return channel;
}

int RunLoad(const CommonOptions& o, const LoadRun& run) {
  if (o.client == "async" && !run.async_call) {
    return Usage("--client async: mav-load " + run.command + " has only a synchronous client");
  }
  Totals totals;
  totals.servers = *ParsePids(o.cpu_pids);  // checked by ParseFlags
  std::printf("mav-load %s: %s, concurrency %lld, %.1f s, deadline %.0f ms%s%s\n",
              run.command.c_str(), o.address.c_str(), static_cast<long long>(o.concurrency),
              o.duration_s, o.deadline_ms, run.what.empty() ? "" : ", ", run.what.c_str());
  std::fflush(stdout);
  Shared shared;
  shared.run = &run;
  shared.options = &o;
  for (ServerUsage& u : totals.servers) u.before = ReadProcess(u.pid);
  const int64_t start_ns = MonotonicNowNs();
  shared.end_ns = start_ns + SecondsToNs(o.duration_s);
  if (o.client == "async") {
    // The slots outlive their last completion: each counts itself out as the last thing it
    // does, and nothing of a slot is touched after that.
    PauseLine pauses;
    std::atomic<int64_t> running(o.concurrency);
    std::vector<std::unique_ptr<AsyncSlot>> slots;
    for (int64_t w = 0; w < o.concurrency; ++w) {
      slots.push_back(std::make_unique<AsyncSlot>(&shared, &pauses, static_cast<uint32_t>(w + 1),
                                                  [&running] { running.fetch_sub(1); }));
    }
    for (std::unique_ptr<AsyncSlot>& slot : slots) slot->Start();
    PrintProgress(start_ns, &shared);
    while (running.load() > 0) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  } else {
    std::vector<std::thread> workers;
    for (int64_t w = 0; w < o.concurrency; ++w) {
      workers.emplace_back(CallUntilEnd, &shared, static_cast<uint32_t>(w + 1));
    }
    PrintProgress(start_ns, &shared);
    for (std::thread& t : workers) t.join();
  }
  totals.elapsed_s = SecondsSince(start_ns);
  for (ServerUsage& u : totals.servers) u.after = ReadProcess(u.pid);

  totals.latency = SummarizeRuntimes(shared.tally.latencies_ms);
  totals.error_latency = SummarizeRuntimes(shared.tally.error_latencies_ms);
  PrintTotals(shared.tally, totals, client::ParseTarget(o.address)->balanced);
  const std::vector<std::string> failures = Failures(o, run, shared.tally, totals.latency);
  for (const std::string& f : failures) std::printf("FAIL: %s\n", f.c_str());
  std::fflush(stdout);
  if (!o.json_path.empty()) {
    const Status written =
        WriteStringToFileAtomic(o.json_path, TotalsJson(o, run, shared.tally, totals, failures));
    if (!written.ok()) return Fail("--json: " + written.message());
  }
  return failures.empty() ? 0 : 1;
}

}  // namespace mav::load
