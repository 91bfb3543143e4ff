#pragma once
// Flags for the services and mavctl: the shared parser (mav/common/flags.h) and port lookup.
//
//   FlagParser flags("mav-simulator", "Serves the Simulator gRPC service and publishes on DDS.");
//   flags.AddString("address", &options.address, "IP address to bind");
//   flags.AddInt("port", &port, "TCP port (env MAV_SIMULATOR_PORT)");
//   flags.ParseOrExit(argc, argv);      // unknown flag / bad value: message + usage, exit(2)
//
// Syntax: `--name value` or `--name=value`; boolean flags also as `--name` (true) or
// `--name=true|false`. `--help` / `-h` prints the usage and exits 0. Arguments that do not start
// with "--" are positional and returned in order; "--" ends flag parsing.

#include <cstdint>
#include <string>
#include <vector>

#include "mav/common/flags.h"
#include "mav/common/status.h"

namespace mav::transport {

// The services share the command-line tools' flag parser (mav/common/flags.h).
using ::mav::FlagParser;

// Reads an integer TCP port from the environment variable `name` if it is set.
// Returns `fallback` when unset; InvalidArgument naming the variable when malformed or not in
// [0, 65535].
Result<int64_t> PortFromEnv(const std::string& name, int64_t fallback);

}  // namespace mav::transport
