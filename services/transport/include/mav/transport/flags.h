#pragma once
// A tiny command-line flag parser shared by the services and mavctl.
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

#include "mav/common/status.h"

namespace mav::transport {

class FlagParser {
 public:
  FlagParser(std::string program, std::string description);

  // The pointee keeps its current value as the default (shown in the usage text).
  void AddString(const std::string& name, std::string* value, const std::string& help);
  void AddInt(const std::string& name, int64_t* value, const std::string& help);
  void AddDouble(const std::string& name, double* value, const std::string& help);
  void AddBool(const std::string& name, bool* value, const std::string& help);

  // Parses args (without the program name). InvalidArgument names the flag:
  // "--port: 'abc' is not an integer", "unknown flag --prot", "--port: missing value".
  // `positional` may be null, then positional arguments are an error.
  // Sets *help_requested (if given) when --help/-h was seen; parsing stops there.
  Status Parse(const std::vector<std::string>& args, std::vector<std::string>* positional,
               bool* help_requested = nullptr);

  // Parses argv[first..argc). On error prints "<program>: <error>" and the usage to stderr and
  // exits with status 2; on --help prints the usage to stdout and exits 0.
  std::vector<std::string> ParseOrExit(int argc, char** argv, int first = 1,
                                       bool allow_positional = false);

  // True if the flag was given on the command line (not just its default).
  bool WasSet(const std::string& name) const;

  std::string Usage() const;

 private:
  enum class Kind { kString, kInt, kDouble, kBool };
  struct Flag {
    std::string name;
    Kind kind;
    void* value;
    std::string help;
    std::string default_text;
    bool set = false;
  };
  Flag* Find(const std::string& name);
  static Status Assign(Flag* flag, const std::string& text);

  std::string program_;
  std::string description_;
  std::vector<Flag> flags_;
};

// Reads an integer TCP port from the environment variable `name` if it is set.
// Returns `fallback` when unset; InvalidArgument naming the variable when malformed or not in
// [0, 65535].
Result<int64_t> PortFromEnv(const std::string& name, int64_t fallback);

}  // namespace mav::transport
