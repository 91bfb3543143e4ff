#include "common.h"

#include <cstdio>
#include <utility>

#include "commands.h"
#include "mav/common/file.h"
#include "mav/dataset/occupancy_io.h"

namespace mav::sim_cli {

void PrintError(const std::string& command, const std::string& message) {
  std::fprintf(stderr, "mav-sim %s: %s\n", command.c_str(), message.c_str());
}

std::optional<int> ParseCommandFlags(const std::string& command, FlagParser* parser,
                                     const std::vector<std::string>& args,
                                     std::vector<std::string>* positional) {
  bool help = false;
  const Status parsed = parser->Parse(args, positional, &help);
  if (help) {
    std::fputs(parser->Help().c_str(), stdout);
    return kExitOk;
  }
  if (!parsed.ok()) {
    PrintError(command, parsed.ToString());
    return kExitUsage;
  }
  return std::nullopt;
}

std::optional<int> ParseDataSetCommand(const std::string& command, FlagParser* parser,
                                       const std::vector<std::string>& args, std::string* dir) {
  std::vector<std::string> positional;
  if (std::optional<int> done = ParseCommandFlags(command, parser, args, &positional)) return done;
  if (positional.size() != 1) {
    PrintError(command, "expected exactly one data set directory (see --help)");
    return kExitUsage;
  }
  *dir = positional[0];
  return std::nullopt;
}

Result<std::optional<dataset::OccupancyGrid>> ReadGroundTruthOccupancy(const std::string& dir) {
  const std::string path = dir + "/ground_truth/occupancy.mavocc";
  if (!PathExists(path)) return std::optional<dataset::OccupancyGrid>();
  MAV_ASSIGN_OR_RETURN(dataset::OccupancyGrid grid, dataset::ReadMavocc(path));
  return std::optional<dataset::OccupancyGrid>(std::move(grid));
}

}  // namespace mav::sim_cli
