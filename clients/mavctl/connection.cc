#include "clients/mavctl/connection.h"

#include <cmath>
#include <cstdlib>
#include <iostream>

#include "mav/transport/flags.h"

namespace mav::mavctl {

void AddConnectionFlags(FlagParser* flags, Connection* connection) {
  flags->AddString("address", &connection->address, "server address");
  flags->AddInt("port", &connection->port, "server port (env " + connection->port_env + ")");
  flags->AddDouble("timeout", &connection->timeout_s, "deadline of each RPC, s");
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
  if (!status.ok()) {
    std::cerr << "mavctl: " << status.message() << "\n";
    std::exit(2);
  }
  if (connection == nullptr) return positional;
  if (!flags->WasSet("port")) {
    auto port = transport::PortFromEnv(connection->port_env, connection->port);
    if (!port.ok()) {
      std::cerr << "mavctl: " << port.status().message() << "\n";
      std::exit(2);
    }
    connection->port = *port;
  }
  if (connection->port <= 0 || connection->port > 65535) {
    std::cerr << "mavctl: --port: " << connection->port << " is outside [1, 65535]\n";
    std::exit(2);
  }
  if (!(connection->timeout_s > 0.0) || !std::isfinite(connection->timeout_s)) {
    std::cerr << "mavctl: --timeout: must be > 0 s\n";
    std::exit(2);
  }
  return positional;
}

}  // namespace mav::mavctl
