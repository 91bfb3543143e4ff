#include "mav/transport/grpc_server.h"

#include <csignal>
#include <future>

#include <grpcpp/create_channel.h>
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/health_check_service_interface.h>
#include <grpcpp/resource_quota.h>
#include <grpcpp/security/credentials.h>
#include <grpcpp/security/server_credentials.h>
#include <grpcpp/server_builder.h>
#include <grpcpp/support/byte_buffer.h>

#include "mav/common/check.h"
#include "mav/common/log.h"

namespace mav::transport {

bool ServerOptions::IsValid(std::string* why) const {
  if (address.empty()) {
    if (why != nullptr) *why = "address: empty";
    return false;
  }
  if (port < 0 || port > 65535) {
    if (why != nullptr) *why = "port: " + std::to_string(port) + " is outside [0, 65535]";
    return false;
  }
  if (shutdown_grace_ms < 0) {
    if (why != nullptr) *why = "shutdown_grace_ms: must be >= 0";
    return false;
  }
  // gRPC's sync server keeps up to 2 polling threads besides the ones running calls.
  if (max_threads != 0 && (max_threads < 4 || max_threads > 10000)) {
    if (why != nullptr) {
      *why =
          "max_threads: " + std::to_string(max_threads) + " is outside [4, 10000] (0 = no bound)";
    }
    return false;
  }
  return true;
}

std::string ServerOptions::Target() const {
  const bool ipv6 = address.find(':') != std::string::npos && address.front() != '[';
  return (ipv6 ? "[" + address + "]" : address) + ":" + std::to_string(port);
}

void AddServerFlags(FlagParser* flags, ServerOptions* options, const std::string& port_env) {
  flags->AddString("address", &options->address,
                   "IP address to bind the gRPC server to (0.0.0.0 exposes it)");
  flags->AddInt("port", &options->port, "TCP port of the gRPC server (env " + port_env + ")");
  flags->AddInt("max-threads", &options->max_threads,
                "threads gRPC runs synchronous calls on; a call finding all busy gets "
                "RESOURCE_EXHAUSTED (0 = no bound; the callback methods, Control.GetState and "
                "Mapping.QueryCollision, run on gRPC's own threads and are not bounded)");
}

Status ApplyPortEnv(const FlagParser& flags, const std::string& port_env, ServerOptions* options) {
  if (flags.WasSet("port")) return Status::Ok();
  MAV_ASSIGN_OR_RETURN(options->port, PortFromEnv(port_env, options->port));
  return Status::Ok();
}

Result<std::unique_ptr<GrpcServer>> GrpcServer::Start(
    const ServerOptions& options, const std::vector<grpc::Service*>& services,
    const std::vector<std::string>& health_names) {
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument(why);

  // Both are process-wide switches read by every ServerBuilder created afterwards.
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();

  std::unique_ptr<GrpcServer> self(new GrpcServer());
  self->options_ = options;
  grpc::ServerBuilder builder;
  // gRPC enables SO_REUSEPORT by default, which lets a second server silently share a port with
  // the first (and steal half of its connections). A busy port must be an error.
  builder.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
  builder.AddListeningPort(options.Target(), grpc::InsecureServerCredentials(), &self->port_);
  if (options.max_threads > 0) {
    grpc::ResourceQuota quota("mav-server");
    quota.SetMaxThreads(static_cast<int>(options.max_threads));
    builder.SetResourceQuota(quota);
  }
  for (grpc::Service* service : services) {
    MAV_CHECK(service != nullptr);
    builder.RegisterService(service);
  }
  self->server_ = builder.BuildAndStart();
  if (self->server_ == nullptr || self->port_ == 0) {
    return Status::Unavailable("cannot serve gRPC on " + options.Target() +
                               " (address in use or not assignable?)");
  }
  grpc::HealthCheckServiceInterface* health = self->server_->GetHealthCheckService();
  MAV_CHECK(health != nullptr) << "the default health service is not enabled";
  health->SetServingStatus(true);
  for (const std::string& name : health_names) health->SetServingStatus(name, true);
  MAV_LOG(kInfo) << "gRPC serving on " << self->target() << " (health, reflection)";
  return self;
}

std::string GrpcServer::target() const {
  ServerOptions bound = options_;
  bound.port = port_;
  return bound.Target();
}

std::shared_ptr<grpc::Channel> GrpcServer::InProcessChannel() {
  return server_->InProcessChannel(grpc::ChannelArguments());
}

void GrpcServer::Shutdown() {
  if (shut_down_ || server_ == nullptr) return;
  shut_down_ = true;
  if (grpc::HealthCheckServiceInterface* health = server_->GetHealthCheckService()) {
    health->SetServingStatus(false);
  }
  server_->Shutdown(std::chrono::system_clock::now() +
                    std::chrono::milliseconds(options_.shutdown_grace_ms));
  server_->Wait();
  MAV_LOG(kInfo) << "gRPC server on " << target() << " stopped";
}

GrpcServer::~GrpcServer() { Shutdown(); }

void BlockShutdownSignals() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  MAV_CHECK(pthread_sigmask(SIG_BLOCK, &set, nullptr) == 0);
}

int WaitForShutdownSignal() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  int sig = 0;
  MAV_CHECK(sigwait(&set, &sig) == 0);
  return sig;
}

// grpc.health.v1 messages are encoded by hand (Debian ships no generated health.pb.h):
//   HealthCheckRequest  { string service = 1; }            -> tag 0x0A, length, bytes
//   HealthCheckResponse { ServingStatus status = 1; }      -> tag 0x08, varint
Result<HealthStatus> CheckHealth(const std::shared_ptr<grpc::Channel>& channel,
                                 const std::string& service, std::chrono::milliseconds timeout) {
  std::string request;
  if (!service.empty()) {
    MAV_CHECK(service.size() < 128) << "service name too long for the one-byte length";
    request.push_back(0x0A);
    request.push_back(static_cast<char>(service.size()));
    request += service;
  }
  grpc::Slice slice(request);
  grpc::ByteBuffer request_buffer(&slice, 1);
  grpc::ByteBuffer response_buffer;

  grpc::GenericStub stub(channel);
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + timeout);
  std::promise<grpc::Status> done;
  std::future<grpc::Status> answer = done.get_future();
  stub.UnaryCall(&context, "/grpc.health.v1.Health/Check", grpc::StubOptions(), &request_buffer,
                 &response_buffer, [&done](grpc::Status s) { done.set_value(std::move(s)); });
  const grpc::Status rpc_status = answer.get();
  if (!rpc_status.ok()) {
    if (rpc_status.error_code() == grpc::StatusCode::NOT_FOUND)
      return HealthStatus::kServiceUnknown;
    return Status::Unavailable("health check: gRPC code " +
                               std::to_string(rpc_status.error_code()) + ": " +
                               rpc_status.error_message());
  }
  std::vector<grpc::Slice> slices;
  if (!response_buffer.Dump(&slices).ok()) return Status::Internal("health check: bad response");
  std::string bytes;
  for (const grpc::Slice& s : slices) {
    bytes.append(reinterpret_cast<const char*>(s.begin()), s.size());
  }
  // An all-default response (UNKNOWN) is encoded as zero bytes.
  if (bytes.empty()) return HealthStatus::kUnknown;
  if (bytes.size() < 2 || bytes[0] != 0x08 || (bytes[1] & 0x80) != 0) {
    return Status::Internal("health check: unexpected response encoding");
  }
  return static_cast<HealthStatus>(bytes[1]);
}

const char* HealthStatusName(HealthStatus status) {
  switch (status) {
    case HealthStatus::kUnknown:
      return "UNKNOWN";
    case HealthStatus::kServing:
      return "SERVING";
    case HealthStatus::kNotServing:
      return "NOT_SERVING";
    case HealthStatus::kServiceUnknown:
      return "SERVICE_UNKNOWN";
  }
  return "?";
}

}  // namespace mav::transport
