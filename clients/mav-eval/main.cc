// mav-eval: reproduces the reference paper's tables with our own code and data.
//   mav-eval localization --data DIR [--method ...] [--out DIR] [--json FILE]
//   mav-eval mapping --data DIR [--method ...] [--out DIR] [--json FILE]
//   mav-eval control [--task T|all] [--controller paper|lee|all] [--task-file F] [--out DIR]
//   mav-eval planning --map FILE.bt [--queries FILE] [--robot-radius M] [--seed S] [--out DIR]
//                     [--json FILE]
//   mav-eval mission --mission FILE [--seed S] [--pose-source vo|contest|truth] [--out DIR]
//                    [--json FILE]

#include <iostream>
#include <string>
#include <vector>

#include "commands.h"

namespace {

constexpr const char* kUsage =
    "usage: mav-eval <command> [flags]\n"
    "commands:\n"
    "  localization   stereo VO accuracy and runtime (the paper's Tables 1 and 2)\n"
    "  mapping        sparse mesh vs OctoMap: collision-check MCC and runtime (Tables 3 and 4)\n"
    "  control        the EuRoC contest's flight tasks, scored (Sec. 3), paper vs Lee controller\n"
    "  planning       roadmap planner vs OMPL peers: path length, planning and flight time "
    "(Sec. 3)\n"
    "  mission        a mission file flown in-process: vision in the loop, planning, control\n"
    "run 'mav-eval <command> --help' for the flags of a command\n";

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::cerr << kUsage;
    return 2;
  }
  const std::string command = argv[1];
  const std::vector<std::string> args(argv + 2, argv + argc);
  if (command == "localization") return mav::eval_cli::RunLocalization(args);
  if (command == "mapping") return mav::eval_cli::RunMapping(args);
  if (command == "control") return mav::eval_cli::RunControl(args);
  if (command == "planning") return mav::eval_cli::RunPlanning(args);
  if (command == "mission") return mav::eval_cli::RunMission(args);
  if (command == "--help" || command == "-h" || command == "help") {
    std::cout << kUsage;
    return 0;
  }
  std::cerr << "mav-eval: unknown command '" << command << "'\n" << kUsage;
  return 2;
}
