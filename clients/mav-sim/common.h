#pragma once
// What mav-sim's subcommands share: error lines, flag parsing with the same --help and error
// handling everywhere, and reading a data set's ground-truth occupancy grid.

#include <optional>
#include <string>
#include <vector>

#include "mav/common/flags.h"
#include "mav/common/status.h"
#include "mav/dataset/occupancy_grid.h"

namespace mav::sim_cli {

// Prints "mav-sim <command>: <message>" to stderr.
void PrintError(const std::string& command, const std::string& message);

// Parses a subcommand's arguments into the parser's flags and *positional. Returns the exit code
// when the command is already finished - kExitOk after printing --help to stdout, kExitUsage
// after printing a flag error - and std::nullopt when it should go on. --help wins over a flag
// error so that a user can always read the flags.
std::optional<int> ParseCommandFlags(const std::string& command, FlagParser* parser,
                                     const std::vector<std::string>& args,
                                     std::vector<std::string>* positional);

// ParseCommandFlags for a subcommand that takes exactly one data set directory (*dir); anything
// else is a usage error.
std::optional<int> ParseDataSetCommand(const std::string& command, FlagParser* parser,
                                       const std::vector<std::string>& args, std::string* dir);

// The ground-truth occupancy grid of the data set in `dir` (DIR/ground_truth/occupancy.mavocc).
// Only generated sets have one, so a missing file is std::nullopt rather than an error; a file
// that cannot be read is.
Result<std::optional<dataset::OccupancyGrid>> ReadGroundTruthOccupancy(const std::string& dir);

}  // namespace mav::sim_cli
