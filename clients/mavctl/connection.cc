#include "clients/mavctl/connection.h"

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <iostream>

#include <grpcpp/client_context.h>
#include <grpcpp/support/status.h>

#include "mav/common/parse.h"
#include "mav/common/time.h"
#include "mav/transport/flags.h"
#include "mav/transport/grpc_server.h"
#include "services/common/grpc_status.h"

namespace mav::mavctl {

void AddConnectionFlags(FlagParser* flags, Connection* connection) {
  flags->AddString("address", &connection->address,
                   "server host, or a target naming several backends (ipv4:H:P,H:P | H:P,H:P | "
                   "dns:///HOST:PORT: round_robin, no --port)");
  flags->AddInt("port", &connection->port, "server port (env " + connection->port_env + ")");
  flags->AddDouble("timeout", &connection->timeout_s, "deadline of each RPC, s");
}

namespace {

[[noreturn]] void UsageExit(const std::string& message) {
  std::cerr << "mavctl: " << message << "\n";
  std::exit(2);
}

// A whole target in --address: one client::ParseTarget takes, and no --port.
void CheckTargetOrExit(const FlagParser& flags, const Connection& connection) {
  if (Result<client::ChannelTarget> t = client::ParseTarget(connection.address); !t.ok()) {
    UsageExit("--address: " + t.status().message());
  }
  if (flags.WasSet("port")) {
    UsageExit("--port: not with --address " + connection.address +
              " (a target names its own ports)");
  }
}

// A host in --address: the port from --port, else the port variable, else the default.
void ResolvePortOrExit(const FlagParser& flags, Connection* connection) {
  if (!flags.WasSet("port")) {
    auto port = transport::PortFromEnv(connection->port_env, connection->port);
    if (!port.ok()) UsageExit(port.status().message());
    connection->port = *port;
  }
  if (connection->port <= 0 || connection->port > 65535) {
    UsageExit("--port: " + std::to_string(connection->port) + " is outside [1, 65535]");
  }
}

}  // namespace

std::shared_ptr<grpc::Channel> MakeChannel(const Connection& connection) {
  return client::MakeCheckedChannel(connection.Target());  // ParseOrExit checked it
}

std::vector<std::string> ParseOrExit(FlagParser* flags, Connection* connection,
                                     const std::vector<std::string>& args, bool allow_positional) {
  std::vector<std::string> positional;
  bool help = false;
  const Status status = flags->Parse(args, allow_positional ? &positional : nullptr, &help);
  if (help) {
    std::cout << flags->Usage();
    std::exit(0);
  }
  if (!status.ok()) UsageExit(status.message());
  if (connection == nullptr) return positional;
  if (client::IsTargetUri(connection->address)) {
    CheckTargetOrExit(*flags, *connection);
  } else {
    ResolvePortOrExit(*flags, connection);
  }
  if (!(connection->timeout_s > 0.0) || !std::isfinite(connection->timeout_s)) {
    UsageExit("--timeout: must be > 0 s");
  }
  return positional;
}

Result<std::vector<double>> ParseNumbers(const std::string& text, size_t n,
                                         const std::string& flag) {
  std::vector<double> out;
  for (std::string_view field : SplitFields(text, ',')) {
    MAV_ASSIGN_OR_RETURN(double v, ParseDouble(Trim(field), flag));
    if (!std::isfinite(v)) return Status::InvalidArgument(flag + ": not finite");
    out.push_back(v);
  }
  if (out.size() != n) {
    return Status::InvalidArgument(flag + ": expected " + std::to_string(n) +
                                   " comma-separated numbers, got " + std::to_string(out.size()));
  }
  return out;
}

void SetDeadline(const Connection& connection, grpc::ClientContext* context) {
  context->set_deadline(std::chrono::system_clock::now() +
                        std::chrono::nanoseconds(SecondsToNs(connection.timeout_s)));
}

int ReportRpcError(const Connection& connection, const std::string& rpc,
                   const grpc::Status& status) {
  const Status mapped = service_common::FromGrpcStatus(status);
  if (status.error_code() == grpc::StatusCode::UNAVAILABLE) {
    std::cerr << "mavctl: cannot connect to " << connection.Target() << " (" << rpc
              << "): " << status.error_message() << "\n";
  } else if (status.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED) {
    std::cerr << "mavctl: no answer from " << connection.Target() << " to " << rpc << " within "
              << connection.timeout_s << " s (--timeout)\n";
  } else {
    std::cerr << "mavctl: " << rpc << " at " << connection.Target() << " failed: "
              << (status.error_code() == grpc::StatusCode::RESOURCE_EXHAUSTED
                      ? "RESOURCE_EXHAUSTED: " + status.error_message()
                      : mapped.ToString())
              << "\n";
  }
  return 1;
}

int CallUnary(const Connection& connection, const std::string& rpc,
              const std::function<grpc::Status(grpc::ClientContext*)>& call) {
  grpc::ClientContext context;
  SetDeadline(connection, &context);
  const grpc::Status status = call(&context);
  return status.ok() ? 0 : ReportRpcError(connection, rpc, status);
}

int ReportDownloadError(const Connection& connection, const std::string& rpc, const Status& s) {
  if (s.ok()) return 0;
  std::cerr << "mavctl: " << rpc << " at " << connection.Target()
            << ": the download is broken: " << s.message() << "\n";
  return 1;
}

}  // namespace mav::mavctl
