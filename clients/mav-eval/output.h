#pragma once
// What every mav-eval command shares: the one writer of a command's report (its text tables on
// stdout, its JSON to --json), the error line, and the progress bar of a long evaluation.

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "mav/common/flags.h"
#include "mav/common/progress.h"
#include "mav/eval/report.h"

namespace mav::eval_cli {

// "<command>: <message>" on stderr; returns `code` (1: the work failed, 2: bad usage).
int Fail(const std::string& command, const std::string& message, int code = 1);

// Parses the flags of a command that reads a data set (`data` is --data's variable): the exit
// code when the command ends here (--help: 0; a bad flag, no --data or a stray argument: 2 with
// the message and the help), nullopt to go on.
std::optional<int> ParseDataCommand(FlagParser& flags, const std::vector<std::string>& args,
                                    const std::string& command, const std::string& data);

// The report's tables on stdout, then its JSON to `json_path` when not empty.
Status PrintReport(const eval::Report& report, const std::string& json_path);

// A progress bar on stderr for eval::StepProgress (one bar per stage, made at its first step).
class ProgressPrinter {
 public:
  eval::StepProgress Callback();

 private:
  std::shared_ptr<std::unique_ptr<ProgressBar>> bar_ =
      std::make_shared<std::unique_ptr<ProgressBar>>();
};

}  // namespace mav::eval_cli
