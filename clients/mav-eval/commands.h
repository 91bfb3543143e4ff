#pragma once
// The subcommands of mav-eval. Each returns the process exit code: 0 success, 1 failure of the
// work (missing or corrupt data), 2 bad usage.

#include <string>
#include <vector>

namespace mav::eval_cli {

int RunLocalization(const std::vector<std::string>& args);
int RunMapping(const std::vector<std::string>& args);
int RunControl(const std::vector<std::string>& args);
int RunPlanning(const std::vector<std::string>& args);
int RunMission(const std::vector<std::string>& args);

}  // namespace mav::eval_cli
