// mav-sim: generates EuRoC-format data sets with exact ground truth from the simulator, and
// inspects them. See `mav-sim --help` and docs/datasets.md.

#include <cstdio>
#include <string>
#include <vector>

#include "commands.h"

namespace {

constexpr const char* kUsage =
    "mav-sim: simulated stereo + IMU data sets in the EuRoC ASL format, with exact ground truth\n"
    "\n"
    "usage: mav-sim <command> [flags]\n"
    "\n"
    "commands:\n"
    "  generate --preset P --out DIR [--frames N] [--seed S] [--rectified] [--force] ...\n"
    "           render a data set (EuRoC ASL + ground-truth occupancy)\n"
    "  info DIR           summarise a data set (frames, rates, calibration, ground truth)\n"
    "  preview DIR --frame K --out x.png\n"
    "           left/right images side by side and a top view of the ground-truth occupancy\n"
    "\n"
    "`mav-sim <command> --help` shows a command's flags.\n";

}  // namespace

int main(int argc, char** argv) {
  using namespace mav::sim_cli;
  if (argc < 2) {
    std::fputs(kUsage, stderr);
    return kExitUsage;
  }
  const std::string command = argv[1];
  const std::vector<std::string> args(argv + 2, argv + argc);
  if (command == "--help" || command == "-h" || command == "help") {
    std::fputs(kUsage, stdout);
    return kExitOk;
  }
  if (command == "generate") return RunGenerate(args);
  if (command == "info") return RunInfo(args);
  if (command == "preview") return RunPreview(args);
  std::fprintf(stderr, "mav-sim: unknown command '%s' (commands: generate, info, preview)\n\n%s",
               command.c_str(), kUsage);
  return kExitUsage;
}
