#pragma once
// mav-sim's subcommands. Each takes the arguments after the command name, prints its own errors
// to stderr, and returns the process exit code (0 ok, 1 failure, 2 bad usage).

#include <string>
#include <vector>

namespace mav::sim_cli {

inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;
inline constexpr int kExitUsage = 2;

int RunGenerate(const std::vector<std::string>& args);
int RunInfo(const std::vector<std::string>& args);
int RunPreview(const std::vector<std::string>& args);

}  // namespace mav::sim_cli
