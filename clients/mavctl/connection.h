#pragma once
// The connection flags every mavctl subcommand shares: --address, --port (with the service's
// port environment variable as the fallback) and --timeout (each RPC's deadline).

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "mav/common/flags.h"

namespace grpc {
class ClientContext;
class Status;
}  // namespace grpc

namespace mav::mavctl {

struct Connection {
  Connection(int64_t default_port, std::string port_env_name)
      : port(default_port), port_env(std::move(port_env_name)) {}

  std::string address = "127.0.0.1";
  int64_t port;
  double timeout_s = 10.0;
  std::string port_env;  // consulted when --port is not given, e.g. MAV_SIMULATOR_PORT

  std::string Target() const { return address + ":" + std::to_string(port); }
};

void AddConnectionFlags(FlagParser* flags, Connection* connection);

// Parses a subcommand's flags: --help prints the usage and exits 0; a usage error (bad flag,
// port outside [1, 65535], non-positive timeout, malformed port variable) prints "mavctl: ..."
// and exits 2. `connection` may be null for subcommands without a server. Returns the positional
// arguments when `allow_positional`, otherwise they are an error.
std::vector<std::string> ParseOrExit(FlagParser* flags, Connection* connection,
                                     const std::vector<std::string>& args,
                                     bool allow_positional = false);

// Sets the RPC deadline from --timeout.
void SetDeadline(const Connection& connection, grpc::ClientContext* context);

// Prints a failed RPC in words (cannot connect / no answer within --timeout / the status with
// its code) and returns the exit code 1.
int ReportRpcError(const Connection& connection, const std::string& rpc,
                   const grpc::Status& status);

}  // namespace mav::mavctl
