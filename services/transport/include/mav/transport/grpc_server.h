#pragma once
// The gRPC bootstrap shared by every service: bind address/port from flags or environment, the
// grpc.health.v1 health service (SERVING after start, NOT_SERVING on shutdown), server
// reflection, and a graceful, signal-safe shutdown on SIGINT/SIGTERM.
//
// A service's main() reads, in this order:
//   BlockShutdownSignals();                       // before any thread exists (gRPC, DDS, workers)
//   ServerOptions options{.port = kDefaultPort};  // then flags --address/--port, env MAV_<S>_PORT
//   auto server = GrpcServer::Start(options, {&service});
//   int sig = WaitForShutdownSignal();            // sigwait(): no async-signal-unsafe handler
//   server->Shutdown();                           // NOT_SERVING, drain RPCs up to the grace period
//
// Ports (defaults, docs/services.md): simulator 50051, localization 50052, mapping 50053,
// planning 50054, control 50055. Port 0 picks a free port (tests); GrpcServer::port() reports it.

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <grpcpp/channel.h>
#include <grpcpp/server.h>

#include "mav/common/status.h"
#include "mav/transport/flags.h"

namespace mav::transport {

struct ServerOptions {
  // Loopback by default: the stack runs on one machine; bind 0.0.0.0 explicitly to expose it.
  std::string address = "127.0.0.1";
  // 0 = let the kernel choose a free port.
  int64_t port = 0;
  // How long Shutdown() lets in-flight RPCs finish before cancelling them.
  int64_t shutdown_grace_ms = 5000;
  // Threads gRPC may run the server's calls on (its pollers included; grpc::ResourceQuota). A
  // call that finds every thread busy is answered RESOURCE_EXHAUSTED at once instead of waiting
  // for one, which bounds both the threads (memory) and the queueing under overload. Methods on
  // gRPC's callback API (Control.GetState, Mapping.QueryCollision) do not take such a thread and
  // are not bounded by it. 0 = gRPC's default (no bound).
  int64_t max_threads = 0;

  bool IsValid(std::string* why) const;
  // "127.0.0.1:50051" (IPv6 addresses are bracketed).
  std::string Target() const;
};

// Registers --address and --port on `flags` (writing into `options`). Call ApplyPortEnv() after
// parsing so that precedence is: flag > environment MAV_<SERVICE>_PORT > default.
void AddServerFlags(FlagParser* flags, ServerOptions* options, const std::string& port_env);
// Applies `port_env` unless --port was given on the command line.
Status ApplyPortEnv(const FlagParser& flags, const std::string& port_env, ServerOptions* options);

class GrpcServer {
 public:
  // Builds and starts a server with `services` (not owned; must outlive the server), the health
  // service and reflection. Health: the overall status "" and each service's full name are set
  // SERVING, as is each name in `health_names` (pass the generated Foo::service_full_name(),
  // e.g. "mav.v1.Simulator"). Unavailable with the address if the port cannot be bound.
  static Result<std::unique_ptr<GrpcServer>> Start(
      const ServerOptions& options, const std::vector<grpc::Service*>& services,
      const std::vector<std::string>& health_names = {});

  // The bound port (resolves port 0) and "address:port".
  int port() const { return port_; }
  std::string target() const;
  grpc::Server* server() { return server_.get(); }
  // A channel that calls the server in-process (no socket), for contract tests.
  std::shared_ptr<grpc::Channel> InProcessChannel();

  // Marks health NOT_SERVING, then stops accepting RPCs and waits for in-flight ones up to the
  // grace period (cancelling the rest). Idempotent; also called by the destructor.
  void Shutdown();

  ~GrpcServer();
  GrpcServer(const GrpcServer&) = delete;
  GrpcServer& operator=(const GrpcServer&) = delete;

 private:
  GrpcServer() = default;
  ServerOptions options_;
  std::unique_ptr<grpc::Server> server_;
  int port_ = 0;
  bool shut_down_ = false;
};

// Blocks SIGINT and SIGTERM in the calling thread; threads created afterwards inherit the mask,
// so the signals stay pending until WaitForShutdownSignal() takes them. Call first in main().
// (A process exec'd from such a thread inherits the mask too: unblock before exec.)
void BlockShutdownSignals();
// Waits (sigwait) for SIGINT or SIGTERM and returns the signal number.
int WaitForShutdownSignal();

// grpc.health.v1.Health/Check on `channel` for `service` ("" = the whole server).
// Returns the status enum value (1 = SERVING, 2 = NOT_SERVING, 3 = SERVICE_UNKNOWN), or
// Unavailable "health check: <gRPC code>: <message>" when the call fails.
enum class HealthStatus { kUnknown = 0, kServing = 1, kNotServing = 2, kServiceUnknown = 3 };
Result<HealthStatus> CheckHealth(const std::shared_ptr<grpc::Channel>& channel,
                                 const std::string& service, std::chrono::milliseconds timeout);
const char* HealthStatusName(HealthStatus status);

}  // namespace mav::transport
